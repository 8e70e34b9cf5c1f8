"""Curved non-matching interface with an exact solution: a shrink fit, per master smoothing,
under mesh refinement (docs/curved_interface.md).

    .venv/bin/python benchmarks/curved_interface.py                  # levels 0-4, 2 workers
    .venv/bin/python benchmarks/curved_interface.py --levels 0,1,2,3 --workers 1
    .venv/bin/python benchmarks/curved_interface.py --redraw         # doc + plot from saved runs
    .venv/bin/python benchmarks/curved_interface.py --arcs 24,17 --levels 0,1   # other arcs

Problem (scene ``demos/scenes/shrink_fit.toml``, mesh ``meshes/shrink_fit.py``): quarter model
of an inner ring a = 0.5 ≤ r ≤ b + δ = 1.01 shrunk into an outer ring b = 1 ≤ r ≤ c = 1.5,
radial interference δ = 0.01 (an initial overlap that the contact resolves; no other load),
symmetry supports on x = 0 and y = 0, frictionless mortar contact with Lagrange multipliers,
slave = the inner ring's outer arc, master = the outer ring's inner arc, non-matching
(8 : 13 segments on the coarsest level), E = 1000, ν = 0.3 on both rings, plane strain.

Levels: level k multiplies all four element counts of the scene's mesh (inner and outer,
radial and circumferential) by 2^k, so h halves from level to level. On level 0 the slave
sagitta h²/8R is 1.7 × the slave's radial displacement |u_inner| (0.49 δ): the hard case of
issue 17; the table of docs/curved_interface.md lists the ratio per level.

Variants (``VARIANTS``, one tuple, extend it there): a master smoothing
(``contacts[].smoothing``) and optionally a slave smoothing (``contacts[].slave_smoothing``,
two-sided); a variant whose scene field does not exist, or whose value the scene validation
refuses, is skipped (and listed with the reason). Plus one control, the polyline on
*matching* arcs (outer_nc = inner_nc): there the slave and master chords coincide in the
deformed state, so its error is the rings' own discretization error alone (Q1 elements on
polygonal rings, no contact-geometry error) — the numerical check of the exact solution.
Each variant runs with the ``linear`` and the ``neo-hooke`` law on both rings.

Exact solution (``benchmarks/analytics.py``): linear — the Lamé rings on their reference
geometry with the contact in the current configuration, ``shrink_fit_linear`` (p = f/r_c per
unit current length: what the mortar's nodal pressures are; the classical p_c of
``shrink_fit_pressure`` differs by O(δ/b) = −0.30 %); Neo-Hooke — the axisymmetric
finite-deformation solution of the same overlap, ``shrink_fit_neo_hooke`` (a 1D boundary
value problem solved to 1e-11; it differs from Lamé by −0.45 %, an O(δ/b) effect of finite
deformation, not an error).

Measured per run: nodal pressure error e_j = p_j/p − 1 at every slave node, the two end nodes
on the symmetry planes included (they end the open chains; their error is also reported on
its own): max |e|, mean |e|, end-node max |e|, the interior spread max e − min e (the
oscillation), active slave nodes / all; observed orders log(e_k/e_k+1)/log 2 between
levels; Newton iterations; force balance (reaction on the inner ring's x = 0 edge against the
contact force on the slave, and against the outer ring's reaction); wall time. One-sided
smoothings are compared with the chord-clearance estimate e ≈ −(2/3) s/δ (the slave chords
lie inside the circle by up to s = h²/8R; the dual-weighted mean of that parabola is 2s/3,
and the linear pressure is proportional to δ minus the clearance).

Writes ``docs/curved_interface.md`` (set-up, exact solution, tables, observations computed
from the numbers), ``docs/curved_interface.png`` (errors against h, pressure profile on
level 0) and ``results/curved_interface/runs.json`` (every run with its nodal pressures, for
--redraw); the workers' output goes to ``results/curved_interface/workers.log``.
Time: 2-8 minutes with 2 workers (measured 118, 342, 436 and 494 s on a shared 2-core
machine): the critical path is the linear averaged-tangent run of level 4, which diverges
(110-480 s to fail: two Newton attempts of 25 iterations on 44k dofs), while the other
worker does nearly everything else (about 2-4 minutes).
"""
from __future__ import annotations

import argparse
import functools
import json
import math
import subprocess
import sys
import time
import traceback
from pathlib import Path
from typing import NamedTuple

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks import analytics, pool  # noqa: E402

SCENE = ROOT / "demos" / "scenes" / "shrink_fit.toml"
DOCS = ROOT / "docs"
MD = DOCS / "curved_interface.md"
PNG = DOCS / "curved_interface.png"
OUT = ROOT / "results" / "curved_interface"
RUNS = OUT / "runs.json"
LEVELS = (0, 1, 2, 3, 4)
MATERIALS = ("linear", "neo-hooke")
CRITERION = 0.01           # issue 17: max |p/p_c − 1| ≤ 1 % with two-sided smoothing
WALL_LIMIT = 600.0         # seconds per run (the pool stops a run beyond it)


