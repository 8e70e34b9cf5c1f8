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
``benchmarks/hertz_refinement.py``) and ``results/hertz_stiff_slave/runs.json`` (``--redraw``
rewrites the section from it).
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
    lines += ["", "What the numbers show:", ""] + observations(by)
    lines.append(MARK[1])
    section = "\n".join(lines) + "\n"
    text = DOC.read_text() if DOC.exists() else ""
    if MARK[0] in text:
        head, rest = text.split(MARK[0], 1)
        text = head + section + rest.split(MARK[1], 1)[1].lstrip("\n")
    else:
        text = text.rstrip("\n") + "\n\n" + section
    DOC.write_text(text)


def observations(by: dict) -> list[str]:
    """The section's conclusions, from the numbers (the runs present)."""
    out = []
    g = by.get
    st, so = g("stiff slave, quads, a/10"), g("soft slave, quads, a/10")
    if st and so:
        out.append(f"* **The pairing is not the cause.** Block (stiff, finer overall) or disk as "
                   f"the slave, a/10 quads: p_max/p₀ − 1 = {100 * st['p0_error']:+.2f} % / "
                   f"{100 * so['p0_error']:+.2f} %, the centre node {100 * st['centre']:+.2f} % / "
                   f"{100 * so['centre']:+.2f} %, L2 {100 * st['l2']:.2f} % / "
                   f"{100 * so['l2']:.2f} %"
                   + "".join(f"; a/{d}: {100 * g(f'stiff slave, quads, a/{d}')['p0_error']:+.2f} "
                             f"% / {100 * g(f'soft slave, quads, a/{d}')['p0_error']:+.2f} %"
                             for d in (20, 40) if g(f"stiff slave, quads, a/{d}")
                             and g(f"soft slave, quads, a/{d}")) + ".")
    ref = g("stiff slave, quads, a/40")
    if ref:
        out.append(f"* **The continuum problem is not Hertz's.** Refined to a/40 (98k dofs) both "
                   f"pairings converge to p_max/p₀ − 1 = {100 * ref['p0_error']:+.2f} % "
                   f"(a/20: {100 * g('stiff slave, quads, a/20')['p0_error']:+.2f} %): finite "
                   "bodies (the block is 9a deep, the half-disk loaded 18a above the contact) and "
                   "finite strain (p₀/E of the disk 2.3 %) against Hertz's small-strain half-"
                   "spaces. So |p_max/p₀ − 1| ≤ 1.0 % at a/10 holds only where the mesh's own "
                   "error at the centre node happens to be negative: "
                   + ", ".join(f"{100 * r['p0_error']:+.2f} %" for k, r in by.items()
                               if k.startswith("stiff slave, quads, a/10") and "2 steps" not in k)
                   + " on the four a/10 realizations below.")
    reals = [r for k, r in by.items() if k.startswith("stiff slave, quads, a/10") and
             "2 steps" not in k]
    pm = [100 * r["p0_error"] for r in reals]
    l2 = [100 * r["l2"] for r in reals]
    if st and len(reals) > 1:
        c = st.get("vs_reference", {})
        out.append(f"* **The +1.5 % belongs to one mesh.** The same nominal mesh with h_c changed "
                   f"by 0.3–0.6 % (four gmsh realizations): p_max/p₀ − 1 from {min(pm):+.2f} % to "
                   f"{max(pm):+.2f} %, L2 from {min(l2):.2f} % to {max(l2):.2f} %. On the "
                   "issue's realization p_max sits at the node next to the centre, x/a = "
                   f"{st['at']:+.2f}, and that node and the next deviate from the converged "
                   f"solution's hat averages by up to {100 * c.get('dev_average_inside', 0):.2f} % "
                   f"of p₀ (at x/a = {c.get('worst_at', 0):+.2f}), in both pairings alike: under "
                   "the disk's contact surface there gmsh's quad recombination left an irregular "
                   "node (the surface node at x/a = +0.20 is shared by three quads; the other "
                   "realizations have none within |x| < 0.6a, and there every node inside "
                   "0.9a is within about 1 % of p₀ of the converged averages and p_max is the "
                   "centre node). Such nodes are common in these meshes (the B2 meshes of "
                   "docs/hertz.md have 3 at a/10 and 4 at a/20 within the refined zone): a "
                   "structured layer of quads along the contact surfaces would remove them; the "
                   "generator is left as it is (every Hertz result would move).")
    if st and "vs_reference" in st:
        fl = [r["vs_reference"]["floor_average"] for r in reals if "vs_reference" in r]
        out.append(f"* **The L2 metric has a floor at a/10.** A dual-basis multiplier is a hat "
                   "average of the pressure, ∫N_j p/∫N_j, not its value at the node; with the "
                   "converged solution's exact hat averages at these nodes the L2 error against "
                   f"Hertz would be {100 * min(fl):.2f}–{100 * max(fl):.2f} % (with its point "
                   f"values {100 * st['vs_reference']['floor_point']:.2f} %, with Hertz's own "
                   f"point values {100 * st['vs_reference']['floor_hertz']:.2f} %); the runs "
                   f"reach {min(l2):.2f}–{max(l2):.2f} %, within 0.1 percentage point of that "
                   "floor. An L2 of 2.2 % at a/10 is below what nodal averages of the converged "
                   "pressure can give. The dual basis at the edge of contact is not the cause: "
                   "the quads' edge nodes lie "
                   + ", ".join(f"{100 * min(r['vs_reference']['edge']):+.2f}" for r in reals
                               if "vs_reference" in r and r["vs_reference"]["edge"])
                   + " % of p₀ (the lowest per run) from the converged hat averages.")
    tri = [g("stiff slave, triangles, a/10"), g("soft slave, triangles, a/10")]
    if all(tri):
        out.append(f"* Triangles (P1): p_max/p₀ − 1 = {100 * tri[0]['p0_error']:+.2f} % / "
                   f"{100 * tri[1]['p0_error']:+.2f} % (stiff / soft slave), L2 "
                   f"{100 * tri[0]['l2']:.2f} % / {100 * tri[1]['l2']:.2f} %: the stiffer P1 "
                   "bulk narrows the contact (edge nodes 3–4 % of p₀ below the converged "
                   "averages), whatever the pairing.")
    two = g("stiff slave, quads, a/10, 2 steps")
    if two and st:
        out.append(f"* Newton: {st['newton'][0]} iterations in one load step; the issue's 11 were "
                   f"the B2 scene's two load steps together ({' + '.join(map(str, two['newton']))})"
                   "; Kratos: 7 in one step (its own quad mesh: +1.04 %, L2 2.50 %, issue 31; "
                   "not rerun).")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a/10 only (no reference runs)")
    ap.add_argument("--redraw", action="store_true", help="no solve: the section from the "
                    "saved runs (results/hertz_stiff_slave/runs.json)")
    args = ap.parse_args()
    print(f"a = {A:.6f}, p0 = {P0:.4f}, E* = {E_STAR:.2f}", flush=True)
    if args.redraw:
        saved = json.loads((OUT / "runs.json").read_text())
        write_doc(saved["runs"], saved["wall"])
        print(f"wrote {DOC.relative_to(ROOT)} from the saved runs")
        return
    t0 = time.perf_counter()
    runs = [run(label, div, **kw) for label, div, kw in plan(args.quick)]
    OUT.mkdir(parents=True, exist_ok=True)
    wall = time.perf_counter() - t0
    (OUT / "runs.json").write_text(json.dumps(dict(runs=runs, wall=wall)))
    write_doc(runs, wall)
    print(f"wrote {DOC.relative_to(ROOT)} ({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
