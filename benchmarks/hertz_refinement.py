"""Hertz benchmark (docs/benchmarks.md B2) under mesh refinement: accuracy and cost.

What it measures
    The scene ``demos/scenes/hertz.toml`` (half-disk R = 1 on the block [-1, 1] x [-1, 0],
    Neo-Hooke E = 1000, nu = 0.3, F = 1, mortar contact with Lagrange multipliers, 2 load
    steps) is solved with the element size near the contact point set to h_contact = a/5,
    a/10, a/20 (a = 0.04814, the analytic half-width). Everything else in the scene is kept,
    except that the refined zone radius is set explicitly to REFINE_RADIUS = 0.15 >= 3a, so
    the uniformly refined zone covers the contact zone at every size.
    For each size it records: number of dofs, slave nodes in contact (last step), the
    accuracy metrics of ``benchmarks/analytics.py::hertz_metrics`` (p_max/p0 - 1, a_fit/a - 1,
    relative L2 pressure error on [-a, a], |total contact force - F|/F), Newton iterations
    and augmentations per load step, and the wall time in total and by phase
    (``Result.timings``).
    Control: the same three meshes are solved again with the small-strain linear elastic law
    for both bodies, to see how much of the difference from the (small-strain) Hertz formula
    comes from the finite-strain Neo-Hooke law.

Outputs (all overwritten on every run)
    docs/hertz.md                set-up, formulas, tables, observed convergence orders
    docs/hertz_pressure.png      nodal pressures of every size vs p0 sqrt(1 - x^2/a^2)
    docs/hertz_convergence.png   log-log L2 and p0 errors vs h_contact

How to run (from the repository root, serial)
    .venv/bin/python benchmarks/hertz_refinement.py

How long it takes
    About 3.5 minutes of CPU time on one core; wall time measured 257 s, 294 s and 385 s
    on a shared machine. Per material law a/5 ~5-15 s, a/10 ~15-30 s, a/20 ~90-200 s
    (bulk assembly and the linear solves dominate).
    a/40 is not included: a trial run was stopped after more than 10 minutes.
    The measured time of the run is written into docs/hertz.md.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import dolfinx  # noqa: E402
from fenicsx_mortar import load_scene, solve  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks import analytics  # noqa: E402
from benchmarks.analytics import hertz_metrics  # noqa: E402

SCENE = ROOT / "demos" / "scenes" / "hertz.toml"
DOCS = ROOT / "docs"
DIVISORS = (5, 10, 20)          # h_contact = a / divisor
REFINE_RADIUS = 0.15            # >= 3a = 0.1444: the refined zone covers the contact zone
CONTROL_MODEL = "linear"        # control runs: same scenes with a small-strain bulk law
a, p0, E_star = analytics.HERTZ_A, analytics.HERTZ_P0, analytics.HERTZ_E_STAR


def run_size(divisor: int, model: str | None = None) -> dict:
    """Solve the Hertz scene with h_contact = a/divisor (and, if given, the material model
    ``model`` for both bodies); return metrics, costs and the nodal pressures."""
    scene = load_scene(SCENE)
    scene.mesh.params = dict(scene.mesh.params, h_contact=a / divisor,
                             refine_radius=REFINE_RADIUS)
    if model is not None:
        for body in scene.bodies:
            body.material.model = model
    tag = f"a/{divisor}" + (f", {model}" if model else "")
    result = solve(scene, log=lambda s: print(f"  [{tag}] {s}", flush=True))
    if not result.converged:
        raise RuntimeError(f"h_contact = a/{divisor}: {result.message}")
    last = result.steps[-1]["contact"][scene.contacts[0].name]
    d = result.pairs[0].interface()
    order = np.argsort(d["x"])
    return dict(
        divisor=divisor, h=a / divisor, dofs=result.summary["dofs"],
        active=last["active_nodes"], metrics=hertz_metrics(result),
        newton=[s["newton_iterations"] for s in result.steps],
        augmentations=[s["augmentations"] for s in result.steps],
        timings=dict(result.timings),
        x=d["x"][order], p=d["pressure"][order])


def orders(runs: list[dict], key: str) -> list[float]:
    """Observed order log(e_i/e_{i+1}) / log(h_i/h_{i+1}) between consecutive sizes."""
    e = [abs(r["metrics"][key]) for r in runs]
    return [np.log(e[i] / e[i + 1]) / np.log(runs[i]["h"] / runs[i + 1]["h"])
            for i in range(len(runs) - 1)]


def plot_pressure(runs: list[dict], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    xs = np.linspace(-1.5 * a, 1.5 * a, 1201)
    ax.plot(xs / a, analytics.pressure(xs, a, p0) / p0, "k-", lw=1.2,
            label=r"analytic $p_0\sqrt{1-x^2/a^2}$")
    markers = "osd^v"
    for r, m in zip(runs, markers):
        sel = np.abs(r["x"]) <= 1.5 * a
        ax.plot(r["x"][sel] / a, r["p"][sel] / p0, m, ms=4, mfc="none", ls=":", lw=0.8,
                label=f"$h_c = a/{r['divisor']}$")
    ax.set_xlim(-1.5, 1.5)
    ax.set_xlabel("x / a  (current position of the slave nodes)")
    ax.set_ylabel("p / p$_0$")
    ax.set_title(f"Hertz (B2): nodal mortar pressures, a = {a:.5f}, p$_0$ = {p0:.4f}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower center")
    fig.tight_layout()
    fig.savefig(path, dpi=120, metadata={"Software": None})
    plt.close(fig)


def plot_convergence(runs: list[dict], path: Path) -> None:
    h = np.array([r["h"] for r in runs])
    fig, ax = plt.subplots(figsize=(5.6, 4.0))
    for key, label, m in (("l2_error", "relative L2 error of p on [-a, a]", "o-"),
                          ("p0_error", "|p$_{max}$/p$_0$ - 1|", "s-")):
        ax.loglog(h, [abs(r["metrics"][key]) for r in runs], m, label=label)
    e0 = runs[0]["metrics"]["l2_error"]
    ax.loglog(h, e0 * h / h[0], "k--", lw=0.8, label="slope 1 (reference)")
    ax.set_xticks(h, [f"a/{r['divisor']}" for r in runs])
    ax.minorticks_off()
    ax.set_xlabel("h$_c$ (element size at the contact)")
    ax.set_ylabel("relative error")
    ax.set_title("Hertz (B2): error vs mesh size")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120, metadata={"Software": None})
    plt.close(fig)


def write_doc(runs: list[dict], controls: list[dict], total_seconds: float,
              path: Path) -> None:
    phases = []
    for r in runs:
        phases += [k for k in r["timings"] if k != "total" and k not in phases]
    pct = lambda v: f"{100 * v:+.2f} %"  # noqa: E731
    acc = ["| h_c | h_c value | dofs | slave nodes in contact | p_max/p0 − 1 | a_fit/a − 1 "
           "| L2 error on [−a, a] | \\|F_c − F\\|/F |",
           "|---|---|---|---|---|---|---|---|"]
    for r in runs:
        m = r["metrics"]
        acc.append(f"| a/{r['divisor']} | {r['h']:.5f} | {r['dofs']} | {r['active']} "
                   f"| {pct(m['p0_error'])} | {pct(m['a_error'])} | {100 * m['l2_error']:.2f} % "
                   f"| {m['force_error']:.1e} |")
    cost = ["| h_c | Newton its per step | augmentations per step | wall total [s] | "
            + " | ".join(f"{k} [s]" for k in phases) + " |",
            "|---" * (4 + len(phases)) + "|"]
    for r in runs:
        t = r["timings"]
        cost.append(f"| a/{r['divisor']} | {', '.join(map(str, r['newton']))} "
                    f"| {', '.join(map(str, r['augmentations']))} | {t['total']:.1f} | "
                    + " | ".join(f"{t.get(k, 0.0):.1f}" for k in phases) + " |")
    o_l2, o_p0 = orders(runs, "l2_error"), orders(runs, "p0_error")
    order_rows = ["| sizes | order of L2 error | order of \\|p_max/p0 − 1\\| |", "|---|---|---|"]
    for i in range(len(runs) - 1):
        order_rows.append(f"| a/{runs[i]['divisor']} → a/{runs[i + 1]['divisor']} "
                          f"| {o_l2[i]:.2f} | {o_p0[i]:.2f} |")

    ctrl = ["| h_c | Neo-Hooke: p_max/p0 − 1 | a_fit/a − 1 | L2 error "
            f"| {CONTROL_MODEL}: p_max/p0 − 1 | a_fit/a − 1 | L2 error "
            f"| {CONTROL_MODEL} wall [s] |",
            "|---|---|---|---|---|---|---|---|"]
    for r, c in zip(runs, controls):
        m, mc = r["metrics"], c["metrics"]
        ctrl.append(f"| a/{r['divisor']} | {pct(m['p0_error'])} | {pct(m['a_error'])} "
                    f"| {100 * m['l2_error']:.2f} % | {pct(mc['p0_error'])} | {pct(mc['a_error'])} "
                    f"| {100 * mc['l2_error']:.2f} % | {c['timings']['total']:.1f} |")
    # largest Neo-Hooke vs small-strain difference of each metric, in percentage points
    diff = {k: 100 * max(abs(r["metrics"][k] - c["metrics"][k]) for r, c in zip(runs, controls))
            for k in ("p0_error", "a_error", "l2_error")}
    smallest = 100 * min(min(abs(r["metrics"]["p0_error"]), abs(r["metrics"]["a_error"]))
                         for r in runs)
    if max(diff["p0_error"], diff["a_error"]) < 0.5 * smallest:
        verdict = ("small compared with the p₀ and a errors themselves, so at these sizes\n"
                   "  those errors are not mainly due to the finite-strain bulk law")
    else:
        verdict = ("not small compared with the p₀ and a errors themselves, so part of\n"
                   "  those errors is the difference between the finite-strain and the\n"
                   "  small-strain bulk law")
    within = [f"a/{r['divisor']}" for r in runs
              if max(abs(r["metrics"]["p0_error"]), abs(r["metrics"]["a_error"])) < 0.02]
    outside = [f"a/{r['divisor']}" for r in runs if f"a/{r['divisor']}" not in within]
    tol = (f"both are within the demo's 2 % tolerance at {', '.join(within) or 'no size'}"
           + (f" and outside it at {', '.join(outside)}" if outside else ""))
    def trend(key: str) -> str:
        e = [abs(r["metrics"][key]) for r in runs]
        return ("decreases in magnitude" if all(x > y for x, y in zip(e, e[1:]))
                else "does not decrease monotonically in magnitude")
    l2 = [100 * r["metrics"]["l2_error"] for r in runs]
    p0e = [100 * r["metrics"]["p0_error"] for r in runs]
    ae = [100 * r["metrics"]["a_error"] for r in runs]
    fe = max(r["metrics"]["force_error"] for r in runs)
    strain = p0 / analytics.HERTZ_E          # order of the strains near the contact
    seq = lambda v: " → ".join(f"{x:+.2f} %" for x in v)  # noqa: E731
    text = f"""# Hertz contact under mesh refinement (B2)

