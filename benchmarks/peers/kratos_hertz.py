"""Kratos Multiphysics 10.4.4 on the B2 Hertz benchmark (fenicsx_mortar docs/benchmarks.md B2),
on exactly the mesh fenicsx_mortar solves on, for a side-by-side timing.

    python3.11 -m venv /tmp/kratos && /tmp/kratos/bin/pip install KratosMultiphysics==10.4.4 \
        KratosStructuralMechanicsApplication==10.4.4 \
        KratosContactStructuralMechanicsApplication==10.4.4 \
        KratosLinearSolversApplication==10.4.4 KratosConstitutiveLawsApplication==10.4.4
    /tmp/kratos/bin/python benchmarks/peers/kratos_hertz.py --level 10 [--repeat 3]

A driver of ours for the peer (no Kratos code in it); not run by the tests or CI. The results
of a side-by-side run are in docs/newton_cost.md.

Set-up (Kratos's own ALM mortar machinery, as in its ALM_frictionless_contact_test_2D tests):
  * mesh: fenicsx_mortar.meshes.hertz.build with the parameters of benchmarks/newton_cost.py
    hertz_scene (h_contact = a/level, h_far 0.1, refine_radius 0.08, grade_to 0.6, quads),
    built by the project's interpreter (export_hertz_mesh.py), written as a .mdpa;
  * TotalLagrangianElement2D4N, HyperElasticPlaneStrain2DLaw (compressible Neo-Hooke,
    psi = mu/2 (I1 - 3) - mu ln J + lambda/2 (ln J)^2, the same energy as ours), E 1000, nu 0.3;
  * load: dead nodal forces (PointLoadCondition2D1N) from the uniform traction 0.5 on the flat
    edge in the reference configuration (consistent linear load, sum exactly F = 1);
  * supports: block bottom u_y = 0, u_x = 0 at (0,-1), (0,1), (0,0.5);
  * contact: contact_structural_mechanics_static_solver, mortar_type ALMContactFrictionless
    (mortar, dual Lagrange multipliers, augmented-Lagrangian active set updated each Newton
    iteration = semi-smooth Newton), alm_contact_process with its defaults (automatic
    penalty / scale factor from E and the nodal size), slave = disk arc, master = block top;
  * convergence: "contact_residual_criterion" (the criterion of Kratos's own ALM tests):
    displacement-residual and LM-residual (weighted gap) norms, each relative 1e-4 or absolute
    1e-9 (the solver's defaults; --rtol/--atol override them), AND the mortar active-set
    criterion (no active-set change);
  * linear solver: none given, so Kratos picks its "fastest available direct solver"
    (printed), with the contact block builder-and-solver;
  * ONE load step, OMP_NUM_THREADS=1 (set below before Kratos is imported).

Timing: wall clock of the load step only (InitializeSolutionStep incl. contact search,
Predict, SolveSolutionStep = the Newton loop, FinalizeSolutionStep), and of SolveSolutionStep
alone; import, mdpa reading and Initialize excluded. Best of --repeat, a fresh Model each.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
PROJECT_PY = str(HERE.parents[1] / ".venv" / "bin" / "python")
F_TOTAL, E, NU = 1.0, 1000.0, 0.3
E_STAR = 1.0 / (2 * (1 - NU**2) / E)
A = 2.0 * np.sqrt(F_TOTAL * 1.0 / (np.pi * E_STAR))        # 0.04814
P0 = 2.0 * F_TOTAL / (np.pi * A)                            # 13.2248


# ----------------------------------------------------------------- mesh -> mdpa

def export_mesh(level: float, workdir: Path) -> dict:
    """The project's own mesh (its gmsh 4.8 and generator), via its interpreter."""
    out = workdir / f"mesh_{level:g}.json"
    subprocess.run([PROJECT_PY, str(HERE / "export_hertz_mesh.py"), f"{level:g}", str(out)],
                   check=True)
    return json.loads(out.read_text())