class Variant(NamedTuple):
    """``master``: contacts[].smoothing; ``slave``: contacts[].slave_smoothing (two-sided),
    None = one-sided (the slave stays the polyline); ``matching``: outer_nc = inner_nc."""
    name: str
    master: str
    slave: str | None = None
    matching: bool = False


#: the variants of the tables and plots, in this order
VARIANTS: tuple[Variant, ...] = (
    Variant("none", "none"),
    Variant("averaged-tangent", "averaged-tangent"),
    Variant("hermite", "hermite"),
    Variant("bspline", "bspline"),
    Variant("hermite, two-sided", "hermite", "hermite"),
    Variant("bspline, two-sided (hermite slave)", "bspline", "hermite"),
    Variant("bspline, two-sided", "bspline", "bspline"),
)
#: the check of the exact solution: matching arcs, where the chords coincide
CONTROL = Variant("matching arcs, none (control)", "none", matching=True)


# ---------------------------------------------------------------- scene, geometry, exact


@functools.lru_cache(maxsize=None)
def _base_scene_params() -> tuple[dict, float, float]:
    """(mesh params, E, ν) of the scene file (both rings share E and ν)."""
    from fenicsx_mortar import load_scene
    scene = load_scene(SCENE)
    mats = {(b.material.E, b.material.nu) for b in scene.bodies}
    if len(mats) != 1:
        raise ValueError(f"{SCENE.name}: both rings must have the same E and nu, got {mats}")
    (E, nu), = mats
    return dict(scene.mesh.params), float(E), float(nu)


def supports_two_sided() -> bool:
    """True when the scene's contact has a ``slave_smoothing`` field (two-sided smoothing)."""
    from fenicsx_mortar import load_scene
    return hasattr(load_scene(SCENE).contacts[0], "slave_smoothing")


@functools.lru_cache(maxsize=None)
def refusal(variant: Variant) -> str | None:
    """Why a variant cannot run (its scene field is missing, or the scene validation
    refuses its value), None when it can."""
    from fenicsx_mortar import SceneError
    if variant.slave is not None and not supports_two_sided():
        return "the scene field contacts[].slave_smoothing does not exist"
    try:
        make_scene(0, MATERIALS[0], variant).validate()
    except (SceneError, ValueError) as e:
        return str(e)
    return None


def available(variant: Variant) -> bool:
    return refusal(variant) is None


def mesh_params(level: int, matching: bool = False, arcs: tuple | None = None) -> dict:
    """The generator parameters of a level: every element count × 2^level (``arcs``: the
    level-0 slave and master segment counts instead of the scene's)."""
    p, _, _ = _base_scene_params()
    if arcs:
        p = dict(p, inner_nc=int(arcs[0]), outer_nc=int(arcs[1]))
    k = 2**level
    p = dict(p, **{n: p[n] * k for n in ("inner_nc", "outer_nc", "inner_nr", "outer_nr")})
    if matching:
        p["outer_nc"] = p["inner_nc"]
    return p


def make_scene(level: int, material: str, variant: Variant, arcs: tuple | None = None):
    """The scene of one run (no output files)."""
    from fenicsx_mortar import load_scene
    scene = load_scene(SCENE)
    scene.mesh.params = mesh_params(level, variant.matching, arcs)
    for body in scene.bodies:
        body.material.model = material
    contact = scene.contacts[0]
    contact.smoothing = variant.master
    if variant.slave is not None:
        if not hasattr(contact, "slave_smoothing"):
            raise ValueError(f"{variant.name}: contacts[].slave_smoothing does not exist")
        contact.slave_smoothing = variant.slave
    scene.output.xdmf = scene.output.plots = False
    return scene


@functools.lru_cache(maxsize=None)
def exact(material: str) -> analytics.ShrinkFit:
    """The exact interface state of the scene's geometry for ``material``."""
    p, E, nu = _base_scene_params()
    args = (p["a"], p["b"], p["c"], p["delta"], E, nu)
    if material == "linear":
        return analytics.shrink_fit_linear(*args)
    if material == "neo-hooke":
        return analytics.shrink_fit_neo_hooke(*args)
    raise ValueError(f"no exact solution for material {material!r}")


def classical_pressure() -> float:
    """p_c of the textbook formula (first order in δ/b)."""
    p, E, nu = _base_scene_params()
    return analytics.shrink_fit_pressure(p["a"], p["b"], p["c"], p["delta"], E, nu)


def level_geometry(level: int) -> dict:
    """Slave and master segment counts, slave chord h (reference), sagitta s = h²/8R, and
    s over the slave's radial displacement, the master's, and δ (linear exact values); the
    chord-clearance estimates of the mean error: one-sided −(2/3) s/δ, polyline
    −(2/3) (s − s_m)/δ (s_m the master's sagitta)."""
    p = mesh_params(level)
    R_s, R_m, delta = p["b"] + p["delta"], p["b"], p["delta"]
    h_s = 2.0 * R_s * math.sin(math.pi / 4 / p["inner_nc"])
    h_m = 2.0 * R_m * math.sin(math.pi / 4 / p["outer_nc"])
    s, s_m = h_s**2 / (8 * R_s), h_m**2 / (8 * R_m)
    ex = exact("linear")
    return dict(level=level, n_slave=p["inner_nc"], n_master=p["outer_nc"],
                nr=(p["inner_nr"], p["outer_nr"]), h=h_s, h_master=h_m, sagitta=s,
                s_over_u_slave=s / abs(ex.u_inner), s_over_u_master=s / ex.u_outer,
                s_over_delta=s / delta, delta_over_h_master=delta / h_m,
                chord_one_sided=-2.0 / 3.0 * s / delta,
                chord_polyline=-2.0 / 3.0 * (s - s_m) / delta)