*Generated by `benchmarks/hertz_refinement.py`; do not edit by hand — rerun the script
(`.venv/bin/python benchmarks/hertz_refinement.py`, about {total_seconds / 60:.0f} min).*

## Set-up

Scene `demos/scenes/hertz.toml` (docs/benchmarks.md B2): a half-disk of radius R = 1 (slave
surface: its arc) is pressed onto the block [−1, 1] × [−1, 0] (master: its top) by a dead
traction 0.5 on its flat edge, total force F = 1 per unit thickness. Both bodies Neo-Hooke,
E = 1000, ν = 0.3, plane strain, quadrilateral meshes. Block bottom u_y = 0, u_x = 0 at
(0, −1); half-disk u_x = 0 at (0, 1) and (0, 0.5). Mortar contact, Lagrange multipliers
solved by the semi-smooth Newton method with the dual basis (the scene's enforcement,
docs/design.md §5a), 2 load steps. Only the mesh changes between the runs: element size
h_c near the contact point, uniform within distance {REFINE_RADIUS} (≥ 3a) of it, growing to
0.1 away from it (`meshes/hertz.py`).

## Analytic solution (small strain)

1/E* = (1 − ν₁²)/E₁ + (1 − ν₂²)/E₂  →  E* = {E_star:.2f}