def write_mdpa(mesh: dict, path: Path) -> dict:
    """Write the .mdpa; return node ids of the special points and the slave node ids."""
    tags = sorted(int(t) for t in mesh["nodes"])
    nid = {t: i + 1 for i, t in enumerate(tags)}                # gmsh tag -> Kratos id
    X = {nid[int(t)]: xy for t, xy in mesh["nodes"].items()}

    def ccw(q):                                                  # counter-clockwise quads
        q = [nid[v] for v in q]
        x = np.array([X[v] for v in q])
        area = 0.5 * np.sum(x[:, 0] * np.roll(x[:, 1], -1) - np.roll(x[:, 0], -1) * x[:, 1])
        return q if area > 0 else q[::-1]

    quads = {b: [ccw(q) for q in mesh["bodies"][b]] for b in ("disk", "block")}

    # boundary segments oriented as in their (ccw) quad: the right-hand normal of a Kratos
    # line (tangent x e_z) is then the outward normal
    directed = {}
    for qs in quads.values():
        for q in qs:
            for k in range(4):
                directed[frozenset((q[k], q[(k + 1) % 4]))] = (q[k], q[(k + 1) % 4])

    def segments(name):
        return [directed[frozenset((nid[a], nid[b]))] for a, b in mesh["curves"][name]]

    slave, master, top = segments("disk_arc"), segments("block_top"), segments("disk_top")

    def node_at(x, y, body):
        ids = {v for q in quads[body] for v in q}
        best = min(ids, key=lambda v: (X[v][0] - x) ** 2 + (X[v][1] - y) ** 2)
        assert np.hypot(X[best][0] - x, X[best][1] - y) < 1e-12, (x, y, body)
        return best

    fix_x = [node_at(0, -1, "block"), node_at(0, 1, "disk"), node_at(0, 0.5, "disk")]
    fix_y = sorted({v for s in segments("block_bottom") for v in s})

    # dead load: consistent nodal forces of the traction 0.5 on the reference flat edge
    load = {}
    for a, b in top:
        half = 0.5 * 0.5 * np.hypot(X[b][0] - X[a][0], X[b][1] - X[a][1])
        load[a] = load.get(a, 0.0) + half
        load[b] = load.get(b, 0.0) + half

    L = ["Begin ModelPartData", "End ModelPartData", "",
         "Begin Properties 0", "End Properties",
         "Begin Properties 1", "End Properties",                  # disk  (materials json)
         "Begin Properties 2", "End Properties",                  # block (materials json)
         "Begin Properties 3", f"    YOUNG_MODULUS {E}", "    THICKNESS 1.0",
         "End Properties", "",                                     # contact conditions
         "Begin Nodes"]
    L += [f"{i} {X[i][0]:.16e} {X[i][1]:.16e} 0.0" for i in sorted(X)]
    L += ["End Nodes", ""]
    eid, elems = 0, {}
    for prop, body in ((1, "disk"), (2, "block")):
        L.append("Begin Elements TotalLagrangianElement2D4N")
        elems[body] = []
        for q in quads[body]:
            eid += 1
            elems[body].append(eid)
            L.append(f"{eid} {prop} " + " ".join(map(str, q)))
        L += ["End Elements", ""]
    cid, conds = 0, {}
    for name, segs in (("slave", slave), ("master", master)):
        L.append("Begin Conditions LineCondition2D2N")
        conds[name] = []
        for a, b in segs:
            cid += 1
            conds[name].append(cid)
            L.append(f"{cid} 3 {a} {b}")
        L += ["End Conditions", ""]
    L.append("Begin Conditions PointLoadCondition2D1N")
    conds["load"] = []
    load_ids = {}
    for v in sorted(load):
        cid += 1
        conds["load"].append(cid)
        load_ids[cid] = load[v]
        L.append(f"{cid} 0 {v}")
    L += ["End Conditions", ""]

    def smp(name, nodes, elements=(), conditions=()):
        out = [f"Begin SubModelPart {name}", "  Begin SubModelPartNodes"]
        out += [f"  {v}" for v in sorted(set(nodes))]
        out += ["  End SubModelPartNodes", "  Begin SubModelPartElements"]
        out += [f"  {e}" for e in elements]
        out += ["  End SubModelPartElements", "  Begin SubModelPartConditions"]
        out += [f"  {c}" for c in conditions]
        out += ["  End SubModelPartConditions", "End SubModelPart", ""]
        return out

    L += smp("Disk", [v for q in quads["disk"] for v in q], elems["disk"])
    L += smp("Block", [v for q in quads["block"] for v in q], elems["block"])
    L += smp("ContactSlave", [v for s in slave for v in s], (), conds["slave"])
    L += smp("ContactMaster", [v for s in master for v in s], (), conds["master"])
    L += smp("Load", list(load), (), conds["load"])
    L += smp("FixY", fix_y)
    L += smp("FixX", fix_x)
    path.write_text("\n".join(L) + "\n")
    return {"load": load_ids, "n_nodes": len(X),
            "slave_nodes": sorted({v for s in slave for v in s})}