# ---------------------------------------------------------------- one run (pool target)


def run_case(job: dict) -> dict:
    """Solve one (level, material, variant); the raw record (nodal values and forces)."""
    from fenicsx_mortar import SceneError, solve
    variant = Variant(*job["variant"])
    scene = make_scene(job["level"], job["material"], variant, job.get("arcs"))
    t0 = time.perf_counter()
    try:
        result = solve(scene, log=lambda s: print(f"[{job['key']}] {s}", flush=True))
    except pool.TimeLimit as e:
        return dict(job, converged=False, message=str(e), wall=time.perf_counter() - t0)
    except SceneError as e:  # the package refuses the variant (e.g. a slave smoothing)
        return dict(job, converged=False, refused=str(e), message=f"refused: {e}",
                    wall=time.perf_counter() - t0)
    except Exception as e:  # a crash is a result too
        traceback.print_exc()
        return dict(job, converged=False, message=f"{type(e).__name__}: {e}",
                    wall=time.perf_counter() - t0)
    rec = dict(job, converged=bool(result.converged), message=result.message,
               wall=time.perf_counter() - t0, dofs=int(result.summary.get("dofs", 0)))
    if not result.converged or not result.steps:
        return rec
    step = result.steps[-1]
    pair = result.pairs[0]
    d = pair.interface()
    theta = np.arctan2(d["y"], d["x"])
    order = np.argsort(theta)
    contact = step["contact"][scene.contacts[0].name]
    rec.update(newton=int(step["newton_iterations"]),
               theta=theta[order].tolist(), p=np.asarray(d["pressure"])[order].tolist(),
               active=np.asarray(d["active"])[order].astype(int).tolist(),
               r_slave=np.hypot(d["x"], d["y"])[order].tolist(),
               r_master=np.hypot(*pair.state.xm.T).tolist(),
               force_on_slave=contact["force_on_slave"], normal_force=contact["normal_force"],
               reactions={k: v for k, v in step["reactions"].items()})
    return rec


def warm_up(_arg=None) -> None:
    """Compile both materials' forms before the timed runs (in each worker)."""
    for material in MATERIALS:
        run_case(dict(key="warm-up", level=0, material=material, variant=tuple(VARIANTS[0])))


# ---------------------------------------------------------------- measures


def measures(rec: dict) -> dict | None:
    """Errors and counts of a converged run (None for a run that did not converge)."""
    if not rec.get("converged"):
        return None
    ex = exact(rec["material"])
    e = np.asarray(rec["p"]) / ex.pressure - 1.0
    inner = e[1:-1]
    react = rec["reactions"]
    R_in, R_out = react["inner_x0"]["x"], react["outer_x0"]["x"]
    F = rec["force_on_slave"][0]
    p, _, _ = _base_scene_params()
    return dict(
        max=float(np.abs(e).max()), mean=float(np.abs(e).mean()),
        ends=float(max(abs(e[0]), abs(e[-1]))), interior_max=float(np.abs(inner).max()),
        signed_mean=float(e.mean()), spread=float(inner.max() - inner.min()),
        active=int(np.sum(rec["active"])), nodes=len(e),
        balance_slave=abs(R_in + F) / abs(F), balance_rings=abs(R_in + R_out) / abs(R_in),
        hoop=R_in / ex.force - 1.0,
        u_slave=float(np.mean(rec["r_slave"]) - (p["b"] + p["delta"])),
        u_master=float(np.mean(rec["r_master"]) - p["b"]))


def orders(values: list[float | None], h: list[float]) -> list[float | None]:
    """Observed orders log(e_k/e_k+1) / log(h_k/h_k+1) between consecutive levels."""
    out = []
    for k in range(len(values) - 1):
        a, b = values[k], values[k + 1]
        ok = a is not None and b is not None and a > 0 and b > 0
        out.append(math.log(a / b) / math.log(h[k] / h[k + 1]) if ok else None)
    return out


def split_variants(runs: dict) -> tuple[list[Variant], list[tuple[Variant, str]]]:
    """(the variants that ran, [(variant, why) for those skipped]): skipped before running
    (:func:`refusal`) or refused by the package when the run started."""
    ran, skipped = [], []
    for v in VARIANTS:
        why = refusal(v)
        if why is None:
            mine = [r for r in runs.values() if Variant(*r["variant"]) == v]
            why = next((r["refused"] for r in mine if r.get("refused")), None)
        (ran if why is None else skipped).append(v if why is None else (v, why))
    return ran, skipped


