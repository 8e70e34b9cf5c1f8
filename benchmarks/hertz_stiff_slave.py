"""Hertz with a stiff, finer slave on a soft curved master (issue 31, item 1): where the
error against Hertz comes from, per pairing, cell type and mesh.

    .venv/bin/python benchmarks/hertz_stiff_slave.py            # ~6 min on 2 cores
    .venv/bin/python benchmarks/hertz_stiff_slave.py --quick    # a/10 only, ~1 min

Set-up (issue 31): the B2 generator (``meshes/hertz.py``) with R = 2, the half-disk
(E = 500, ν = 0.25) and the block (E = 2000, ν = 0.3), both Neo-Hooke, plane strain, dead
traction 0.5 on the disk's flat edge (F = 2), h_c = a/10 within 0.3 of the contact point,
growing to h_far = 0.2; mortar, Lagrange multipliers, dual basis, one load step (the issue's
11 Newton iterations were the two load steps of the B2 scene together, 5 + 6). Pairings:
"stiff slave" = the block's top is the slave (the issue's), "soft slave" = the disk's arc.
Hertz: E* = 429.2, a = 0.10893, p₀ = 11.689.

What it measures, per run: p_max/p₀ − 1, the relative L2 error of the nodal pressures'
piecewise-linear interpolant on [−a, a] (``benchmarks/analytics.py`` definitions with this
problem's a and p₀), Newton iterations, the centre node's p/p₀ − 1 and where p_max sits. And
against the converged solution of the same continuum problem (the a/40 run of the same
pairing): each node's deviation from that solution's value there and from its hat-weighted
average ∫N_j p / ∫N_j (what a dual-basis multiplier approximates), and two floors of the L2
metric at the run's own node positions — the L2 error the run would have with the converged
nodal *averages* and with its *point values*: no contact discretization whose nodal pressures
are multipliers of a hat-function space can go below the first.

Mesh realizations: the same nominal mesh with h_c × (1 ± 0.3 %, − 0.6 %) — gmsh's unstructured
quads then differ node by node — shows how much of the a/10 numbers belong to one mesh.

Writes the section between ``<!-- stiff-slave -->`` markers of docs/hertz.md (kept there by
``benchmarks/hertz_refinement.py``) and ``results/hertz_stiff_slave/runs.json``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import trapezoid

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks import analytics  # noqa: E402

SCENE = ROOT / "demos" / "scenes" / "hertz.toml"
DOC = ROOT / "docs" / "hertz.md"
OUT = ROOT / "results" / "hertz_stiff_slave"
R, F = 2.0, 2.0
CYL, BLOCK = (500.0, 0.25), (2000.0, 0.3)
E_STAR = analytics.effective_modulus(*CYL, *BLOCK)
A = analytics.half_width(F, R, E_STAR)
P0 = analytics.peak_pressure(F, A)
MESH = dict(h_far=0.2, refine_radius=0.3)
MARK = ("<!-- stiff-slave -->", "<!-- /stiff-slave -->")


def make_scene(divisor: float, cell: str = "quadrilateral", stiff_slave: bool = True,
               scale: float = 1.0, steps: int = 1):
    """The issue's set-up at h_c = a/divisor (× ``scale``: another mesh realization)."""
    from fenicsx_mortar import load_scene
    from fenicsx_mortar.scene import Material
    scene = load_scene(SCENE)
    scene.mesh.cell = cell
    scene.mesh.params = dict(MESH, h_contact=A / divisor * scale, R=R)
    scene.bodies[0].material = Material(model="neo-hooke", E=CYL[0], nu=CYL[1])
    scene.bodies[1].material = Material(model="neo-hooke", E=BLOCK[0], nu=BLOCK[1])
    for d in scene.dirichlet:           # the disk's x-supports at (0, R) and (0, R/2)
        if d.body == "disk" and d.point is not None:
            d.point = [0.0, R * d.point[1]]
    if stiff_slave:
        c = scene.contacts[0]
        c.slave, c.master = "block_top", "disk_arc"
    scene.steps.count = steps
    scene.output.xdmf = scene.output.plots = False
    return scene


