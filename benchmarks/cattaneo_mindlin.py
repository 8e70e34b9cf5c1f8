"""Cattaneo–Mindlin partial slip (docs/friction.md): two cylinders of one material pressed by
P, then sheared by Q < μP; the stick zone, the tangential traction and the force ratio per
enforcement, master smoothing and mesh level against Johnson's analytic solution.

    .venv/bin/python benchmarks/cattaneo_mindlin.py                       # 3 levels x 5 x 3
    .venv/bin/python benchmarks/cattaneo_mindlin.py --levels 0 --enforcements alm-stick
    .venv/bin/python benchmarks/cattaneo_mindlin.py --redraw              # table + plot only

The scene ``demos/scenes/cattaneo_mindlin.toml``: half-disks R = 1 (E = 1000, ν = 0.3,
Neo-Hooke), the upper one pressed by its flat top in four steps (P ≈ 1), then a tangential
dead load Q on that top at Q/(μP) = 0.3, 0.6, 0.9 (t = 2, 3, 4; one step each), μ = 0.3.
Level L: element size h_c = a/(10·2^L) on the slave arc near the contact, 1.37 h_c on the
master's (non-matching). Per run and shear state, with P the measured normal contact force
(the press reaction), a = 2√(P R*/(πE*)), p₀ = 2P/(πa), R* = R/2, E* = E/(2(1 − ν²)), and the
nodal values in the current configuration, x measured from the pressure's centroid:

* c/a: the stick-zone half-width. c is fitted to the nodal deficit μp_j − q_j (the analytic
  deficit is μp₀ (c/a) √(1 − x²/c²) in |x| < c and 0 outside) by least squares; the status
  bracket [outermost sticking node, innermost slipping node] is printed with it.
* L2(q): ‖q_h − q‖/‖q‖ over [−a, a], q_h the piecewise-linear nodal traction.
* The analytic solution is taken in the contact's frame: P and Q are the normal and
  tangential contact forces N, T (Σ p_j ψ_j, Σ t_j A_j); T/Q, the tangential contact force
  over the applied load, is printed (the shear tilts the contact plane: T ≠ Q by ~1 %).
* Newton iterations per step (all solves of the step: augmentations included) and the
  Uzawa augmentations; the press residue max |q|/(μp₀) at the end of the press (t = 1).

Writes ``docs/cattaneo_mindlin.json`` (every run's numbers and nodal tractions) and
``docs/cattaneo_mindlin.png`` (q(x) against the analytic curve at each level, multipliers
and ALM, no smoothing). An enforcement "type:basis" picks the mortar basis:
``alm-stick:dual``, ``lagrange:standard`` (the multipliers with the ALM's default basis).
Runs one at a time (the machine is shared): 15 min for all 45 under load (2026-12-05).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SCENE = ROOT / "demos" / "scenes" / "cattaneo_mindlin.toml"
DATA = ROOT / "docs" / "cattaneo_mindlin.json"
PNG = ROOT / "docs" / "cattaneo_mindlin.png"
LEVELS = (0, 1, 2)
ENFORCEMENTS = ("lagrange", "lagrange:standard", "alm", "alm-stick", "alm-stick:dual")
SMOOTHINGS = ("none", "hermite", "bspline")
SHEAR_TIMES = (2.0, 3.0, 4.0)


# ------------------------------------------------------------------ analytic (Johnson §7.1)
def half_width(P: float, R_star: float, E_star: float) -> float:
    """a = 2√(P R*/(π E*)) (plane strain, force per unit thickness)."""
    return 2.0 * math.sqrt(P * R_star / (math.pi * E_star))


def stick_ratio(Q: float, mu: float, P: float) -> float:
    """c/a = √(1 − Q/(μP)) for 0 ≤ Q ≤ μP."""
    return math.sqrt(max(1.0 - Q / (mu * P), 0.0))


def traction(x, a: float, c: float, p0: float, mu: float) -> np.ndarray:
    """Cattaneo–Mindlin q(x) = μp₀ √(1 − x²/a²) − μp₀ (c/a) √(1 − x²/c²) (second term in
    |x| < c only), zero outside [−a, a]."""
    x = np.asarray(x, dtype=float)
    full = mu * p0 * np.sqrt(np.clip(1.0 - (x / a) ** 2, 0.0, None))
    if c <= 0:
        return full
    return full - mu * p0 * (c / a) * np.sqrt(np.clip(1.0 - (x / c) ** 2, 0.0, None))


def metrics(x, p, q, status, P: float, Q: float, mu: float, R_star: float,
            E_star: float) -> dict:
    """Stick zone and traction error of one state (nodal x, p, q ≥ 0 along Q, status).

    Args:
        x, p, q, status: per slave node (current x, pressure, tangential traction signed
            along Q, "stick"/"slip"/"inactive").
        P, Q: the normal contact force and the applied tangential load.
        mu, R_star, E_star: friction coefficient, reduced radius and modulus.

    Returns:
        c_fit/a, the status bracket, c/a analytic, L2(q), a and p₀.
    """
    from scipy.integrate import trapezoid
    from scipy.optimize import minimize_scalar
    a = half_width(P, R_star, E_star)
    p0 = 2.0 * P / (math.pi * a)
    on = p > 0
    x = np.asarray(x) - np.sum(x[on] * p[on]) / np.sum(p[on])   # centre of the pressure
    order = np.argsort(x)
    x, p, q, status = x[order], p[order], q[order], np.asarray(status)[order]
    deficit = mu * p - q
    w = np.gradient(x) * (p > 0)

    def misfit(c):
        model = mu * p0 * (c / a) * np.sqrt(np.clip(1.0 - (x / c) ** 2, 0.0, None))
        return float(np.sum(w * (deficit - model) ** 2))
    c_fit = float(minimize_scalar(misfit, bounds=(1e-3 * a, 1.2 * a), method="bounded",
                                  options={"xatol": 1e-9 * a}).x)
    stick, slip = np.abs(x[status == "stick"]), np.abs(x[status == "slip"])
    inner = slip[slip < stick.max()] if stick.size and slip.size else slip
    bracket = (float(stick.max()) / a if stick.size else 0.0,
               float(slip.min()) / a if slip.size else float("nan"))
    c = stick_ratio(Q, mu, P) * a
    xs = np.linspace(-a, a, 4001)
    exact = traction(xs, a, c, p0, mu)
    l2 = math.sqrt(trapezoid((np.interp(xs, x, q) - exact) ** 2, xs) / trapezoid(exact ** 2, xs))
    return {"c_fit": c_fit / a, "c_exact": c / a, "bracket": bracket,
            "slip_inside_stick": int(inner.size), "l2": l2, "a": a, "p0": p0}


# ------------------------------------------------------------------ runs
def scene_for(level: int, enforcement: str, smoothing: str):
    """The scene at ``level``; ``enforcement`` is a type, or "type:basis" (alm-stick:dual)."""
    from fenicsx_mortar import load_scene
    scene = load_scene(SCENE)
    scene.mesh.params = dict(scene.mesh.params, h_contact=scene.mesh.params["h_contact"]
                             / 2 ** level)
    c = scene.contacts[0]
    kind, _, basis = enforcement.partition(":")
    c.enforcement.type, c.smoothing, c.basis = kind, smoothing, basis or None
    scene.output.xdmf = scene.output.plots = False
    return scene


def constants(scene) -> dict:
    """μ, R*, E*, and Q at t' = 1 (the traction along x times the top's length 2R)."""
    mat = scene.bodies[0].material
    R = scene.mesh.params.get("R", 1.0)
    return {"mu": scene.contacts[0].friction.mu, "R_star": R / 2,
            "E_star": mat.E / (2.0 * (1.0 - mat.nu ** 2)),
            "Q_max": scene.tractions[0].value[0] * 2.0 * R}


def shear_fraction(t: float) -> float:
    return min(max((t - 1.0) / 3.0, 0.0), 1.0)


def run(level: int, enforcement: str, smoothing: str, log=print) -> dict:
    """Solve one configuration; its numbers per shear state (JSON-ready)."""
    from fenicsx_mortar import solve
    scene = scene_for(level, enforcement, smoothing)
    k = constants(scene)
    states, steps = {}, []

    def on_step(rec, state):
        d = state.pairs[0].interface() if hasattr(state, "pairs") else None
        steps.append(rec)
        if d is not None:
            states[round(rec["time"], 9)] = {key: np.asarray(v).tolist() for key, v in d.items()
                                             if key in ("x", "pressure", "t_tangential",
                                                        "status")}
    t0 = time.perf_counter()
    res = solve(scene, log=lambda s: log(f"  [L{level} {enforcement} {smoothing}] {s}"),
                on_step=on_step)
    wall = time.perf_counter() - t0
    out = {"level": level, "enforcement": enforcement, "smoothing": smoothing,
           "converged": bool(res.converged), "message": res.message, "wall": wall,
           "dofs": res.summary.get("dofs"), "steps": [], "states": {}}
    for rec in res.steps:
        c = rec["contact"][scene.contacts[0].name]
        out["steps"].append({"time": rec["time"], "newton": rec["newton_iterations"],
                             "augmentations": rec["augmentations"], "cuts": rec["cuts"],
                             "P": c["normal_force"], "T": c["tangential_force"],
                             "kkt": c["kkt_residual"]})
    for t, d in states.items():
        rec = next(s for s in out["steps"] if abs(s["time"] - t) < 1e-9)
        x, p = np.array(d["x"]), np.array(d["pressure"])
        q = np.array(d["t_tangential"])
        Q = k["Q_max"] * shear_fraction(t)
        sign = np.sign(rec["T"]) if rec["T"] else 1.0
        entry = {"x": d["x"], "p": d["pressure"], "q": (sign * q).tolist(),
                 "status": d["status"], "P": rec["P"], "Q": Q, "T": abs(rec["T"])}
        if t > 1.0 + 1e-9:
            # the analytic solution in the contact's frame: its normal and tangential forces
            # (the shear tilts the contact plane: T differs from the applied Q by 0.8 %)
            entry.update(metrics(x, p, sign * q, np.array(d["status"]), rec["P"],
                                 abs(rec["T"]), k["mu"], k["R_star"], k["E_star"]))
            entry["force_ratio"] = abs(rec["T"]) / Q
        else:
            a = half_width(rec["P"], k["R_star"], k["E_star"])
            p0 = 2.0 * rec["P"] / (math.pi * a)
            entry["residue"] = float(np.abs(q).max() / (k["mu"] * p0))
        keep = (p > 0) | (q != 0)      # the nodal arrays of the contact zone only (JSON size)
        for key in ("x", "p", "q", "status"):
            entry[key] = np.asarray(entry[key])[keep].tolist()
        out["states"][f"{t:g}"] = entry
    return out


# ------------------------------------------------------------------ report
def table(runs: list[dict]) -> str:
    lines = ["| level | enforcement | smoothing | T/μN | c/a exact | c/a fit | stick/slip "
             "bracket /a | L2(q) | T/Q | Newton/step (max) | aug. | press residue |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in runs:
        press = r["states"].get("1", {}).get("residue", float("nan"))
        shear = {s["time"]: s for s in r["steps"]}
        for t in SHEAR_TIMES:
            e = r["states"].get(f"{t:g}")
            s = shear.get(t)
            if e is None:
                lines.append(f"| {r['level']} | {r['enforcement']} | {r['smoothing']} | "
                             f"{0.3 * (t - 1):.1f} | not reached: {r['message'][:60]} |")
                continue
            newton = [x["newton"] for x in r["steps"] if x["time"] > t - 1 + 1e-9
                      and x["time"] <= t + 1e-9]
            ratio = e["T"] / (0.3 * e["P"])
            lines.append(
                f"| {r['level']} | {r['enforcement']} | {r['smoothing']} | {ratio:.3f} | "
                f"{e['c_exact']:.3f} | {e['c_fit']:.3f} ({_rel(e['c_fit'], e['c_exact'])})"
                f" | {e['bracket'][0]:.3f}–{e['bracket'][1]:.3f} | {e['l2']:.2%} | "
                f"{e['force_ratio']:.6f} | {np.mean(newton):.0f} ({max(newton)}) | "
                f"{s['augmentations'] if s else '-'} | {press:.3f} |")
    return "\n".join(lines)


def summary(runs: list[dict]) -> str:
    """One row per run: c/a error and L2(q) at the three shear states, Newton iterations
    and augmentations per step (all steps: press and shear), the press residue."""
    lines = ["| level | enforcement | smoothing | c_fit/c − 1 at T/μN ≈ 0.3 / 0.6 / 0.9 | "
             "L2(q) | Newton/step mean (max) | augmentations/step mean (max) | "
             "press residue | completed |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in runs:
        es = [r["states"].get(f"{t:g}") for t in SHEAR_TIMES]
        c = " / ".join(_rel(e["c_fit"], e["c_exact"]) if e else "–" for e in es)
        l2 = " / ".join(f"{e['l2']:.1%}" if e else "–" for e in es)
        newton = [s["newton"] for s in r["steps"]] or [0]
        aug = [s["augmentations"] for s in r["steps"]] or [0]
        press = r["states"].get("1", {}).get("residue", float("nan"))
        lines.append(f"| {r['level']} | {r['enforcement']} | {r['smoothing']} | {c} | {l2} | "
                     f"{np.mean(newton):.1f} ({max(newton, default=0)}) | "
                     f"{np.mean(aug):.1f} ({max(aug, default=0)}) | {press:.3f} | "
                     f"{'yes' if r['converged'] else 'no'} |")
    return "\n".join(lines)


def _compact(runs: list[dict]) -> list[dict]:
    """The JSON kept in docs: 7 digits, nodal arrays only where the plot uses them."""
    def rnd(x):
        if isinstance(x, float):
            return float(f"{x:.7g}")
        if isinstance(x, list):
            return [rnd(v) for v in x]
        if isinstance(x, dict):
            return {k: rnd(v) for k, v in x.items()}
        return x
    out = []
    for r in runs:
        r = rnd(r)
        if r["smoothing"] != "none":
            for e in r["states"].values():
                for key in ("x", "p", "q", "status"):
                    e.pop(key, None)
        out.append(r)
    return out


def _order(run: dict) -> tuple:
    def index(seq, x):
        return seq.index(x) if x in seq else len(seq)
    return (run["level"], index(ENFORCEMENTS, run["enforcement"]),
            index(SMOOTHINGS, run["smoothing"]))


def _rel(x: float, ref: float) -> str:
    return f"{x / ref - 1:+.1%}" if ref > 0 else "-"


def plot(runs: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    # lagrange:standard is not drawn: its tractions are alm-stick's (the same basis)
    picked = [r for r in runs if r["smoothing"] == "none"
              and r["enforcement"] != "lagrange:standard"]
    levels = sorted({r["level"] for r in picked})
    fig, axes = plt.subplots(1, len(levels), figsize=(5 * len(levels), 4), squeeze=False)
    for ax, level in zip(axes[0], levels):
        for r in picked:
            if r["level"] != level:
                continue
            for t, colour in zip(SHEAR_TIMES, ("C0", "C1", "C2")):
                e = r["states"].get(f"{t:g}")
                if e is None:
                    continue
                x, p = np.array(e["x"]), np.array(e["p"])
                x = x - np.sum(x * p) / np.sum(p)
                o = np.argsort(x)
                mark = {"lagrange": "o", "alm": "x", "alm-stick": "+"}.get(r["enforcement"], "1")
                ratio = e["T"] / (0.3 * e["P"])
                ax.plot(x[o] / e["a"], np.array(e["q"])[o] / (0.3 * e["p0"]), mark, ms=3,
                        color=colour, label=f"{r['enforcement']} T/μN={ratio:.2f}")
                if r["enforcement"] == "lagrange":
                    xs = np.linspace(-1.2, 1.2, 600)
                    ax.plot(xs, traction(xs * e["a"], e["a"], e["c_exact"] * e["a"], e["p0"],
                                         0.3) / (0.3 * e["p0"]), "-", color=colour, lw=1)
        ax.set_xlim(-1.2, 1.2)
        ax.set_xlabel("x / a")
        ax.set_ylabel("q / (μ p₀)")
        ax.set_title(f"level {level}: h = a/{10 * 2 ** level}")
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=6, loc="lower center", ncol=3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", default=",".join(map(str, LEVELS)))
    ap.add_argument("--enforcements", default=",".join(ENFORCEMENTS))
    ap.add_argument("--smoothings", default=",".join(SMOOTHINGS))
    ap.add_argument("--redraw", action="store_true", help="table and plot from the JSON")
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--png", type=Path, default=PNG)
    args = ap.parse_args(argv)
    runs = json.loads(args.data.read_text()) if args.data.exists() else []
    if not args.redraw:
        for level in map(int, args.levels.split(",")):
            for enf in args.enforcements.split(","):
                for sm in args.smoothings.split(","):
                    r = run(level, enf, sm)
                    print(f"L{level} {enf} {sm}: {r['message']} ({r['wall']:.0f} s)", flush=True)
                    runs = [x for x in runs if (x["level"], x["enforcement"], x["smoothing"])
                            != (level, enf, sm)] + [r]
                    runs.sort(key=_order)
                    args.data.write_text(json.dumps(_compact(runs), separators=(",", ":")))
    runs.sort(key=_order)
    print(table(runs))
    print()
    print(summary(runs))
    plot(runs, args.png)
    return 0


if __name__ == "__main__":
    sys.exit(main())