def failure(message: str) -> str:
    """The solver's reason(s) in a stop message, each attempt with its first and last
    residual."""
    import re

    def attempt(text: str) -> str:
        reason = re.split(r",? residuals", text)[0].strip()
        res = re.search(r"residuals ([0-9eE.+\-, ]+)", text)
        if res:
            r = [x for x in res.group(1).replace(",", " ").split() if x]
            reason += f" (residual {r[0]} → {r[-1]} in {len(r) - 1} iterations)"
        return reason
    tail = message.split("cuts; ", 1)[-1]
    parts = tail.split("; with full Newton steps: ")
    return "; retried with full Newton steps: ".join(attempt(x) for x in parts)


def _key(level: int, material: str, variant: Variant) -> str:
    return f"L{level} {material} {variant.name}"


def _fmt(x: float | None, spec: str = ".2e") -> str:
    return "—" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)


def _pct(x: float | None, digits: int = 2) -> str:
    """x in per cent, fixed point, or two significant digits below 10^-digits %."""
    if x is None:
        return "—"
    if x != 0 and abs(100 * x) < 10.0**-digits:
        return f"{100 * x:.1e} %"
    return f"{100 * x:.{digits}f} %"


# ---------------------------------------------------------------- the document


def _provenance() -> str:
    def git(*args: str) -> str:
        try:
            return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True,
                                  timeout=10).stdout
        except (OSError, subprocess.SubprocessError):
            return "?"
    commit = git("rev-parse", "--short", "HEAD").strip()
    dirty = git("status", "--porcelain", "--", "fenicsx_mortar")
    files = [line[3:] for line in dirty.splitlines() if line.strip()]
    return (f"commit {commit}" + (f" with uncommitted changes in {', '.join(files)}"
                                  if files else ", clean fenicsx_mortar/"))


