"""The gradient-check rows the tests ran, gathered for one table at the end of the session.

The test modules run the suite's cases (minifilm.evaluation.gradcheck_table) one (case, seed) per
test through :func:`check`; tests/conftest.py prints :func:`table` in pytest's terminal summary,
the same table ``minifilm gradcheck`` prints. (A module of its own: every test folder may import
it, and conftest.py reads what they recorded.)
"""
from minifilm.evaluation.gradcheck_table import Row, cases, float32_cases, format_table
from minifilm.nn.gradcheck import worst_error

ROWS: dict = {}


def check(case, seed):
    """Run one case on one seed, record it, and fail the test with the worst entry if it fails."""
    row = ROWS.setdefault((case.group == "float32", case.name), Row(case))
    result = case.check(seed)
    row.add(seed, result)
    worst = worst_error(result.errors)          # NaN or inf (or no array checked): inf, a failure
    assert result.crossings == 0, f"{case.name}, seed {seed}: {result.crossings} stencil evaluations crossed a kink"
    assert worst <= case.limit, f"{case.name}, seed {seed}: {worst:.2e} > {case.limit:g} at {result.worst}"
    return result


def table() -> str:
    """Both tables of the rows recorded so far (empty when none ran)."""
    parts = []
    order = {(False, c.name): i for i, c in enumerate(cases())}
    order.update({(True, c.name): i for i, c in enumerate(float32_cases())})
    for float32, title, error in ((False, "backward pass", "worst rel. error"),
                                  (True, "network (float32)", "worst rel. diff.")):
        rows = [r for key, r in sorted(ROWS.items(), key=lambda kv: order[kv[0]]) if key[0] == float32]
        if rows:
            parts.append(format_table(rows, title, error))
    return "\n\n".join(parts)
