"""Two half-rings (B3, the paper's Fig. 33): a pressed ring turned inside a fixed one, with
Coulomb friction — large sliding along a curved master.

Problem (scene ``demos/scenes/half_rings.toml``; the set-up is ours, docs/benchmarks.md B3): the
fixed ring is the lower half annulus R_i = 10, R_e = 12 with clamped cut ends (master: its
inner arc); the moving ring is the lower half annulus R_i = 8, R_e = 10 (slave: its outer
arc); both Neo-Hooke, E = 689.56, ν = 0.32. The moving ring's inner arc is driven as a rigid
hub: pressed down by 0.5 (t ∈ [0, 1]), then turned anticlockwise about the origin by
φ_max = arcsin(0.4) = 0.4115 rad (t ∈ [1, 2]). Coulomb μ = 0.3 here (``--mu`` changes it).

By default a SHORT run (the press in two steps and the first three turn steps, ~1/7 of the
turn), so the test suite stays fast; ``--full`` runs the scene's whole load path (24
steps), ``--smoothing NAME`` picks the master curve (none, hermite, bspline, ...).

Expected result: the moving ring is in equilibrium under the hub and the contact alone,
so the hub reaction equals minus the contact force on the slave (to the solver tolerance);
every slipping node sits on the cone, |t_T| = μ|t_N|; while every active node slips, the
moment of the hub reactions about the origin is close to μ·r·N (r ≈ 10 the contact radius,
N the total normal contact force), since the master's normals pass nearly through the
origin and the moment is carried by the tangential tractions.

Writes ``results/demo_half_rings[_full]/``: ``reactions.csv``/``.png`` (hub reactions and
moment against the load parameter), ``deformed.png`` (meshes coloured by contact pressure at
chosen steps) and ``master_end.png`` (zoom on the master's end), ``snapshots.npz`` (every
step's nodal state, for ``fenicsx_mortar.io.pictures``), the package's per-step interface CSVs
in ``run/interface/`` and, with ``--full``, ``load_path.gif``.
"""
import argparse
import time
from pathlib import Path

import numpy as np

from fenicsx_mortar import Friction, load_scene, solve
from fenicsx_mortar import _dolfinx as dx
from fenicsx_mortar.io.pictures import (Snapshot, animation_gif, frames_png, load_snapshots,
                                     save_snapshots, snapshot)

PHI_MAX, PRESS = 0.41152, 0.5
SHORT_TIMES = [0.5, 1.0, 1.05, 1.1, 1.15]


class Stalled(Exception):
    """The step control keeps cutting: the run creeps without getting anywhere."""


