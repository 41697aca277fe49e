"""The gradient-check rows the tests ran, gathered for one table at the end of the session.

The test modules run the suite's cases (minifilm.evaluation.gradcheck_table) one (case, seed) per
test through :func:`check`; the gradient checks of code outside the table (t-SNE, the style
classifier, the FiLM-vector fit, the companion's own check) go through :func:`other`.
tests/conftest.py prints :func:`table` in pytest's terminal summary: the table ``minifilm
gradcheck`` prints, then a line for each other check. (A module of its own: every test folder
may import it, and conftest.py reads what they recorded.)
"""
import math

from minifilm.evaluation.gradcheck_table import Row, cases, float32_cases, format_table
from minifilm.nn.gradcheck import worst_error

ROWS: dict = {}
OTHERS: dict = {}       # name -> [worst error, limit]


def check(case, seed):
    """Run one case on one seed, record it, and fail the test with the worst entry if it fails."""
    row = ROWS.setdefault((case.group == "float32", case.name), Row(case))
    result = case.check(seed)
    row.add(seed, result)
    worst = worst_error(result.errors)          # NaN or inf (or no array checked): inf, a failure
    assert result.crossings == 0, f"{case.name}, seed {seed}: {result.crossings} stencil evaluations crossed a kink"
    assert worst <= case.limit, f"{case.name}, seed {seed}: {worst:.2e} > {case.limit:g} at {result.worst}"
    return result


def other(name: str, errors, limit: float) -> None:
    """Record a gradient check outside the table (``errors``: a number, or a dict or list of
    them; NaN or inf is a failure) and fail the test when its worst error is not below ``limit``."""
    worst = worst_error(errors if isinstance(errors, (dict, list, tuple)) else [errors])
    entry = OTHERS.setdefault(name, [0.0, limit])
    entry[0] = max(entry[0], worst)
    assert worst < limit, f"{name}: {worst:.2e} >= {limit:g} ({errors})"


def format_others() -> str:
    w = max([len("other gradient check")] + [len(n) for n in OTHERS])
    head = f"{'other gradient check':<{w}}  {'worst rel. error':>16}  limit    pass"
    lines = [head, "-" * len(head)]
    for name, (worst, limit) in OTHERS.items():
        ok = math.isfinite(worst) and worst < limit
        lines.append(f"{name:<{w}}  {worst:>16.1e}  {limit:<7.0e}  {'yes' if ok else 'NO'}")
    return "\n".join(lines)


def table() -> str:
    """Both tables of the rows recorded so far and the other checks (empty when none ran)."""
    parts = []
    order = {(False, c.name): i for i, c in enumerate(cases())}
    order.update({(True, c.name): i for i, c in enumerate(float32_cases())})
    for float32, title, error in ((False, "backward pass", "worst rel. error"),
                                  (True, "network (float32)", "worst rel. diff.")):
        rows = [r for key, r in sorted(ROWS.items(), key=lambda kv: order[kv[0]]) if key[0] == float32]
        if rows:
            parts.append(format_table(rows, title, error))
    if OTHERS:
        parts.append(format_others())
    return "\n\n".join(parts)
