"""Ironing (B4, after Puso & Laursen 2004 and Yang et al. 2005): a stiff "bullet" tool is
pressed into a soft substrate and dragged along it with Coulomb friction.

Problem (scene ``demos/scenes/ironing.toml``): substrate [0, 12] × [0, 4] (70 × 10 quads,
E = 689.6, ν = 0.32, bottom fixed; master: its top); tool = a 2 × 1 rectangle on a half-disk
of radius 1 centred at (1.2, 5.02) (E = 6896, ν = 0.32; slave: its arc, 18 segments),
initial gap 0.02; Neo-Hooke in both, Coulomb μ = 0.3 (``--mu`` changes it). The tool's top
edge moves down by 1.0 (t ∈ [0, 1], press), then 8 to the right with u_y held
(t ∈ [1, 2], iron).

By default a SHORT run: the press in 9 steps (the first one closes the gap) and the first 3
ironing steps (slide 0.6), so the test suite stays fast; ``--full`` runs the scene's whole
load path (80 steps).

Expected result: the tool is in equilibrium under its top edge and the contact alone, so
the reactions on its top edge equal minus the contact force on the tool (solver
tolerance); every slipping node sits on the cone, |t_T| = μ|t_N|; in steady ironing (all
active nodes slipping) the contact-frame tangential over normal force is close to μ
(equal to it when every active node slips, since then t_T = μ t_N node by node).

Writes ``results/demo_ironing[_full]/``: ``reactions.csv``/``.png`` (tool reactions and
T/N against the slide), ``deformed.png`` (meshes coloured by contact pressure at chosen
steps), ``snapshots.npz``, the package's interface CSVs in ``run/interface/`` and, with
``--full``, ``load_path.gif``.
"""
import argparse
import time
from pathlib import Path

import numpy as np

from fenicsx_mortar import Friction, load_scene, solve
from fenicsx_mortar.io.pictures import (Snapshot, animation_gif, frames_png, load_snapshots,
                                     save_snapshots, snapshot)

PRESS, SLIDE = 1.0, 8.0
SHORT_TIMES = [0.03] + [0.125 * k for k in range(1, 9)] + [1.025, 1.05, 1.075]


class Stalled(Exception):
    """The step control keeps cutting: the run creeps without getting anywhere."""


def load_parameters(t: float) -> tuple[float, float]:
    """(press depth, slide distance) of the tool's top edge at pseudo-time t."""
    return PRESS * min(t, 1.0), SLIDE * min(max(t - 1.0, 0.0), 1.0)


def cone_error(d: dict, mu: float) -> float:
    """max over slipping nodes of | |t_T| − μ p | / (μ p) (0 when frictionless or none slip)."""
    if mu == 0 or "status" not in d:
        return 0.0
    slip = (d["status"] == "slip") & (d["pressure"] > 0)
    if not slip.any():
        return 0.0
    return float(np.max(np.abs(np.abs(d["t_tangential"][slip]) - mu * d["pressure"][slip])
                        / (mu * d["pressure"][slip])))


