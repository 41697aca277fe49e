"""Small helpers shared by the comparison's report modules (compare_report.py, compare_claims*.py)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def report_name(folder) -> str:
    """How a report names a folder (the data, the released network): its own name, never a path (a
    path relative to where the command ran still spells out that machine's folders)."""
    return Path(folder).resolve().name or str(folder)


def fmt(v, digits=4):
    """A number for a table: 'n/a' for None, NaN and inf."""
    return "n/a" if v is None or (isinstance(v, float) and not np.isfinite(v)) else f"{v:.{digits}f}"


def seed_summary(r) -> dict:
    """Mean and sample std over the seeds of a variant's test errors (r['seed_errors'], or just
    r['errors']): {'mse', 'mse_sd', 'bll', 'bll_sd', 'n', 'per_style': {style: mean mse}}."""
    runs = r.get("seed_errors") or [r["errors"]]
    out = {"n": len(runs)}
    for key in ("mse", "bll"):
        v = np.array([e[key] for e in runs])
        out[key], out[key + "_sd"] = float(v.mean()), float(v.std(ddof=1)) if len(v) > 1 else float("nan")
    out["per_style"] = {s: float(np.mean([e["per_style"][s]["mse"] for e in runs])) for s in runs[0]["per_style"]}
    return out