def materials(path: Path) -> None:
    law = {"name": "KratosMultiphysics.StructuralMechanicsApplication.HyperElasticPlaneStrain2DLaw"}
    var = {"YOUNG_MODULUS": E, "POISSON_RATIO": NU, "THICKNESS": 1.0, "DENSITY": 1.0}
    path.write_text(json.dumps({"properties": [
        {"model_part_name": f"Structure.{mp}", "properties_id": pid,
         "Material": {"constitutive_law": law, "Variables": var, "Tables": {}}}
        for mp, pid in (("Disk", 1), ("Block", 2))]}, indent=1))


def parameters(stem: Path, echo: int, rtol: float | None, atol: float | None) -> dict:
    fix = lambda mp, c: {"python_module": "assign_vector_variable_process",  # noqa: E731
                         "kratos_module": "KratosMultiphysics",
                         "Parameters": {"model_part_name": f"Structure.{mp}",
                                        "variable_name": "DISPLACEMENT", "constrained": c,
                                        "value": [0.0, 0.0, 0.0], "interval": [0.0, "End"]}}
    return {
        "problem_data": {"problem_name": "hertz_b2", "parallel_type": "OpenMP",
                         "echo_level": 0, "start_time": 0.0, "end_time": 1.0},
        "solver_settings": {
            "solver_type": "Static", "model_part_name": "Structure", "domain_size": 2,
            "echo_level": echo, "analysis_type": "non_linear",
            "model_import_settings": {"input_type": "mdpa", "input_filename": str(stem)},
            "material_import_settings": {"materials_filename": str(stem) + "_materials.json"},
            # (the contact_* tolerances are read from contact_settings, the others from here)
            "contact_settings": {"mortar_type": "ALMContactFrictionless",
                                 **({} if rtol is None else
                                    {"contact_residual_relative_tolerance": rtol}),
                                 **({} if atol is None else
                                    {"contact_residual_absolute_tolerance": atol})},
            "time_stepping": {"time_step": 1.0},          # one load step: t = 0 -> 1
            "convergence_criterion": "contact_residual_criterion",
            "max_iteration": 30, "compute_reactions": True,
            **({} if rtol is None else {"residual_relative_tolerance": rtol}),
            **({} if atol is None else {"residual_absolute_tolerance": atol}),
            # linear_solver_settings deliberately absent: Kratos's default direct solver
        },
        "processes": {
            "constraints_process_list": [fix("FixY", [False, True, False]),
                                         fix("FixX", [True, False, False])],
            "loads_process_list": [],
            "contact_process_list": [{
                "python_module": "alm_contact_process",
                "kratos_module": "KratosMultiphysics.ContactStructuralMechanicsApplication",
                "Parameters": {"model_part_name": "Structure",
                               "contact_model_part": {"0": ["ContactSlave", "ContactMaster"]},
                               "assume_master_slave": {"0": ["ContactSlave"]},
                               "contact_type": "Frictionless"}}]},
        "output_processes": {},
    }


# ----------------------------------------------------------------- run

def loaded_blas() -> list[str]:
    """Shared objects mapped into this process whose name says BLAS/LAPACK/MKL/etc."""
    keys = ("blas", "lapack", "mkl", "mumps", "pardiso", "superlu", "umfpack", "cholmod")
    libs = set()
    with open("/proc/self/maps") as f:
        for line in f:
            p = line.split()[-1]
            if p.startswith("/") and any(k in os.path.basename(p).lower() for k in keys):
                libs.add(p)
    return sorted(libs)