a = 2 √(F R / (π E*)) = {a:.5f},  p₀ = 2F / (π a) = {p0:.4f},  p(x) = p₀ √(1 − x²/a²)

Metrics (`hertz_metrics` in `benchmarks/analytics.py`): p_max/p₀ − 1 from the largest nodal
pressure; a_fit/a − 1 where a_fit is the least-squares fit of p_max √(1 − x²/a_fit²) to the
nodal pressures; the relative L2 error of the piecewise-linear interpolant of the nodal
pressures against p(x) on [−a, a]; |F_c − F|/F with F_c the total contact force on the
slave. x is the current position of the slave nodes.

The simulation is finite-deformation (Neo-Hooke) and the contact pressure is evaluated on the
deformed configuration; at this load the strains near the contact are of order
p₀/E = {strain:.1%}, so the computed solution differs slightly from the small-strain Hertz
formula and need not converge exactly to it. As a control, the same meshes are also solved
with the small-strain linear elastic law (`model = "{CONTROL_MODEL}"`) for both bodies; the
contact kinematics stay those of the deformed configuration in both cases.

## Results

Accuracy (last load step, full load):

{chr(10).join(acc)}

Cost (one MPI rank; phases from `Result.timings`, contact = contact search and mortar
assembly, bulk_assembly = bulk residual and tangent):