def l2_error(x: np.ndarray, p: np.ndarray) -> float:
    xs = np.linspace(-A, A, 4001)
    exact = analytics.pressure(xs, A, P0)
    return float(np.sqrt(trapezoid((np.interp(xs, x, p) - exact) ** 2, xs)
                         / trapezoid(exact ** 2, xs)))


def hat_averages(x: np.ndarray, xf: np.ndarray, pf: np.ndarray) -> np.ndarray:
    """∫ N_j p dx / ∫ N_j dx of the piecewise-linear pressure (xf, pf) over the hats of the
    nodes x (sorted; the first and last get 0: far outside the contact)."""
    out = np.zeros(len(x))
    for j in range(1, len(x) - 1):
        t = np.linspace(x[j - 1], x[j + 1], 4001)
        N = np.where(t < x[j], (t - x[j - 1]) / (x[j] - x[j - 1]),
                     (x[j + 1] - t) / (x[j + 1] - x[j]))
        out[j] = trapezoid(N * np.interp(t, xf, pf), t) / trapezoid(N, t)
    return out


def run(label: str, divisor: float, **kw) -> dict:
    from fenicsx_mortar import solve
    scene = make_scene(divisor, **kw)
    t0 = time.perf_counter()
    res = solve(scene, log=lambda s: None)
    if not res.converged:
        raise RuntimeError(f"{label}: {res.message}")
    d = res.pairs[0].interface()
    order = np.argsort(d["x"])
    x, p = d["x"][order], d["pressure"][order]
    c = int(np.argmin(np.abs(x)))
    rec = dict(label=label, divisor=divisor, dofs=int(res.summary["dofs"]),
               newton=[s["newton_iterations"] for s in res.steps], wall=time.perf_counter() - t0,
               x=x.tolist(), p=p.tolist(), p0_error=float(p.max() / P0 - 1.0),
               l2=l2_error(x, p), centre=float(p[c] / P0 - 1.0),
               at=float(x[np.argmax(p)] / A), **kw)
    print(f"{label:38s} dofs {rec['dofs']:6d}  p_max/p0-1 {100 * rec['p0_error']:+.2f} %  "
          f"L2 {100 * rec['l2']:.2f} %  centre {100 * rec['centre']:+.2f} %  "
          f"p_max at x/a {rec['at']:+.3f}  Newton {rec['newton']}  {rec['wall']:.0f} s",
          flush=True)
    return rec


def against_reference(rec: dict, ref: dict) -> dict:
    """The run's nodes against the converged solution ``ref`` (same pairing, a/40)."""
    x, p = np.array(rec["x"]), np.array(rec["p"])
    xf, pf = np.array(ref["x"]), np.array(ref["p"])
    point = np.interp(x, xf, pf)
    avg = hat_averages(x, xf, pf)
    inside = np.abs(x) < 0.9 * A
    return dict(floor_average=l2_error(x, avg), floor_point=l2_error(x, point),
                floor_hertz=l2_error(x, analytics.pressure(x, A, P0)),
                dev_point_inside=float(np.abs(p - point)[inside].max() / P0),
                dev_average_inside=float(np.abs(p - avg)[inside].max() / P0),
                worst_at=float(x[inside][np.argmax(np.abs(p - avg)[inside])] / A),
                edge=[float(v) for v in ((p - avg) / P0)[np.abs(x) >= 0.9 * A] if v != 0.0])