def run_once(stem: Path, info: dict, echo: int) -> dict:
    import KratosMultiphysics as KM
    import KratosMultiphysics.StructuralMechanicsApplication as SMA
    import KratosMultiphysics.ContactStructuralMechanicsApplication as CSMA
    import KratosMultiphysics.LinearSolversApplication  # noqa: F401  (the direct solvers)
    import KratosMultiphysics.ConstitutiveLawsApplication  # noqa: F401
    from KratosMultiphysics.StructuralMechanicsApplication.structural_mechanics_analysis \
        import StructuralMechanicsAnalysis

    clock = {}

    class Hertz(StructuralMechanicsAnalysis):
        def ModifyBeforeSolutionLoop(self):
            super().ModifyBeforeSolutionLoop()
            mp = self.model["Structure.Load"]
            for c in mp.Conditions:                      # dead nodal forces, downward
                c.SetValue(SMA.POINT_LOAD, [0.0, -info["load"][c.Id], 0.0])

        def RunSolutionLoop(self):
            # one load step, timed; nothing else happens inside the clock
            while self.KeepAdvancingSolutionLoop():
                self.time = self._AdvanceTime()
                t0 = time.perf_counter()
                c0 = time.process_time()
                self.InitializeSolutionStep()
                self._GetSolver().Predict()
                t1 = time.perf_counter()
                clock["converged"] = self._GetSolver().SolveSolutionStep()
                t2 = time.perf_counter()
                self.FinalizeSolutionStep()
                t3 = time.perf_counter()
                clock.update(step=t3 - t0, solve=t2 - t1, cpu=time.process_time() - c0)
                self.OutputSolutionStep()

    with open(str(stem) + "_parameters.json") as f:
        params = KM.Parameters(f.read())
    model = KM.Model()
    sim = Hertz(model, params)
    sim.Initialize()
    sim.RunSolutionLoop()
    mp = model["Structure"]
    solver = sim._GetSolver()
    strategy = solver._GetSolutionStrategy()
    bs = solver._GetBuilderAndSolver()
    its = mp.ProcessInfo[KM.NL_ITERATION_NUMBER]
    n_eq = bs.GetEquationSystemSize()
    # pressures on the slave nodes (the LM dof; Kratos's sign: negative in compression)
    x, lm, aug, act = [], [], [], []
    for nid in info["slave_nodes"]:
        n = mp.GetNode(nid)
        x.append(n.X)                                    # current position
        act.append(n.Is(KM.ACTIVE))
        lm.append(n.GetSolutionStepValue(CSMA.LAGRANGE_MULTIPLIER_CONTACT_PRESSURE))
        aug.append(n.GetValue(CSMA.AUGMENTED_NORMAL_CONTACT_PRESSURE)
                   if n.Has(CSMA.AUGMENTED_NORMAL_CONTACT_PRESSURE) else np.nan)
    ry = sum(n.GetSolutionStepValue(KM.REACTION_Y) for n in model["Structure.FixY"].Nodes)
    n_lm = sum(1 for n in mp.Nodes if n.HasDofFor(CSMA.LAGRANGE_MULTIPLIER_CONTACT_PRESSURE)
               and n.Is(KM.SLAVE))
    active = sum(1 for nid in info["slave_nodes"] if mp.GetNode(nid).Is(KM.ACTIVE))
    out = dict(clock, its=its, n_eq=n_eq, n_lm=n_lm, active=active, ry=ry,
               x=np.array(x), lm=np.array(lm), aug=np.array(aug), act=np.array(act),
               scale=mp.ProcessInfo[KM.SCALE_FACTOR], penalty=mp.ProcessInfo[KM.INITIAL_PENALTY],
               linear_solver=str(solver._GetLinearSolver()).strip().splitlines()[0],
               strategy=type(strategy).__name__, builder=type(bs).__name__,
               criterion=type(solver._GetConvergenceCriterion()).__name__)
    sim.Finalize()
    return out