def run(mu: float, times: list[float] | None, out: Path):
    scene = load_scene(Path(__file__).parent / "scenes" / "ironing.toml")
    scene.contacts[0].friction = Friction(law="coulomb", mu=mu) if mu > 0 else Friction()
    if times is not None:
        scene.steps.times, scene.steps.count = times, None
    rows: list[dict] = []
    snaps: list[Snapshot] = []

    def on_step(rec: dict, state) -> None:
        c = rec["contact"]["ironing"]
        ft = c.get("tangential_force_on_slave", [0.0, 0.0])
        d = state.pairs[0].interface()
        depth, slide = load_parameters(rec["time"])
        rows.append(dict(time=rec["time"], depth=depth, slide=slide,
                         Rx=rec["reactions"]["tool_x"]["x"], Ry=rec["reactions"]["tool_y"]["y"],
                         Fx_contact=c["force_on_slave"][0] + ft[0],
                         Fy_contact=c["force_on_slave"][1] + ft[1],
                         N=c["normal_force"], T=c.get("tangential_force", 0.0),
                         active=c["active_nodes"], stick=c.get("stick_nodes", 0),
                         slip=c.get("slip_nodes", 0), p_max=c["max_pressure"],
                         newton=rec["newton_iterations"], augmentations=rec["augmentations"],
                         cuts=rec["cuts"], cone_error=cone_error(d, mu)))
        snaps.append(snapshot(state, rec["time"]))
        r = rows[-1]
        print(f"  t = {r['time']:.5f}  depth {depth:.3f} slide {slide:.3f}  Newton {r['newton']:3d}"
              f"  cuts {r['cuts']}  R = ({r['Rx']:8.3f}, {r['Ry']:8.3f})  T/N = "
              f"{abs(r['T']) / max(r['N'], 1e-300):.4f}  stick/slip {r['stick']}/{r['slip']}",
              flush=True)
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

    def col(k, rs):
        return np.array([r[k] for r in rs])
    press = [r for r in rows if r["time"] <= 1.0]
    iron = [r for r in rows if r["time"] >= 1.0]
    fig, (a0, a1, a2) = plt.subplots(1, 3, figsize=(14, 4), constrained_layout=True)
    a0.plot(col("depth", press), col("Ry", press), "o-", ms=3, label="R_y (tool top)")
    a0.plot(col("depth", press), col("Rx", press), "s-", ms=3, label="R_x (tool top)")
    a0.set(xlabel="press depth of the tool's top edge", ylabel="reaction", title="press")
    a1.plot(col("slide", iron), col("Rx", iron), "o-", ms=3, label="R_x (tool top)")
    a1.plot(col("slide", iron), col("Ry", iron), "s-", ms=3, label="R_y (tool top)")
    a1.set(xlabel="slide distance", ylabel="reaction", title=f"iron ({title})")
    a2.plot(col("slide", iron), np.abs(col("T", iron)) / col("N", iron), "o-", ms=3,
            label="|T| / N (contact frame)")
    a2.plot(col("slide", iron), np.abs(col("Rx", iron)) / np.abs(col("Ry", iron)), "s-", ms=3,
            label="|R_x| / |R_y| (Cartesian)")
    if mu > 0:
        a2.axhline(mu, color="k", ls="--", lw=0.9, label="μ")
    a2.set(xlabel="slide distance", ylabel="force ratio", title="tangential / normal")
    for a in (a0, a1, a2):
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
    args = ap.parse_args()
    name = "demo_ironing" + (f"_full_mu{args.mu:g}" if args.full else "")
    out = Path(__file__).resolve().parents[1] / "results" / name
    out.mkdir(parents=True, exist_ok=True)

    if args.redraw:
        rows, snaps, wall = read_saved(out), load_snapshots(out / "snapshots.npz"), 0.0
        converged, message = rows[-1]["time"] >= 2.0 - 1e-12, "redrawn from saved data"
    else:
        converged, message, rows, snaps, wall = run(args.mu,
                                                    None if args.full else SHORT_TIMES, out)
    print(("completed" if converged else "STOPPED") + f": {message} ({wall:.1f} s)")
    last = rows[-1]
    depth, slide = load_parameters(last["time"])
    print(f"reached t = {last['time']:.5g}: depth {depth:.3f}, slide {slide:.3f} of {SLIDE:g}; "
          f"{len(rows)} steps, {sum(r['cuts'] for r in rows)} cuts; Newton per step mean "
          f"{np.mean([r['newton'] for r in rows]):.1f}, max {max(r['newton'] for r in rows)}")

    title = f"mu = {args.mu:g}"
    write_curves(out, rows, args.mu, title)
    save_snapshots(out / "snapshots.npz", snaps)

    def label(s):
        return "t = {:.4g}: depth {:.2f}, slide {:.2f}".format(s.time, *load_parameters(s.time))
    times = np.array([r["time"] for r in rows])
    chosen = sorted({int(np.argmin(np.abs(times - t)))
                     for t in (1.0, 1.25, 1.5, 2.0) if t <= times[-1]}
                    | {len(rows) - 1})

    def tool_x(s):
        return 1.2 + load_parameters(s.time)[1]
    frames_png(out / "deformed.png", [snaps[i] for i in chosen], ncols=2, label=label,
               window=(-0.3, 12.3, 1.5, 6.3), panel=(6.0, 2.6),
               suptitle=f"ironing, {title}: tool arc coloured by contact pressure")
    if args.full:
        animation_gif(out / "load_path.gif", snaps[::2] + [snaps[-1]], label=label,
                      window=(-0.3, 12.3, 1.5, 6.3), size=(7.5, 3.0), fps=6)

    # checks
    balance = max(np.hypot(r["Rx"] + r["Fx_contact"], r["Ry"] + r["Fy_contact"])
                  / np.hypot(r["Rx"], r["Ry"]) for r in rows if r["active"] > 0)
    cone = max(r["cone_error"] for r in rows)
    print(f"tool reaction + contact force on the tool: max relative misfit {balance:.1e}")
    print(f"slipping nodes: max | |t_T| - mu p | / (mu p) = {cone:.1e}")
    steady = [r for r in rows if r["slide"] >= 2.0]
    if steady:
        ratio = np.array([abs(r["T"]) / r["N"] for r in steady])
        cart = np.array([abs(r["Rx"] / r["Ry"]) for r in steady])
        all_slip = sum(r["stick"] == 0 for r in steady)
        print(f"steady ironing (slide >= 2, {len(steady)} steps, {all_slip} with every active "
              f"node slipping): |T|/N mean {ratio.mean():.4f} (min {ratio.min():.4f}, max "
              f"{ratio.max():.4f}); |R_x/R_y| mean {cart.mean():.4f}")
    print(f"wrote {out}/reactions.csv, reactions.png, deformed.png, snapshots.npz"
          + (", load_path.gif" if args.full else ""))
    assert balance < 1e-6 and cone < 1e-8, (balance, cone)
    if not converged:
        print(f"NOT OK: the load path stopped at depth {depth:.3f}, slide {slide:.3f}")
        raise SystemExit(1)
    print("OK: tool balances the contact force, slipping nodes on the cone")
