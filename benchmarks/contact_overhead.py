"""Contact overhead per Newton iteration, and how the contact cost scales (issue 7).

What it measures
----------------
1. **Hertz (B2) at h_c = a/20** (a = 0.04814, mesh parameter ``h_contact = a/20``), the
   scene ``demos/scenes/hertz.toml`` at that size with its enforcement (Lagrange multipliers,
   dual basis, the package's default). By default the state is the disk
   pressed rigidly into the block by δ = a²/(2R), so that its arc overlaps the block over
   about the Hertz width (the converged active set's size; ``--solve-hertz`` solves the
   scene instead, which takes minutes, and prints the run's own phase times). In that
   state one Newton iteration's worth of work — one residual and one Jacobian evaluation —
   is timed through the solver's own callbacks (``evaluate_residual`` / ``evaluate_jacobian``)
   with a fresh ``Timings`` per repetition, ``--reps`` times, and the medians are printed:

   * bulk assembly: the UFL residual (with lifting) and Jacobian, as the solver assembles
     them (``bulk_assembly``: the callbacks' time less the contact work inside them);
   * contact (``contact``: everything the pair hooks do), with its sub-phases search
     (``contact_search``), kernel (``contact_kernel``: curve + projection + mortar
     integration, one vectorized pass), PETSc insertion (``contact_insertion``) and the
     rest (gather of coordinates, nodal sums, enforcement, sparse R and K).
     The issue's contact overhead is search + projection + integration + insertion; the
     whole ``contact`` phase is counted, a superset.

   Printed: the ratio contact / bulk assembly (target <= 30 %).

2. **Half-rings (B3)** (``meshes/half_rings.py``, default divisions 4 x 32 / 4 x 60, or
   ``--rings-refine`` multiples of them in both directions): two Neo-Hooke rings
   (E = 689.56, nu = 0.32), slave ``moving_outer``, master ``fixed_inner``, mortar + ALM.
   The state is set directly: the moving ring translated 0.5 down (rigidly) into the fixed
   ring, so the lower part of the interface is active. Same breakdown and ratio.

3. **Linear scaling**: a synthetic interface — a flat (slightly wavy) slave of N segments
   pressed 0.25 h into a flat master of about 0.8 master segments per slave segment
   (non-matching, every slave node active: the most work per segment) — evaluated directly
   through the pair's numpy code path: search + ``mortar.weighted_gaps`` + nodal
   sums/enforcement + the enforcement's residual and tangent + PETSc insertion into a preallocated
   matrix over the surface coordinates. N = 100 … 10 000 (2 decades). The least-squares
   exponent of time ∝ N^k (log-log) is printed for each phase and for the total (target
   k <= 1.15), and for the total over N >= 1000 alone (the small sizes are dominated by a
   fixed per-call overhead, which flattens the full fit).

How to run
----------
    .venv/bin/python benchmarks/contact_overhead.py            # all three parts, ~2 min
    .venv/bin/python benchmarks/contact_overhead.py --only scaling --reps 5
    .venv/bin/python benchmarks/contact_overhead.py --only rings --rings-refine 1 2 4 8
Options: ``--only {hertz,rings,scaling}`` (repeatable), ``--reps`` (timing repetitions,
median taken), ``--sizes`` (slave segment counts for part 3), ``--clock cpu`` (process CPU
time instead of wall time: steadier when other jobs share the machine), ``--solve-hertz``.
Serial only.

Targets (issue 7): contact overhead <= 30 % of bulk assembly per Newton iteration on Hertz
at a/20 and on the half-rings; fitted exponent <= 1.15. The script only prints; it asserts
nothing about time.

Measured (issue 31, 2026-12-04, ``--clock cpu``, 2-core machine at load average 5–6): Hertz
a/20 contact 7.9–8.3 ms against bulk 21.1–21.3 ms (37.5–38.7 %) before; after the kernel's
deferred Hessians and closed-form polyline (``contact/mortar.py``, now
``contact/polyline_mortar.py``) 5.8–6.3 ms against 20.8–21.4 ms (26.9–29.5 %):
curve+proj+mortar 3.2–3.3 → 1.0–1.2 ms, the rest (nodal sums,
enforcement, sparse R/K, now with the pair-weighted Hessians of the contact nodes) 4.0–4.5 ms.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from petsc4py import PETSc  # noqa: E402

from fenicsx_mortar import _dolfinx as dx  # noqa: E402
from fenicsx_mortar.scene.bulk import build_bulk  # noqa: E402
from fenicsx_mortar.contact import assembly, mortar  # noqa: E402
from fenicsx_mortar.contact.curves import Polyline  # noqa: E402
from fenicsx_mortar.contact.registry import ENFORCEMENTS  # noqa: E402
from fenicsx_mortar.contact.state import ContactState  # noqa: E402
from fenicsx_mortar.contact.kernel import nodal_sum  # noqa: E402
from fenicsx_mortar.contact.search import candidate_pairs  # noqa: E402
from fenicsx_mortar.scene.meshing import build_domain  # noqa: E402
from fenicsx_mortar.scene import Scene, from_dict, load_scene  # noqa: E402
from fenicsx_mortar.problem import ContactProblem  # noqa: E402
from fenicsx_mortar.scene.runner import scene_pairs  # noqa: E402
from fenicsx_mortar.newton import NewtonSolver  # noqa: E402
from fenicsx_mortar.stepping import LoadStepper  # noqa: E402
from fenicsx_mortar.timings import Timings  # noqa: E402

from benchmarks.analytics import HERTZ_A as A_HERTZ  # noqa: E402

#: the clock the pieces are timed with (``--clock``): wall time by default; CPU time of this
#: process is steadier on a machine shared with other jobs
clock = time.perf_counter

CONTACT_PHASES = ("contact", "contact_search", "contact_kernel", "contact_insertion")


# ------------------------------------------------------------------ parts 1 and 2: scenes


def build(scene: Scene):
    """mesh → bulk → contact → Newton solver, as fenicsx_mortar.scene.runner.solve wires them."""
    scene.validate()
    dom = build_domain(scene)
    bulk = build_bulk(scene, dom)
    pairs = scene_pairs(scene, dom, bulk.V)
    problem = ContactProblem(bulk.residual, bulk.u, bulk.bcs, pairs, bulk.jacobian,
                             settings=scene.solver)
    build.problem = problem  # (the solver lives as long as its problem)
    return dom, bulk, pairs, problem.newton


def one_iteration(solver: NewtonSolver, reps: int) -> dict[str, float]:
    """Median seconds, by phase, of one residual + one Jacobian evaluation at the solver's
    current iterate, run through the solver's own callbacks (``evaluate_residual`` /
    ``evaluate_jacobian``) with a fresh ``Timings`` per repetition: ``bulk_assembly`` (UFL residual
    with lifting and Jacobian, final PETSc assembly), ``contact`` (all contact work) and its
    sub-phases ``contact_search``, ``contact_kernel`` (curve + projection + mortar
    integration), ``contact_insertion`` (PETSc). ``contact`` less those three is the rest:
    gather of coordinates, nodal sums, enforcement and the sparse R/K build."""
    x, b, A = solver.x, solver.b, solver.A
    for h in solver.pairs:
        h._first_jacobian = False  # a typical (not first-of-step) iteration
    saved = solver.timings, [h.timings for h in solver.pairs]
    samples: dict[str, list[float]] = {}
    try:
        for _ in range(reps + 1):  # the first round warms up and is dropped
            t = Timings()
            solver.timings = t
            for h in solver.pairs:
                h.timings = t
            solver.evaluate_residual(x, b)
            solver.evaluate_jacobian(x, A)
            for k in ("bulk_assembly",) + CONTACT_PHASES:
                samples.setdefault(k, []).append(t.get(k, 0.0))
    finally:
        solver.timings = saved[0]
        for h, tt in zip(solver.pairs, saved[1]):
            h.timings = tt
    out = {k: statistics.median(v[1:]) for k, v in samples.items()}
    st = solver.pairs[0].state
    out["_contrib"] = st.gap.size
    out["_active"] = int(np.count_nonzero(st.p > 0))
    out["_slave_segments"] = len(solver.pairs[0].slave.seg)
    return out


def report_iteration(title: str, r: dict[str, float], extra: str = "") -> None:
    ms = 1e3
    bulk, contact = r["bulk_assembly"], r["contact"]
    rest = contact - r["contact_search"] - r["contact_kernel"] - r["contact_insertion"]
    print(f"\n== {title} ==")
    if extra:
        print(extra)
    print(f"slave segments {r['_slave_segments']}, contributions {r['_contrib']}, "
          f"active nodes {r['_active']}")
    print("per Newton iteration (1 residual + 1 Jacobian), median of reps, ms:")
    print(f"  bulk assembly         {bulk * ms:9.3f}")
    print(f"  contact               {contact * ms:9.3f}")
    for k, label in (("contact_search", "search"), ("contact_kernel", "curve+proj+mortar"),
                     ("contact_insertion", "PETSc insertion")):
        print(f"    {label:20s}{r[k] * ms:9.3f}")
    print(f"    {'rest':20s}{rest * ms:9.3f}   (gather, nodal sums, enforcement, sparse R/K)")
    print(f"  contact / bulk assembly = {100 * contact / bulk:.1f} %   (target <= 30 %)")


def hertz(reps: int, solve: bool) -> dict:
    scene = load_scene(ROOT / "demos" / "scenes" / "hertz.toml")
    h = A_HERTZ / 20
    scene.mesh.params = {**scene.mesh.params, "h_contact": h}
    scene.output.xdmf = scene.output.plots = False
    t0 = time.perf_counter()
    dom, bulk, hooks, solver = build(scene)
    t_build = time.perf_counter() - t0
    V = bulk.V
    ndofs = dx.dof_count(V)
    cells = dx.num_cells_global(dom.mesh)
    info = f"{cells} cells, {ndofs} dofs; build {t_build:.1f} s"
    if solve:
        t0 = time.perf_counter()
        ended = LoadStepper(build.problem, bulk.set_time, scene.steps.targets(),
                            max_cuts=scene.steps.max_cuts, on_event=None).run()
        msg = ended.message
        t_solve = time.perf_counter() - t0
        phases = ", ".join(f"{k} {v:.1f} s" for k, v in solver.timings.items())
        info += f"; solved in {t_solve:.1f} s ({msg}; {phases})"
    else:
        # the disk pressed rigidly into the block by δ = a²/(2R): its arc then overlaps the
        # block top over about |x| < a, the converged contact zone (same active set size)
        delta = A_HERTZ**2 / 2.0
        u = bulk.u
        u.interpolate(lambda X: np.stack([np.zeros(X.shape[1]), np.full(X.shape[1], -delta)]),
                      dom.cells("disk"))
        u.x.scatter_forward()
        solver.system.pull(solver.x)   # (with multipliers x is longer than u)
        bulk.set_time(1.0)
        info += f"; state: disk pressed rigidly {delta:.2e} into the block (--solve-hertz: " \
                f"the solved state)"
    solver._set_iterate(solver.x)
    r = one_iteration(solver, reps)
    report_iteration(f"Hertz B2, h_c = a/20 = {h:.5f}", r, info)
    return r


def half_rings_scene(refine: int = 1) -> Scene:
    neo = {"model": "neo-hooke", "E": 689.56, "nu": 0.32}
    # the default divisions (4 x 32 fixed, 4 x 60 moving) times ``refine``
    params = {"fixed_nr": 4 * refine, "fixed_nc": 32 * refine, "moving_nr": 4 * refine,
              "moving_nc": 60 * refine}
    return from_dict(Scene, {
        "title": "B3 half-rings (benchmark state)",
        "mesh": {"generator": "half_rings", "cell": "quadrilateral", "params": params},
        "bodies": [{"name": "fixed_ring", "material": neo},
                   {"name": "moving_ring", "material": neo}],
        "dirichlet": [{"boundary": "fixed_outer", "x": 0.0, "y": 0.0},
                      {"boundary": "moving_inner", "x": 0.0, "y": -0.5}],
        "contacts": [{"name": "rings", "slave": "moving_outer", "master": "fixed_inner",
                      "method": "mortar", "enforcement": {"type": "alm"}}],
        "output": {"xdmf": False, "plots": False},
    }, "")


def rings(reps: int, refine: int = 1) -> dict:
    scene = half_rings_scene(refine)
    dom, bulk, hooks, solver = build(scene)
    # the moving ring translated 0.5 down (rigidly), the fixed ring at rest
    u = bulk.u
    moving = dom.cells("moving_ring")
    u.interpolate(lambda X: np.stack([np.zeros(X.shape[1]), np.full(X.shape[1], -0.5)]),
                  moving)
    u.x.scatter_forward()
    dx.function_vector(u).copy(solver.x)
    bulk.set_time(1.0)
    V = bulk.V
    ndofs = dx.dof_count(V)
    cells = dx.num_cells_global(dom.mesh)
    solver._set_iterate(solver.x)
    r = one_iteration(solver, reps)
    slave = sum(h.slave.seg.shape[0] for h in hooks)
    report_iteration(f"Half-rings B3 ({refine} x the default divisions), moving ring 0.5 "
                     f"down", r, f"{cells} cells, {ndofs} dofs, {slave} slave segments")
    return r


# ------------------------------------------------------------------ part 3: scaling


def synthetic_interface(n_slave: int):
    """Slave: the flat bottom of an upper body, x in [-0.5, 0.5], n_slave segments, with a
    small waviness (so gaps vary) and pressed into the master by 0.25 h on average (h the
    slave segment length: a converged-contact penetration, well inside the search radius 2h,
    every slave node active); master: the top y = 0 of a lower body, x in [-0.6, 0.6],
    about 0.8 master segments per slave segment (non-matching)."""
    h = 1.0 / n_slave
    # slave oriented so that e3 × t points out of the upper body (down): right to left
    x = np.linspace(0.5, -0.5, n_slave + 1)
    xs = np.stack([x, -0.25 * h + 0.1 * h * np.sin(40.0 * x)], axis=1)
    seg_s = np.stack([np.arange(n_slave), np.arange(1, n_slave + 1)], axis=1)
    n_m = max(2, round(0.8 * 1.2 * n_slave))
    # master: e3 × t points up (out of the lower body): left to right
    xm = np.stack([np.linspace(-0.6, 0.6, n_m + 1), np.zeros(n_m + 1)], axis=1)
    seg_m = np.stack([np.arange(n_m), np.arange(1, n_m + 1)], axis=1)
    return xs, seg_s, xm, seg_m


def scaling_case(n_slave: int, reps: int) -> dict[str, float]:
    xs, seg_s, xm, seg_m = synthetic_interface(n_slave)
    ns, nm = len(xs), len(xm)
    n_coords = 2 * (ns + nm)
    h = float(np.mean(np.linalg.norm(xs[seg_s[:, 1]] - xs[seg_s[:, 0]], axis=1)))
    radius = 2.0 * h
    enf = ENFORCEMENTS["alm"](1000.0 / h, ns, 1e-8, 0.0)
    dofs = np.arange(n_coords, dtype=np.int64)
    skip = np.zeros(0, dtype=np.int64)
    layouts = assembly.Layouts()
    ones = np.ones(ns)
    ctx: dict = {}

    def search():
        ctx["pairs"] = candidate_pairs(xs, seg_s, xm, seg_m, radius)

    def kernel():
        curve = Polyline(xm, seg_m)
        ctx["curve"] = curve
        ctx["gap"], ctx["area"] = mortar.weighted_gaps(xs, seg_s, xm, seg_m, curve,
                                                       ctx["pairs"], 2)

    def enforce():
        g, Ar = nodal_sum(ctx["gap"], ns), nodal_sum(ctx["area"], ns)
        st = ContactState(xs, xm, ctx["curve"], ctx["pairs"], ctx["gap"], ctx["area"], g, Ar,
                          layouts)
        st.law = enf.pressure(g, Ar)
        ctx["st"], ctx["p"] = st, st.p

    def sparse():
        ctx["f"] = enf.residual(ctx["st"], ones)
        ctx["K"] = enf.tangent(ctx["st"], ones, first=False)

    # first pass to learn the pattern, then a preallocated PETSc matrix / vector
    search(), kernel(), enforce(), sparse()
    K = ctx["K"].tocsr()
    K.sum_duplicates()
    pattern = sp_pattern(K)
    A = PETSc.Mat().createAIJ((n_coords, n_coords), csr=(pattern.indptr.astype(PETSc.IntType),
                                                          pattern.indices.astype(PETSc.IntType),
                                                          np.zeros(pattern.nnz)),
                               comm=PETSc.COMM_SELF)
    A.assemble()
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    b = PETSc.Vec().createSeq(n_coords)

    def petsc():
        assembly.add_to_vector(b, dofs, ctx["f"])
        assembly.add_to_matrix(A, ctx["K"], dofs, skip, n_coords, layouts)
        A.assemble()

    pieces = (("search", search), ("kernel", kernel), ("enforce", enforce),
              ("sparse", sparse), ("petsc", petsc))
    samples: dict[str, list[float]] = {name: [] for name, _ in pieces}
    for _ in range(reps):  # interleaved, as in one_iteration
        for name, fn in pieces:
            t0 = clock()
            fn()
            samples[name].append(clock() - t0)
    out = {name: statistics.median(v) for name, v in samples.items()}
    out["_pairs"] = len(ctx["pairs"][0])
    out["_active"] = int(np.count_nonzero(ctx["p"] > 0))
    A.destroy(), b.destroy()
    return out


def sp_pattern(K):
    """K's sparsity plus the diagonal (a matrix PETSc can preallocate from)."""
    import scipy.sparse as sp
    P = (abs(K) + sp.identity(K.shape[0], format="csr")).tocsr()
    P.sort_indices()
    return P