def hub_moment(state) -> float:
    """Moment about the origin of the forces the hub exerts on the moving ring, from the
    unconstrained residual at the hub dofs (no contact term acts there) and the current
    node positions."""
    bulk = state.bulk
    b = dx.create_vector(bulk.residual)
    dx.assemble_unconstrained_residual(b, bulk.residual)
    r = b.array_r
    hub = next(s for s in bulk.supports if s.label == "hub")
    X = bulk.V.tabulate_dof_coordinates()[:, :2]
    x = X + bulk.u.x.array.reshape(-1, 2)[: len(X)]
    ix, iy = hub.dofs["x"], hub.dofs["y"]
    return float(np.sum(x[ix // 2, 0] * r[iy]) - np.sum(x[iy // 2, 1] * r[ix]))


def load_parameters(t: float) -> tuple[float, float]:
    """(press s, turn φ) at pseudo-time t."""
    return PRESS * min(t, 1.0), PHI_MAX * min(max(t - 1.0, 0.0), 1.0)


def run(mu: float, smoothing: str, times: list[float] | None, out: Path):
    scene = load_scene(Path(__file__).parent / "scenes" / "half_rings.toml")
    scene.contacts[0].friction = Friction(law="coulomb", mu=mu) if mu > 0 else Friction()
    scene.contacts[0].smoothing = smoothing
    if times is not None:
        scene.steps.times = times
    rows: list[dict] = []
    snaps: list[Snapshot] = []

    def on_step(rec: dict, state) -> None:
        c = rec["contact"]["rings"]
        d = state.pairs[0].interface()
        on = d["pressure"] > 0
        r_contact = float(np.mean(np.hypot(d["x"][on], d["y"][on]))) if on.any() else 10.0
        s, phi = load_parameters(rec["time"])
        rows.append(dict(time=rec["time"], press=s, phi=phi, Rx=rec["reactions"]["hub"]["x"],
                         Ry=rec["reactions"]["hub"]["y"], M=hub_moment(state),
                         N=c["normal_force"], T=c.get("tangential_force", 0.0),
                         Fx_contact=(c["force_on_slave"][0]
                                     + c.get("tangential_force_on_slave", [0, 0])[0]),
                         Fy_contact=(c["force_on_slave"][1]
                                     + c.get("tangential_force_on_slave", [0, 0])[1]),
                         r_contact=r_contact, active=c["active_nodes"],
                         stick=c.get("stick_nodes", 0), slip=c.get("slip_nodes", 0),
                         p_max=c["max_pressure"], newton=rec["newton_iterations"],
                         augmentations=rec["augmentations"], cuts=rec["cuts"],
                         cone_error=cone_error(d, mu)))
        snaps.append(snapshot(state, rec["time"]))
        print(f"  t = {rec['time']:.5f}  phi = {phi:.4f}  Newton {rec['newton_iterations']:3d}"
              f"  cuts {rec['cuts']}  N = {c['normal_force']:9.3f}  M = {rows[-1]['M']:9.3f}"
              f"  stick/slip {rows[-1]['stick']}/{rows[-1]['slip']}", flush=True)
        if len(rows) >= 20 and rows[-1]["time"] - rows[-20]["time"] < 0.01:
            raise Stalled("20 steps advanced pseudo-time by less than 0.01 "
                          f"(t = {rec['time']:.6g})")

    t0 = time.perf_counter()
    try:
        result = solve(scene, out=out / "run", log=lambda s: None, on_step=on_step)
        converged, message = result.converged, result.message
    except Stalled as e:
        converged, message = False, f"stalled: {e}"
    return converged, message, rows, snaps, time.perf_counter() - t0


def cone_error(d: dict, mu: float) -> float:
    """max over slipping nodes of | |t_T| − μ p | / (μ p) (0 when frictionless or none slip)."""
    if mu == 0 or "status" not in d:
        return 0.0
    slip = (d["status"] == "slip") & (d["pressure"] > 0)
    if not slip.any():
        return 0.0
    return float(np.max(np.abs(np.abs(d["t_tangential"][slip]) - mu * d["pressure"][slip])
                        / (mu * d["pressure"][slip])))


def read_saved(out: Path) -> list[dict]:
    """The per-step rows a previous run wrote to ``reactions.csv``."""
    lines = (out / "reactions.csv").read_text().split()
    keys = lines[0].split(",")
    return [dict(zip(keys, map(float, line.split(",")))) for line in lines[1:]]


def write_curves(out: Path, rows: list[dict], mu: float, title: str) -> None:
    keys = list(rows[0])
    (out / "reactions.csv").write_text(",".join(keys) + "\n" + "\n".join(
        ",".join(f"{r[k]:.12g}" for k in keys) for r in rows) + "\n")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = np.array([0.0] + [r["time"] for r in rows])

    def col(k):
        return np.array([0.0] + [r[k] for r in rows])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    a1.plot(t, col("Rx"), "o-", ms=3, label="hub R_x")
    a1.plot(t, col("Ry"), "s-", ms=3, label="hub R_y")
    a1.plot(t, col("N"), "^-", ms=3, label="normal contact force N")
    a1.set(xlabel="pseudo-time (0–1 press, 1–2 turn)", ylabel="force", title=title)
    a2.plot(t, col("M"), "o-", ms=3, label="hub moment about the origin")
    if mu > 0:
        turn = t > 1.0
        a2.plot(t[turn], (mu * col("r_contact") * col("N"))[turn], "k--", lw=0.9,
                label="μ · r · N (turn phase; r = mean radius of the active slave nodes)")
    a2.set(xlabel="pseudo-time (0–1 press, 1–2 turn)", ylabel="moment")
    for a in (a1, a2):
        a.axvline(1.0, color="0.6", lw=0.8)
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.savefig(out / "reactions.png", dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="the whole load path (minutes)")
    ap.add_argument("--mu", type=float, default=0.3)
    ap.add_argument("--redraw", action="store_true",
                    help="no solve: draw the pictures again from the saved reactions.csv and "
                         "snapshots.npz of the same options")
    ap.add_argument("--smoothing", default="none")
    args = ap.parse_args()
    name = "demo_half_rings" + (f"_full_mu{args.mu:g}_{args.smoothing}" if args.full else "")
    out = Path(__file__).resolve().parents[1] / "results" / name
    out.mkdir(parents=True, exist_ok=True)

    if args.redraw:
        rows, snaps, wall = read_saved(out), load_snapshots(out / "snapshots.npz"), 0.0
        converged, message = rows[-1]["time"] >= 2.0 - 1e-12, "redrawn from saved data"
    else:
        converged, message, rows, snaps, wall = run(args.mu, args.smoothing,
                                                    None if args.full else SHORT_TIMES, out)
    print(("completed" if converged else "STOPPED") + f": {message} ({wall:.1f} s)")
    last = rows[-1]
    s, phi = load_parameters(last["time"])
    print(f"reached t = {last['time']:.5g}: press {s:.3f}, turn {phi:.4f} rad = "
          f"{100 * phi / PHI_MAX:.1f} % of phi_max; {len(rows)} steps, "
          f"{sum(r['cuts'] for r in rows)} cuts; Newton per step mean "
          f"{np.mean([r['newton'] for r in rows]):.1f}, max {max(r['newton'] for r in rows)}")

    title = f"half-rings, mu = {args.mu:g}, smoothing {args.smoothing}"
    write_curves(out, rows, args.mu, title)
    save_snapshots(out / "snapshots.npz", snaps)

    def label(sn):
        p = load_parameters(sn.time)
        return "t = {:.3g}: press {:.2f}, turn {:.1f}°".format(sn.time, p[0], np.degrees(p[1]))
    times = [r["time"] for r in rows]
    chosen = [times.index(1.0)] if 1.0 in times else []
    chosen += [int(np.argmin(np.abs(np.array(times) - t)))
               for t in (1.25, 1.5, 2.0) if t <= times[-1]]
    chosen = sorted(set(chosen + [len(rows) - 1]))
    frames_png(out / "deformed.png", [snaps[i] for i in chosen], ncols=2, label=label,
               window=(-13, 13, -12.7, 0.5), panel=(5.2, 3.0), legend_loc="upper center",
               suptitle=f"{title}: slave arc coloured by contact pressure")
    frames_png(out / "master_end.png", [snaps[i] for i in chosen[-2:]], ncols=2, label=label,
               window=(6.5, 12.5, -4.0, 1.0), panel=(4.5, 3.8), legend_loc="lower left",
               suptitle=f"{title}: the slave's right end at the master's end (zoom)")
    if args.full:
        animation_gif(out / "load_path.gif", snaps, label=label, window=(-13, 13, -12.7, 0.5),
                      size=(6.5, 3.6), fps=5, legend_loc="upper center")

    # checks
    balance = max(np.hypot(r["Rx"] + r["Fx_contact"], r["Ry"] + r["Fy_contact"])
                  / max(np.hypot(r["Rx"], r["Ry"]), 1e-300) for r in rows if r["active"] > 0)
    cone = max(r["cone_error"] for r in rows)
    print(f"hub reaction + contact force on the slave: max relative misfit {balance:.1e}")
    print(f"slipping nodes: max | |t_T| - mu p | / (mu p) = {cone:.1e}")
    # during the (symmetric) press the tangential tractions cancel in the moment: turn only
    all_slip = [r for r in rows if r["phi"] > 0 and r["slip"] > 0 and r["stick"] == 0]
    for r in all_slip:
        ratio = r["M"] / (args.mu * r["r_contact"] * r["N"])
        print(f"  all {int(r['slip'])} active nodes slip at t = {r['time']:.4g}: M = {r['M']:.3f}, "
              f"mu r N = {args.mu * r['r_contact'] * r['N']:.3f} (r = {r['r_contact']:.3f}), "
              f"ratio {ratio:.4f}")
    print(f"wrote {out}/reactions.csv, reactions.png, deformed.png, snapshots.npz"
          + (", load_path.gif" if args.full else ""))
    assert balance < 1e-6 and cone < 1e-8, (balance, cone)
    if args.mu > 0 and not args.full:
        assert all_slip and all(abs(r["M"] / (args.mu * r["r_contact"] * r["N"]) - 1) < 0.05
                                for r in all_slip)
    if not converged:
        print(f"NOT OK: the load path stopped at {100 * phi / PHI_MAX:.1f} % of the turn")
        raise SystemExit(1)
    print("OK: hub balances the contact force, slipping nodes on the cone"
          + (", moment = mu r N within 5 % while all slip" if args.mu > 0 else ""))