def pressure_metrics(x, p):
    """As benchmarks/analytics.py pressure_metrics: p_max/p0 - 1 and the relative L2 error of
    the piecewise-linear nodal pressure against p0 sqrt(1 - x^2/a^2) on [-a, a]."""
    o = np.argsort(x)
    x, p = x[o], p[o]
    xs = np.linspace(-A, A, 4001)
    exact = P0 * np.sqrt(np.clip(1 - xs**2 / A**2, 0, None))
    trap = lambda f: np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(xs))  # noqa: E731
    l2 = np.sqrt(trap((np.interp(xs, x, p) - exact) ** 2) / trap(exact**2))
    return p.max() / P0 - 1.0, l2


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--level", type=float, default=10, help="h_contact = a/level")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--echo", type=int, default=0, help="solver echo level")
    ap.add_argument("--rtol", type=float, help="relative residual tolerances (default: "
                    "Kratos's 1e-4, displacement and LM residuals)")
    ap.add_argument("--atol", type=float, help="absolute residual tolerances (default 1e-9)")
    ap.add_argument("--dump", help="write the slave-node x and pressures to this .json")
    ap.add_argument("--work", default="/tmp/kratos_hertz_work",
                    help="where the .mdpa and the parameter files go")
    args = ap.parse_args()
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    stem = work / f"hertz_{args.level:g}"
    info = write_mdpa(export_mesh(args.level, work), Path(str(stem) + ".mdpa"))
    info["load"] = {int(k): v for k, v in info["load"].items()}
    materials(Path(str(stem) + "_materials.json"))
    Path(str(stem) + "_parameters.json").write_text(
        json.dumps(parameters(stem, args.echo, args.rtol, args.atol), indent=1))

    import KratosMultiphysics as KM
    KM.Logger.GetDefaultOutput().SetSeverity(KM.Logger.Severity.WARNING)
    rows = [run_once(stem, info, args.echo) for _ in range(args.repeat)]
    best = min(rows, key=lambda r: r["step"])
    # Kratos's ALM scales its multiplier: contact pressure = -SCALE_FACTOR * LM (compression
    # positive); at convergence this is AUGMENTED_NORMAL_CONTACT_PRESSURE up to penalty * gap
    p = -best["lm"] * best["scale"]
    p_aug = -best["aug"]
    e0, l2 = pressure_metrics(best["x"], p)
    n_nodes = info["n_nodes"]
    print(f"== Kratos 10.4.4, B2 Hertz, h_c = a/{args.level:g}, one load step, "
          f"OMP_NUM_THREADS={os.environ['OMP_NUM_THREADS']}")
    print(f"strategy {best['strategy']}, builder {best['builder']}, criterion "
          f"{best['criterion']}, linear solver: {best['linear_solver']}")
    print(f"SCALE_FACTOR {best['scale']:.4g}, INITIAL_PENALTY {best['penalty']:.4g}")
    print(f"nodes {n_nodes}: displacement dofs {2 * n_nodes}, slave LM dofs "
          f"{len(info['slave_nodes'])}, equation system size {best['n_eq']}")
    print(f"converged {[r['converged'] for r in rows]}, Newton iterations "
          f"{[r['its'] for r in rows]}, active slave nodes {best['active']}")
    print("wall step s  " + " ".join(f"{r['step']:.3f}" for r in rows)
          + f"   (best {best['step']:.3f}; cpu {best['cpu']:.3f})")
    print("wall Solve s " + " ".join(f"{r['solve']:.3f}" for r in rows)
          + f"   (best {min(r['solve'] for r in rows):.3f})")
    print(f"reaction sum_y(block bottom) {best['ry']:.6f} (F = 1)")
    print(f"p_max {p.max():.4f}  p_max/p0 - 1 = {100 * e0:+.2f} %   L2 = {100 * l2:.2f} %"
          f"   (p0 {P0:.4f}, a {A:.5f})")
    on = best["act"]
    print(f"max |p(LM) - p(AUGMENTED_NORMAL_CONTACT_PRESSURE)| on active nodes "
          f"{np.abs(p - p_aug)[on].max() if on.any() else float('nan'):.2e}")
    o = np.argsort(best["x"])
    print(f"contact force (trapezoid of nodal p over current x) "
          f"{np.sum(0.5 * (p[o][1:] + p[o][:-1]) * np.diff(best['x'][o])):.5f}")
    print("BLAS/LAPACK-like libraries mapped:", loaded_blas() or "none")
    tol = f"rtol {args.rtol or 1e-4:g} atol {args.atol or 1e-9:g}"
    print(f"ROW kratos[{tol}] a/{args.level:g} dofs {2 * n_nodes}+{len(info['slave_nodes'])}LM "
          f"its {best['its']} wall {best['step']:.3f} solve {min(r['solve'] for r in rows):.3f} "
          f"p0err {100 * e0:+.2f}% L2 {100 * l2:.2f}%")
    if args.dump:
        Path(args.dump).write_text(json.dumps({"x": best["x"].tolist(), "lm": best["lm"].tolist(),
                                               "aug": best["aug"].tolist()}))


if __name__ == "__main__":
    main()