{chr(10).join(cost)}

Control: Neo-Hooke against the small-strain `{CONTROL_MODEL}` law on the same meshes:

{chr(10).join(ctrl)}

Observed convergence orders between consecutive sizes (h halves each time, Neo-Hooke):

{chr(10).join(order_rows)}

![nodal pressures](hertz_pressure.png)

![errors vs h](hertz_convergence.png)

## What the numbers show

* The total contact force equals the applied force to round-off at every size
  (largest |F_c − F|/F = {fe:.0e}).
* The relative L2 pressure error decreases with refinement: {" → ".join(f"{x:.2f} %" for x in l2)}
  (observed orders {", ".join(f"{o:.2f}" for o in o_l2)}).
* The peak pressure error goes {seq(p0e)} ({trend("p0_error")}) and the fitted
  half-width error {seq(ae)} ({trend("a_error")});
  {tol}.
* With the small-strain `{CONTROL_MODEL}` law the metrics differ from the Neo-Hooke ones by
  at most {diff['p0_error']:.2f} (p₀), {diff['a_error']:.2f} (a) and {diff['l2_error']:.2f}
  (L2) percentage points: {verdict}.
* Cost grows quickly with refinement; the bulk assembly and the linear solves take most of
  the time. A separate trial at h_c = a/40 (not rerun by the script) was stopped after
  more than 10 minutes, so that size is not included.

Total run time of the script for this document: {total_seconds:.0f} s
(dolfinx {dolfinx.__version__}, one MPI rank). Wall times depend on the machine and its
load: they change from one run to the next, the accuracy numbers do not.
"""
    # sections other benchmarks keep in this file (benchmarks/hertz_stiff_slave.py)
    if path.exists():
        old = path.read_text()
        for mark in ("stiff-slave",):
            m0, m1 = f"<!-- {mark} -->", f"<!-- /{mark} -->"
            if m0 in old and m1 in old:
                text += "\n" + m0 + old.split(m0, 1)[1].split(m1, 1)[0] + m1 + "\n"
    path.write_text(text)


def main() -> None:
    t0 = time.perf_counter()
    runs = []
    for n in DIVISORS:
        print(f"h_contact = a/{n} = {a / n:.6f}", flush=True)
        runs.append(run_size(n))
        m = runs[-1]["metrics"]
        print(f"  p0 {100 * m['p0_error']:+.2f} %, a {100 * m['a_error']:+.2f} %, "
              f"L2 {100 * m['l2_error']:.2f} %, force {m['force_error']:.1e}, "
              f"{runs[-1]['timings']['total']:.1f} s", flush=True)
    DOCS.mkdir(exist_ok=True)
    plot_pressure(runs, DOCS / "hertz_pressure.png")
    plot_convergence(runs, DOCS / "hertz_convergence.png")
    controls = []
    for n in DIVISORS:
        print(f"control: h_contact = a/{n}, material {CONTROL_MODEL}", flush=True)
        controls.append(run_size(n, CONTROL_MODEL))
    write_doc(runs, controls, time.perf_counter() - t0, DOCS / "hertz.md")
    print(f"wrote docs/hertz.md, docs/hertz_pressure.png, docs/hertz_convergence.png "
          f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