def plan(quick: bool) -> list[tuple[str, float, dict]]:
    jobs = [("stiff slave, quads, a/10", 10, {}),
            ("stiff slave, quads, a/10, 2 steps", 10, dict(steps=2)),
            ("soft slave, quads, a/10", 10, dict(stiff_slave=False)),
            ("stiff slave, triangles, a/10", 10, dict(cell="triangle")),
            ("soft slave, triangles, a/10", 10, dict(cell="triangle", stiff_slave=False))]
    jobs += [(f"stiff slave, quads, a/10, h_c x {s}", 10, dict(scale=s))
             for s in (0.994, 0.997, 1.003)]
    if not quick:
        for div in (20, 40):
            jobs += [(f"stiff slave, quads, a/{div}", div, {}),
                     (f"soft slave, quads, a/{div}", div, dict(stiff_slave=False))]
    return jobs


def write_doc(runs: list[dict], wall: float) -> None:
    by = {r["label"]: r for r in runs}
    pct = lambda v: f"{100 * v:+.2f} %"  # noqa: E731
    rows = ["| run | dofs | Newton | p_max/p₀ − 1 | p_max at x/a | centre node p/p₀ − 1 | L2 on "
            "[−a, a] | L2 floor: converged averages / point values at these nodes |",
            "|---|---|---|---|---|---|---|---|"]
    for r in runs:
        ref = by.get(("soft" if not r.get("stiff_slave", True) else "stiff")
                     + " slave, quads, a/40")
        floor = "—"
        if ref is not None and r is not ref:
            c = against_reference(r, ref)
            r["vs_reference"] = c
            floor = f"{100 * c['floor_average']:.2f} % / {100 * c['floor_point']:.2f} %"
        rows.append(f"| {r['label']} | {r['dofs']} | {', '.join(map(str, r['newton']))} "
                    f"| {pct(r['p0_error'])} | {r['at']:+.2f} | {pct(r['centre'])} "
                    f"| {100 * r['l2']:.2f} % | {floor} |")
    lines = [MARK[0], "## Stiff, finer slave on a soft curved master (issue 31)", "",
             "*Generated by `benchmarks/hertz_stiff_slave.py` (its docstring has the set-up "
             f"and the measures; {wall / 60:.0f} min).* R = 2, disk E = 500, ν = 0.25, block "
             "E = 2000, ν = 0.3, F = 2, Neo-Hooke both, h_c = a/10 within 0.3, h_far = 0.2, "
             f"dual multipliers, one load step: a = {A:.5f}, p₀ = {P0:.3f}.", ""] + rows
    dev = [r for r in runs if "vs_reference" in r and r["divisor"] == 10]
    if dev:
        lines += ["", "Per node against the converged solution of the same pairing (a/40): "
                  "largest deviation inside |x| < 0.9a from its point value / from its hat "
                  "average, in % of p₀, and where the latter is; the edge nodes' deviation from "
                  "their hat averages:", "",
                  "| run | point | average | at x/a | edge nodes |", "|---|---|---|---|---|"]
        for r in dev:
            c = r["vs_reference"]
            lines.append(f"| {r['label']} | {100 * c['dev_point_inside']:.2f} | "
                         f"{100 * c['dev_average_inside']:.2f} | {c['worst_at']:+.2f} | "
                         + ", ".join(f"{100 * v:+.2f}" for v in c["edge"]) + " |")
    lines.append(MARK[1])
    section = "\n".join(lines) + "\n"
    text = DOC.read_text() if DOC.exists() else ""
    if MARK[0] in text:
        head, rest = text.split(MARK[0], 1)
        text = head + section + rest.split(MARK[1], 1)[1].lstrip("\n")
    else:
        text = text.rstrip("\n") + "\n\n" + section
    DOC.write_text(text)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a/10 only (no reference runs)")
    args = ap.parse_args()
    print(f"a = {A:.6f}, p0 = {P0:.4f}, E* = {E_STAR:.2f}", flush=True)
    t0 = time.perf_counter()
    runs = [run(label, div, **kw) for label, div, kw in plan(args.quick)]
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "runs.json").write_text(json.dumps(runs))
    write_doc(runs, time.perf_counter() - t0)
    print(f"wrote {DOC.relative_to(ROOT)} ({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
