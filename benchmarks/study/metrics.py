"""The errors of a study run: from its result (B1, B2), and for B3 from its reaction curve
against the reference run's, once every run is done."""
from __future__ import annotations

import numpy as np

from benchmarks import analytics

from .cases import RINGS_TIMES, Case
from .records import key


def errors(case: Case, result) -> dict:
    """The error columns of a converged run (B3's come later, see ``finalize_rings``)."""
    if case.benchmark == "patch":
        s = result.stress.values()
        return {"err_sigma_yy": float(np.abs(s[:, 1, 1] + 1.0).max())}
    if case.benchmark in ("hertz", "hertz_mc"):
        m = analytics.hertz_metrics(result)
        return {"err_p0": abs(m["p0_error"]), "err_l2": m["l2_error"],
                "err_a": abs(m["a_error"]), "err_force": m["force_error"]}
    return {}


def finalize_rings(records: list[dict], ref: Case | None) -> None:
    """B3 errors: every half-rings curve against the reference run's."""
    reference = None
    if ref is not None:
        for r in records:
            if key(r) == ref.key and r["status"] == "converged":
                reference = r.get("curve")
    for r in records:
        if r["benchmark"] == "half_rings" and r.get("curve"):
            ok = r["status"] == "converged"
            err, osc = analytics.reaction_errors(r["curve"], reference if ok else None,
                                                 RINGS_TIMES)
            r["osc_reaction"] = osc if ok else ""
            r["err_reaction"] = err if (reference and ok) else ""
            r["reference"] = ref is not None and key(r) == ref.key