def _table_levels(levels: list[int], runs: dict) -> str:
    lines = ["| level | slave × master segments (radial) | dofs | slave h | sagitta s = h²/8R "
             "| s / \\|u_slave\\| | s / u_master | s / δ | δ / h_master | −(2/3) s/δ |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for k in levels:
        g = level_geometry(k)
        dofs = next((r.get("dofs") for r in runs.values() if r["level"] == k
                     and not Variant(*r["variant"]).matching and r.get("dofs")), None)
        lines.append(f"| {k} | {g['n_slave']} × {g['n_master']} ({g['nr'][0]}, {g['nr'][1]}) "
                     f"| {dofs or '—'} | {g['h']:.4f} | {g['sagitta']:.3e} "
                     f"| {g['s_over_u_slave']:.3f} | {g['s_over_u_master']:.3f} "
                     f"| {g['s_over_delta']:.3f} | {g['delta_over_h_master']:.2f} "
                     f"| {_pct(g['chord_one_sided'], 1)} |")
    return "\n".join(lines)


def _table_runs(material: str, levels: list[int], runs: dict, variants) -> str:
    lines = ["| variant | level | converged | Newton | active / nodes | max \\|e\\| "
             "| mean \\|e\\| | ends | interior spread | mean e | wall s |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for v in variants:
        for k in levels:
            rec = runs.get(_key(k, material, v))
            if rec is None or rec.get("refused"):
                continue
            m = measures(rec)
            if m is None:
                why = failure(rec.get("message", ""))[:160]
                lines.append(f"| {v.name} | {k} | **no**: {why} | — | — | — | — | — | — | — "
                             f"| {rec.get('wall', 0):.0f} |")
                continue
            lines.append(f"| {v.name} | {k} | yes | {rec['newton']} | {m['active']} / "
                         f"{m['nodes']} | {_pct(m['max'])} | {_pct(m['mean'])} "
                         f"| {_pct(m['ends'])} | {_pct(m['spread'])} | {_pct(m['signed_mean'])} "
                         f"| {rec['wall']:.1f} |")
    return "\n".join(lines)


def _series(material: str, levels: list[int], runs: dict, v: Variant, what: str) -> list:
    out = []
    for k in levels:
        rec = runs.get(_key(k, material, v))
        m = measures(rec) if rec else None
        out.append(None if m is None else m[what])
    return out


def _table_orders(material: str, levels: list[int], runs: dict, variants) -> str:
    h = [level_geometry(k)["h"] for k in levels]
    head = " | ".join(f"L{k}" for k in levels)
    lines = [f"| variant | measure | {head} | observed orders |",
             "|---|---|" + "---|" * len(levels) + "---|"]
    for v in variants:
        for what in ("max", "mean"):
            e = _series(material, levels, runs, v, what)
            if all(x is None for x in e):
                continue
            o = ", ".join(_fmt(x, ".2f") for x in orders(e, h))
            lines.append(f"| {v.name} | {what} \\|e\\| | "
                         + " | ".join(_fmt(x) for x in e) + f" | {o} |")
    return "\n".join(lines)


def _observations(levels: list[int], runs: dict, variants, skipped) -> list[str]:
    obs = []
    k0 = levels[0]
    g0 = level_geometry(k0)
    # the criterion at the coarsest level
    for v in variants:
        if v.slave is None:
            continue
        rec = runs.get(_key(k0, "linear", v))
        m = measures(rec) if rec else None
        if m is not None:
            ok = m["active"] == m["nodes"] and m["max"] <= CRITERION
            obs.append(f"Issue 17's criterion on level {k0} (s/|u_slave| = "
                       f"{g0['s_over_u_slave']:.2f}), linear, {v.name}: {m['active']} of "
                       f"{m['nodes']} slave nodes active, max |e| = {_pct(m['max'])} — "
                       + ("**met**." if ok else "**not met**."))
    for v, why in skipped:
        obs.append(f"Not run: {v.name} (master {v.master}, slave {v.slave}): {why}.")
    # one-sided smoothed: the chord clearance
    for name in ("hermite", "bspline"):
        v = next((x for x in variants if x.name == name), None)
        if v is None:
            continue
        rows = []
        for k in levels:
            rec = runs.get(_key(k, "linear", v))
            m = measures(rec) if rec else None
            if m is not None:
                rows.append(f"L{k} {_pct(m['signed_mean'])} vs "
                            f"{_pct(level_geometry(k)['chord_one_sided'])}")
        if rows:
            obs.append(f"One-sided {name} (linear): the mean error e against the chord-"
                       f"clearance estimate −(2/3) s/δ: " + "; ".join(rows) + ". The slave "
                       "polyline's own chords account for the error; what is left is of the "
                       "size of the rings' own discretization error (the matching-arcs "
                       "control).")
    # polyline oscillation and averaged normals
    v_none = next((x for x in variants if x.name == "none"), None)
    v_bs = next((x for x in variants if x.name == "bspline"), None)
    if v_none and v_bs:
        sp_n = _series("linear", levels, runs, v_none, "spread")
        sp_b = _series("linear", levels, runs, v_bs, "spread")
        pairs = [f"L{k} {_pct(a)} / {_pct(b)}" for k, a, b in zip(levels, sp_n, sp_b)]
        obs.append("Interior spread max e − min e (the oscillation of the nodal pressure), "
                   "linear, polyline / one-sided B-spline: " + "; ".join(pairs) + ".")
        pm = _series("linear", levels, runs, v_none, "signed_mean")
        est = [level_geometry(k)["chord_polyline"] for k in levels]
        obs.append("Polyline mean error e (linear) against the estimate −(2/3)(s − s_m)/δ "
                   "(both polylines' chords; s_m the master's sagitta): "
                   + "; ".join(f"L{k} {_pct(a)} vs {_pct(b)}"
                               for k, a, b in zip(levels, pm, est) if a is not None) + ".")
    # two-sided against the control (the rings' own discretization error)
    for v in variants:
        if v.slave is None:
            continue
        ratio = [(k, a / b) for k, a, b in zip(
            levels, _series("linear", levels, runs, v, "mean"),
            _series("linear", levels, runs, CONTROL, "mean")) if a is not None and b]
        if ratio:
            obs.append(f"{v.name} (linear): mean |e| / the matching-arcs control's = "
                       + ", ".join(f"L{k} {r:.2f}" for k, r in ratio)
                       + ": the error left is of the size of the rings' own discretization "
                       "error.")
    v_avg = next((x for x in variants if x.name == "averaged-tangent"), None)
    if v_none and v_avg:
        d = [abs(a - b) for a, b in zip(_series("linear", levels, runs, v_none, "max"),
                                         _series("linear", levels, runs, v_avg, "max"))
             if a is not None and b is not None]
        if d:
            obs.append(f"Averaged normals (averaged-tangent) and the polyline give the same "
                       f"pressures: their max |e| differ by at most {_pct(max(d))} on the "
                       f"levels where both converged (linear); both oscillate.")
    # convergence failures
    fails = [r for r in runs.values() if not r.get("converged") and not r.get("refused")]
    for r in sorted(fails, key=lambda r: (r["level"], r["material"])):
        g = level_geometry(r["level"])
        obs.append(f"Did not converge: level {r['level']}, {r['material']}, "
                   f"{Variant(*r['variant']).name} (δ / h_master = "
                   f"{g['delta_over_h_master']:.2f}; {r.get('wall', 0):.0f} s): "
                   f"{failure(r.get('message', ''))[:400]}.")
    # active nodes
    open_runs = []
    for r in runs.values():
        m = measures(r)
        if m is not None and m["active"] < m["nodes"]:
            open_runs.append(f"{r['key']} ({m['active']}/{m['nodes']})")
    obs.append("Every converged run has every slave node active." if not open_runs else
               "Runs with open slave nodes: " + ", ".join(sorted(open_runs)) + ".")
    # force balance
    bal = [max(m["balance_slave"], m["balance_rings"]) for m in
           (measures(r) for r in runs.values()) if m is not None]
    if bal:
        obs.append(f"Force balance: the reactions on the inner ring's x = 0 edge equal the "
                   f"contact force on the slave, and the outer ring's reaction, to within "
                   f"{max(bal):.1e} (relative) in every converged run.")
    return obs


def _control_check(levels: list[int], runs: dict) -> str:
    """The matching-arcs control against the exact solution, per level, and the Richardson
    extrapolation of its mean pressure from the two finest levels."""
    lines = ["| material | level | mean e | max \\|e\\| | u_slave / exact − 1 "
             "| u_master / exact − 1 | hoop force / exact − 1 |",
             "|---|---|---|---|---|---|---|"]
    extrap = []
    for material in MATERIALS:
        ex = exact(material)
        means = []
        for k in levels:
            rec = runs.get(_key(k, material, CONTROL))
            m = measures(rec) if rec else None
            if m is None:
                continue
            means.append((k, m["signed_mean"]))
            lines.append(f"| {material} | {k} | {_pct(m['signed_mean'], 3)} | {_pct(m['max'], 3)} "
                         f"| {_pct(m['u_slave'] / ex.u_inner - 1, 3)} "
                         f"| {_pct(m['u_master'] / ex.u_outer - 1, 3)} | {_pct(m['hoop'], 3)} |")
        if len(means) >= 2:
            (k1, e1), (k2, e2) = means[-2], means[-1]
            r = (4.0 * e2 - e1) / 3.0        # Richardson, O(h²)
            extrap.append(f"{material}: mean e on levels {k1}, {k2} = {_pct(e1, 4)}, "
                          f"{_pct(e2, 4)}, Richardson-extrapolated (O(h²)) {_pct(r, 4)}")
    return "\n".join(lines) + ("\n\n" + ";  ".join(extrap) + "." if extrap else "")


def write_doc(levels: list[int], runs: dict, wall: float | None, provenance: str) -> None:
    p, E, nu = _base_scene_params()
    lin, nh, pc = exact("linear"), exact("neo-hooke"), classical_pressure()
    variants, skipped = split_variants(runs)
    g0 = level_geometry(levels[0])
    doc = f"""# Curved non-matching interface: the shrink fit

<!-- generated by benchmarks/curved_interface.py; edit that file, not this one -->

An exact curved benchmark for the master (and slave) smoothings of docs/smoothing.md (issue
17). Run `.venv/bin/python benchmarks/curved_interface.py` (levels {", ".join(map(str, levels))},
2 workers{f", measured {wall:.0f} s wall" if wall else ""}); tests/test_curved_interface.py
runs its coarsest level. Code state of these numbers (when the run started): {provenance}.

## Set-up

Quarter model (scene `demos/scenes/shrink_fit.toml`, generator `meshes/shrink_fit.py`): an
inner ring a = {p['a']:g} ≤ r ≤ b + δ = {p['b'] + p['delta']:g} shrunk into an outer ring
b = {p['b']:g} ≤ r ≤ c = {p['c']:g}. In the reference configuration they overlap radially by
the interference δ = {p['delta']:g}; the contact resolves the overlap and there is no other
load. Symmetry supports u_x = 0 on x = 0 and u_y = 0 on y = 0 of both rings. Both rings
E = {E:g}, ν = {nu:g}, plane strain, `linear` or `neo-hooke`. Frictionless mortar contact
with Lagrange multipliers (dual basis), one load step (nothing scales with the pseudo-time:
the overlap is geometric, so the scene sets max_cuts = 0). Slave: the inner ring's outer arc
(convex; its chords lie inside the circle, an artificial clearance — the case issue 17
describes), master: the outer ring's inner arc, non-matching: {g0['n_slave']} against
{g0['n_master']} segments on level {levels[0]} (they share only the end nodes' angles).
Level k multiplies every element count (radial and circumferential, both rings) by 2^k.

Pressure error at slave node j: e_j = p_j / p − 1 with p the exact pressure below; max and
mean of |e_j| over **all** slave nodes, the two end nodes on the symmetry planes included
(there the open slave and master chains end; "ends" is their error alone); "interior
spread" = max e − min e over the other nodes (the oscillation); a node is active when
p_j > 0. Orders: log(e_k/e_k+1)/log(h_k/h_k+1), h the slave chord.

{_table_levels(levels, runs)}

u_slave = the inner ring's radial displacement at the interface ({lin.u_inner:.5f}),
u_master = the outer ring's ({lin.u_outer:.5f}), linear exact values. On level {levels[0]} the
slave sagitta is {g0['s_over_u_slave']:.2f} × |u_slave| and {g0['s_over_delta']:.2f} × δ:
the hard case of issue 17 (sagitta ≥ 1/5 of the radial displacement) whichever displacement
one takes. The last column is the chord-clearance estimate of a one-sided smoothing's mean
error (module docstring).

## Exact solution

Plane strain, a thick ring carries u(r) = A r + B/r (Lamé). Under the interface pressure p,
the outer ring's inner radius grows by p C_out and the inner ring's outer radius shrinks by
p C_in,

    C_out = (1+ν) b/E · ((1−2ν) b² + c²)/(c² − b²),
    C_in  = (1+ν) b/E · ((1−2ν) b² + a²)/(b² − a²),

and compatibility u_outer(b) − u_inner(b) = δ gives (first order in δ/b)

    p_c = δ / (C_out + C_in) = E δ (c² − b²)(b² − a²) / (2 (1−ν²) b³ (c² − a²))   (one material)
        = {pc:.6f}.

The package's `linear` model keeps the reference geometry in the bulk but makes contact in
the current configuration: with the rings' reference radii b + δ and b, the contact force
per radian f = δ / (C_in(b+δ)/(b+δ) + C_out(b)/b), the contact radius r_c = b + f C_out/b,
and the mortar's nodal pressure (force per current length) p = f / r_c
(`analytics.shrink_fit_linear`): p = {lin.pressure:.6f} ({_pct(lin.pressure / pc - 1, 3)}
against p_c), u_slave = {lin.u_inner:.6f}, u_master = {lin.u_outer:.6f}, r_c = {lin.r_contact:.6f}.
**This is the exact reference of the linear runs.**

Neo-Hooke: with the interference imposed as an initial overlap, finite deformation changes
the answer at O(δ/b). The axisymmetric solution r(R) of the same overlap (radial
equilibrium dP_r/dR + (P_r − P_θ)/R = 0 of the plane-strain Neo-Hooke law, free at r = a
and r = c, equal radius and force per radian at the interface) is a 1D boundary value
problem, solved to 1e-11 (`analytics.shrink_fit_neo_hooke`): p = {nh.pressure:.6f}
({_pct(nh.pressure / pc - 1, 3)} against Lamé's p_c, {_pct(nh.pressure / lin.pressure - 1, 3)}
against the linear model), u_slave = {nh.u_inner:.6f}, u_master = {nh.u_outer:.6f}. It is the
reference of the Neo-Hooke runs: exact for the continuum problem the runs discretize, but
computed, not closed form.

**Numerical check** — the polyline on *matching* arcs (outer_nc = inner_nc): slave and master
chords coincide in the deformed state, so only the rings' own discretization error (Q1
elements on polygonal rings) is left; it falls at O(h²) to the exact values:

{_control_check(levels, runs)}

## Results, linear

{_table_runs("linear", levels, runs, variants + [CONTROL])}

{_table_orders("linear", levels, runs, variants + [CONTROL])}

## Results, Neo-Hooke (against the axisymmetric Neo-Hooke solution)

{_table_runs("neo-hooke", levels, runs, variants + [CONTROL])}

{_table_orders("neo-hooke", levels, runs, variants + [CONTROL])}

![errors and pressure profile](curved_interface.png)

## Observations (from the numbers above)

""" + "\n".join(f"* {o}" for o in _observations(levels, runs, variants, skipped)) + "\n"
    MD.write_text(doc)


# ---------------------------------------------------------------- the plot


def plot(levels: list[int], runs: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    variants = split_variants(runs)[0] + [CONTROL]
    colors = {v.name: f"C{i}" for i, v in enumerate(variants)}
    colors[CONTROL.name] = "k"
    # variants that coincide (polyline and averaged normals) stay visible: markers and widths
    markers = {v.name: "osx^v<>Dp"[i % 9] for i, v in enumerate(variants)}
    widths = {v.name: 2.4 - 1.4 * (i % 2) for i, v in enumerate(variants)}
    h = np.array([level_geometry(k)["h"] for k in levels])
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.2), constrained_layout=True)
    for ax, material in zip(axes[:2], MATERIALS):
        for v in variants:
            for what, ls in (("mean", "-"), ("max", "--")):
                e = _series(material, levels, runs, v, what)
                if any(x is not None for x in e):   # a gap where a run did not converge
                    y = [np.nan if x is None else x for x in e]
                    ax.loglog(h, y, ls, marker=markers[v.name], ms=5,
                              lw=widths[v.name], mfc="none", color=colors[v.name],
                              label=v.name if what == "mean" else None)
        for slope, y0 in ((2, 0.6), (1, 0.6)):
            ax.loglog(h, y0 * (h / h[0]) ** slope, ":", color="0.5", lw=1)
            ax.text(h[-1], y0 * (h[-1] / h[0]) ** slope, f"h^{slope} ", color="0.4",
                    fontsize=8, ha="right", va="center")
        ax.axhline(CRITERION, color="r", lw=0.8, ls=":")
        ax.text(h[0], CRITERION, "1 %", color="r", fontsize=8, va="bottom", ha="right")
        ax.set(xlabel="slave chord h", ylabel="|p/p_exact − 1|: mean (solid), max (dashed)",
               title=f"{material}: nodal pressure error vs h")
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8)
    ax = axes[2]
    k0 = levels[0]
    for v in variants:
        rec = runs.get(_key(k0, "linear", v))
        if rec and rec.get("converged"):
            ax.plot(np.degrees(rec["theta"]), np.asarray(rec["p"]) / exact("linear").pressure,
                    "-", marker=markers[v.name], ms=5, mfc="none", lw=widths[v.name],
                    color=colors[v.name], label=v.name)
    ax.axhline(1.0, color="k", lw=0.8)
    g0 = level_geometry(k0)
    ax.set(xlabel="polar angle of the slave node (degrees)", ylabel="p / p_exact",
           title=f"level {k0}, linear: p along the arc\n{g0['n_slave']} slave × "
                 f"{g0['n_master']} master segments, s/|u_slave| = {g0['s_over_u_slave']:.2f}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(PNG, dpi=100, metadata={"Software": None})
    plt.close(fig)


# ---------------------------------------------------------------- main


def plan(levels: list[int]) -> list[tuple[int, str, Variant]]:
    """Every (level, material, variant) to run, the largest meshes first."""
    todo = [(k, m, v) for k in sorted(levels, reverse=True) for m in MATERIALS
            for v in [x for x in VARIANTS if available(x)] + [CONTROL]]
    return todo


def run_all(levels: list[int], workers: int, arcs: tuple | None = None) -> dict:
    OUT.mkdir(parents=True, exist_ok=True)
    runs: dict[str, dict] = {}

    def done(out: pool.Outcome) -> None:
        rec = out.record or dict(out.job.payload, converged=False, wall=out.wall,
                                 message=f"worker died (exit code {out.returncode})")
        if out.stopped and rec.get("converged") is False:
            rec["message"] = f"stopped by the {WALL_LIMIT:.0f} s wall limit; " + rec["message"]
        runs[rec["key"]] = rec
        m = measures(rec)
        state = (f"max {_pct(m['max'])}, mean {_pct(m['mean'])}, active {m['active']}/"
                 f"{m['nodes']}, Newton {rec['newton']}" if m else
                 rec["message"][:200] if rec.get("refused") else
                 "NOT CONVERGED: " + rec["message"][:200])
        print(f"{rec['key']:45s} {rec['wall']:6.1f} s  {state}", flush=True)

    every = [pool.Job(dict(key=_key(k, m, v), level=k, material=m, variant=tuple(v),
                           arcs=arcs), wall_limit=WALL_LIMIT, tag=_key(k, m, v))
             for k, m, v in plan(levels)]
    first = [j for j in every if j.payload["level"] == levels[0]]

    def jobs():
        """The coarsest level first; then the rest (largest first) without the variants
        the package refused there."""
        yield from first
        while sum(r["level"] == levels[0] for r in runs.values()) < len(first):
            yield None
        refused = {tuple(r["variant"]) for r in runs.values() if r.get("refused")}
        yield from (j for j in every if j.payload["level"] != levels[0]
                    and tuple(j.payload["variant"]) not in refused)

    with open(OUT / "workers.log", "w") as log:
        pool.run("benchmarks.curved_interface:run_case", jobs(), done, workers=workers,
                 warm_up="benchmarks.curved_interface:warm_up", output=log)
    return runs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", default=",".join(map(str, LEVELS)),
                    help="comma-separated mesh levels (0 = the scene's mesh)")
    ap.add_argument("--workers", type=int, default=2, help="worker processes")
    ap.add_argument("--redraw", action="store_true", help="no solve: doc and plot from "
                    f"{RUNS.relative_to(ROOT)}")
    ap.add_argument("--arcs", default=None, help="SLAVE,MASTER: the level-0 arc segment counts "
                    "instead of the scene's (e.g. 24,17, issue 31); prints max |e| per run, "
                    "writes no doc")
    args = ap.parse_args()
    wall = None
    if args.arcs:
        arcs = tuple(int(x) for x in args.arcs.split(","))
        levels = sorted(int(x) for x in args.levels.split(","))
        runs = run_all(levels, max(1, args.workers), arcs)
        (OUT / f"runs_{arcs[0]}x{arcs[1]}.json").write_text(json.dumps(runs) + "\n")
        print(f"\nslave x master = {arcs[0]} x {arcs[1]} segments on level 0: max |e| "
              "(ends, interior spread)")
        for v in VARIANTS + (CONTROL,):
            for m in MATERIALS:
                row = [measures(runs[_key(k, m, v)]) if _key(k, m, v) in runs else None
                       for k in levels]
                print(f"  {v.name:40s} {m:9s} " + "  ".join(
                    f"L{k}: {_pct(r['max'])} ({_pct(r['ends'])}, {_pct(r['spread'])})"
                    if r else f"L{k}: —" for k, r in zip(levels, row)))
        return
    if args.redraw:
        saved = json.loads(RUNS.read_text())
        levels, runs, wall = saved["levels"], saved["runs"], saved.get("wall")
        provenance = saved.get("provenance", "?")
    else:
        levels = sorted(int(x) for x in args.levels.split(","))
        provenance = _provenance()
        t0 = time.perf_counter()
        runs = run_all(levels, max(1, args.workers))
        wall = time.perf_counter() - t0
        RUNS.write_text(json.dumps(dict(levels=levels, runs=runs, wall=wall,
                                        provenance=provenance)) + "\n")
    write_doc(levels, runs, wall, provenance)
    plot(levels, runs)
    print(f"wrote {MD.relative_to(ROOT)}, {PNG.relative_to(ROOT)}, {RUNS.relative_to(ROOT)}"
          + (f" ({wall:.0f} s)" if wall else ""))


if __name__ == "__main__":
    main()