def fit_exponent(n: np.ndarray, t: np.ndarray) -> float:
    k, _ = np.polyfit(np.log(n), np.log(t), 1)
    return float(k)


def scaling(sizes: list[int], reps: int) -> dict:
    rows = []
    for n in sizes:
        rows.append((n, scaling_case(n, reps)))
    phases = ("search", "kernel", "enforce", "sparse", "petsc")
    print("\n== Linear scaling: synthetic flat interface, all active (per residual + Jacobian "
          "evaluation, median, ms) ==")
    print(f"{'N slave':>8} {'pairs':>7} {'active':>7} " + " ".join(f"{p:>9}" for p in phases)
          + f" {'total':>9} {'us/seg':>8}")
    N = np.array([n for n, _ in rows], dtype=float)
    tot = np.array([sum(r[p] for p in phases) for _, r in rows])
    for (n, r), t in zip(rows, tot):
        print(f"{n:8d} {r['_pairs']:7d} {r['_active']:7d} "
              + " ".join(f"{1e3 * r[p]:9.3f}" for p in phases)
              + f" {1e3 * t:9.3f} {1e6 * t / n:8.2f}")
    print("fitted exponent k of time ∝ N^k (least squares, log-log):")
    for p in phases:
        print(f"  {p:8s} k = {fit_exponent(N, np.array([r[p] for _, r in rows])):.3f}")
    core = np.array([r["kernel"] + r["sparse"] + r["petsc"] for _, r in rows])
    print(f"  kernel + insertion (sparse + petsc): k = {fit_exponent(N, core):.3f}")
    print(f"  total contact (search … petsc):      k = {fit_exponent(N, tot):.3f}   "
          f"(target <= 1.15; {N[0]:.0f} … {N[-1]:.0f} = {np.log10(N[-1] / N[0]):.1f} decades)")
    big = N >= 1000
    if big.sum() >= 2:
        # the fixed per-call overhead (~ms of Python/numpy dispatch) flattens the small-N
        # end; the slope over the large sizes is the asymptotic one
        print(f"  total contact, N >= 1000 only:       k = {fit_exponent(N[big], tot[big]):.3f}")
    return dict(rows=rows)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", action="append", choices=("hertz", "rings", "scaling"))
    ap.add_argument("--reps", type=int, default=15)
    ap.add_argument("--solve-hertz", action="store_true",
                    help="time Hertz in the solved state (the solve takes minutes)")
    ap.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                    help="wall time (default) or this process's CPU time (steadier on a "
                         "loaded machine)")
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 300, 1000, 3000, 10000])
    ap.add_argument("--rings-refine", type=int, nargs="+", default=[1],
                    help="half-rings meshes: these multiples of the default divisions")
    args = ap.parse_args(argv)
    global clock
    if args.clock == "cpu":
        # the solver's Timings read time.perf_counter: this process measures CPU time
        time.perf_counter = time.process_time
    clock = time.perf_counter
    parts = args.only or ["hertz", "rings", "scaling"]
    print(f"contact_overhead: reps = {args.reps}, clock = {args.clock}, numpy {np.__version__}, "
          f"PETSc {'.'.join(map(str, PETSc.Sys.getVersion()))}")
    if "hertz" in parts:
        hertz(args.reps, args.solve_hertz)
    if "rings" in parts:
        for k in args.rings_refine:
            rings(args.reps, k)
    if "scaling" in parts:
        scaling(args.sizes, args.reps)


if __name__ == "__main__":
    main()
