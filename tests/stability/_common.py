"""Shared helpers of the hard-case stability suite (docs/stability.md).

Each case runs one or more scenes of ``demos/scenes/hard/`` through ``solve`` and checks:

* ``converged``;
* no NaN/Inf in the displacement, the nodal contact pressure (and tangential traction), the
  reactions and the per-step contact records;
* Newton iterations per step (summed over the ALM augmentations of the step, as recorded in
  ``newton_iterations``) ≤ the case's bound;
* step cuts (the number of failed attempts over the whole run) ≤ the case's bound;
* the pressure is free of spurious oscillation, measured by :func:`oscillation`.

Oscillation measure ("excess total variation"): order the slave nodes along the slave
surface, take the active zone (first to last node with p > 0) widened by one node on each
side, and compute

    osc = [ TV(p) − (2 p_max − p_first − p_last) ] / p_max ,   TV(p) = Σ_k |p_{k+1} − p_k| .

A single-humped profile (uniform, Hertzian, a ramp — anything that rises to its maximum and
then falls) has TV = (p_max − p_first) + (p_max − p_last), so osc = 0 to round-off. Every
extra wiggle of amplitude d adds 2d/p_max: a node-to-node zig-zag of ±5 % over n nodes gives
osc ≈ 0.2 n. A physically two-peaked profile (a wide plate on a narrower block: pressure peaks
at the block's corners) has osc = 2 (p_max − p_valley)/p_max, which is why each bound is set
against a smooth reference (stated per case) rather than against zero. The run's measure is
the largest over its converged steps.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
HARD = ROOT / "demos" / "scenes" / "hard"


def oscillation(d: dict) -> float:
    """Excess total variation of the nodal pressure (see the module docstring); 0 when
    nothing is in contact."""
    order = np.argsort(d["s"])
    p = np.asarray(d["pressure"], dtype=float)[order]
    on = np.flatnonzero(p > 0)
    if len(on) == 0:
        return 0.0
    lo, hi = max(on[0] - 1, 0), min(on[-1] + 1, len(p) - 1)
    q = p[lo:hi + 1]
    pmax = q.max()
    tv = np.abs(np.diff(q)).sum()
    return float((tv - (2 * pmax - q[0] - q[-1])) / pmax)


@dataclass
class Run:
    """A finished run and what the suite measures on it."""
    name: str
    result: object
    seconds: float
    osc_per_step: list[float] = field(default_factory=list)
    interfaces: list[dict] = field(default_factory=list)  # per converged step
    nonfinite: list[str] = field(default_factory=list)

    @property
    def converged(self) -> bool:
        return bool(self.result.converged)

    @property
    def newton(self) -> list[int]:
        return [s["newton_iterations"] for s in self.result.steps]

    @property
    def cuts(self) -> int:
        """Failed attempts (halvings) over the whole run: a step record's ``cuts`` is the
        number of halvings since the previous converged step."""
        return int(sum(s["cuts"] for s in self.result.steps))

    @property
    def osc(self) -> float:
        return max(self.osc_per_step, default=0.0)


def run_scene(scene_or_path, name: str | None = None, log: Callable[[str], None] | None = None,
              edit: Callable | None = None) -> Run:
    """Solve a scene (path or Scene), recording the interface after every converged step."""
    from fenicsx_mortar import load_scene, solve
    scene = load_scene(scene_or_path) if isinstance(scene_or_path, (str, Path)) else scene_or_path
    if edit is not None:
        edit(scene)
    run = Run(name or scene.title, None, 0.0)

    def on_step(record, state):
        for h in state.pairs:
            d = {k: np.array(v, copy=True) for k, v in h.interface().items()}
            run.interfaces.append(d)
            run.osc_per_step.append(oscillation(d))
            _check_finite(run, f"step {record['step']} {h.name}", d)
        _check_finite(run, f"step {record['step']} record", record)

    t0 = time.perf_counter()
    run.result = solve(scene, log=log or (lambda s: None), on_step=on_step)
    run.seconds = time.perf_counter() - t0
    u = run.result.u.x.array
    if not np.all(np.isfinite(u)):
        run.nonfinite.append("displacement")
    return run


def _check_finite(run: Run, where: str, obj, key: str = "") -> None:
    if isinstance(obj, dict):
        for k, v in obj.items():
            _check_finite(run, where, v, f"{key}.{k}" if key else str(k))
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            _check_finite(run, where, v, f"{key}[{i}]")
    elif isinstance(obj, np.ndarray):
        if (obj.dtype.kind in "fc"
                and not np.all(np.isfinite(obj[~np.isnan(obj)] if key == "gap" else obj))):
            run.nonfinite.append(f"{where}: {key}")
    elif isinstance(obj, float) and not math.isfinite(obj):
        run.nonfinite.append(f"{where}: {key}")


def assert_stable(run: Run, max_newton: int, max_cuts: int, max_osc: float | None) -> None:
    """The four generic assertions of the suite."""
    r = run.result
    assert r.converged, f"{run.name}: {r.message}"
    assert not run.nonfinite, f"{run.name}: non-finite values in {run.nonfinite}"
    assert r.steps, f"{run.name}: no converged step"
    worst = max(run.newton)
    assert worst <= max_newton, (f"{run.name}: {worst} Newton iterations in one step "
                                 f"(bound {max_newton}); per step {run.newton}")
    assert run.cuts <= max_cuts, f"{run.name}: {run.cuts} step cuts (bound {max_cuts})"
    if max_osc is not None:
        assert run.osc <= max_osc, (f"{run.name}: pressure oscillation {run.osc:.3g} > "
                                    f"{max_osc} (per step {np.round(run.osc_per_step, 3)})")


def contact(run: Run, step: int = -1, pair: str | None = None) -> dict:
    rec = run.result.steps[step]["contact"]
    return rec[pair] if pair else next(iter(rec.values()))
