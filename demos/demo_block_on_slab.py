"""Frictional block on a slab (B5): sticking under a load, sliding under a displacement.

Problem: a block [0, 1] × [1, 1.5] (slave surface: its bottom) rests on a slab [−1, 2] × [0, 1]
(master: its top), E = 1000, ν = 0.3 (Neo-Hooke), Coulomb friction μ = 0.3, slab bottom
fixed (scene ``demos/scenes/block_on_slab.toml``). Phase 1 (t ∈ [0, 1]): a dead pressure 1
on the block top presses it down; the normal contact force becomes N = 1. Phase 2
(t ∈ [1, 2]), run two ways:

* stick, load-controlled: a horizontal dead traction on the block's left edge whose
  resultant grows to 0.8 μN = 0.24 (below the friction limit, so a static equilibrium
  exists; the left edge is not held);
* slide, displacement-controlled: u_x of the left edge driven to 0.1, well past the onset
  of sliding (load control beyond μN has no static equilibrium: the block would accelerate).

Expected result: while stuck, the force the slab exerts on the block along x equals the
applied force (1e-8 relative); once every contact node slips, the push reaction equals
that force and the contact-frame tangential force equals μ × normal force (1e-8 relative),
and every slipping node sits on the friction cone, |t_T| = μ |t_N|.

Writes ``results/demo_block_on_slab/``: ``reactions.csv`` and ``reactions.png`` (tangential
over normal contact force against the push, both runs) and ``slide.png`` (the deformed
bodies at the end of the slide, the block bottom coloured by contact pressure).
"""
from pathlib import Path

import numpy as np

from fenicsx_mortar import Traction, load_scene, solve
from fenicsx_mortar.io.pictures import frames_png, snapshot

MU, N_PRESS = 0.3, 1.0
OUT = Path(__file__).resolve().parents[1] / "results" / "demo_block_on_slab"
TIMES = [0.5, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 1.9, 2.0]


def scene_slide():
    scene = load_scene(Path(__file__).parent / "scenes" / "block_on_slab.toml")
    scene.steps.times = TIMES
    return scene


def scene_stick(applied: float):
    """The same scene, the push replaced by a traction whose resultant on the left edge
    (length 0.5) ramps to ``applied`` over phase 2."""
    scene = scene_slide()
    scene.dirichlet = [d for d in scene.dirichlet if d.name != "push"]
    scene.tractions = [Traction(boundary="block_left", value=[applied / 0.5, 0.0], curve="slide")]
    return scene


def carried_x(step: dict) -> float:
    """The force the slab exerts on the block along −x (normal + tangential contact parts)."""
    c = step["contact"]["interface"]
    return -(c["force_on_slave"][0] + c["tangential_force_on_slave"][0])


if __name__ == "__main__":
    OUT.mkdir(parents=True, exist_ok=True)
    applied_max = 0.8 * MU * N_PRESS
    stick = solve(scene_stick(applied_max), log=lambda s: None)
    assert stick.converged, stick.message
    curve = stick.scene.curve("slide")

    pictures = []
    slide = solve(scene_slide(), log=lambda s: None,
                  on_step=lambda rec, state: pictures.append(snapshot(state, rec["time"]))
                  if rec["time"] in (1.2, 2.0) else None)
    assert slide.converged, slide.message

    print("stick (load control):")
    print(f"{'t':>5s} {'applied':>10s} {'carried':>10s} {'rel. error':>10s} {'N':>8s} "
          f"{'T/(muN)':>8s} {'stick':>5s} {'slip':>5s}")
    stick_err = 0.0
    rows = []
    for s in stick.steps:
        c = s["contact"]["interface"]
        applied = applied_max * curve(s["time"])
        err = abs(carried_x(s) - applied) / applied if applied > 0 else 0.0
        stick_err = max(stick_err, err)
        ratio = abs(c["tangential_force"]) / (MU * c["normal_force"])
        print(f"{s['time']:5.2f} {applied:10.6f} {carried_x(s):10.6f} {err:10.1e} "
              f"{c['normal_force']:8.5f} {ratio:8.4f} {c['stick_nodes']:5d} {c['slip_nodes']:5d}")
        rows.append(("stick", s["time"], 0.0, applied, carried_x(s), c["normal_force"],
                     c["tangential_force"], c["stick_nodes"], c["slip_nodes"]))

    print("slide (displacement control):")
    print(f"{'t':>5s} {'u_push':>7s} {'reaction':>10s} {'carried':>10s} {'N':>8s} "
          f"{'|T|/(muN)-1':>11s} {'stick':>5s} {'slip':>5s}")
    slide_curve = slide.scene.curve("slide")
    for s in slide.steps:
        c = s["contact"]["interface"]
        u_push = 0.1 * slide_curve(s["time"])
        R = s["reactions"]["push"]["x"]
        dev = abs(c["tangential_force"]) / (MU * c["normal_force"]) - 1
        print(f"{s['time']:5.2f} {u_push:7.3f} {R:10.6f} {carried_x(s):10.6f} "
              f"{c['normal_force']:8.5f} {dev:11.1e} {c['stick_nodes']:5d} {c['slip_nodes']:5d}")
        rows.append(("slide", s["time"], u_push, R, carried_x(s), c["normal_force"],
                     c["tangential_force"], c["stick_nodes"], c["slip_nodes"]))

    # checks at the end of the slide, every contact node slipping
    last = slide.steps[-1]
    c = last["contact"]["interface"]
    d = slide.pairs[0].interface()
    on = d["pressure"] > 0
    all_slip = bool(np.all(d["status"][on] == "slip"))
    cone = float(np.max(np.abs(np.abs(d["t_tangential"][on]) - MU * d["pressure"][on])
                        / (MU * d["pressure"][on])))
    mu_err = abs(abs(c["tangential_force"]) / (MU * c["normal_force"]) - 1)
    R = last["reactions"]["push"]["x"]
    reaction_err = abs(R - carried_x(last)) / abs(R)
    print(f"stick: max |carried - applied| / applied = {stick_err:.1e}")
    print(f"slide, last step: {on.sum()} active nodes, all slipping: {all_slip}; "
          f"max | |t_T| - mu p | / (mu p) = {cone:.1e}")
    print(f"slide, last step: reaction {R:.8f}, carried {carried_x(last):.8f} (rel. diff "
          f"{reaction_err:.1e}); |T| / (mu N) - 1 = {mu_err:.1e}, "
          f"mu N = {MU * c['normal_force']:.8f}")

    # reaction curves: CSV and PNG
    header = ("run,time,u_push,applied_or_reaction_x,carried_x,normal_force,tangential_force,"
              "stick_nodes,slip_nodes")
    (OUT / "reactions.csv").write_text(header + "\n" + "\n".join(
        ",".join(str(v) if isinstance(v, (str, int)) else f"{v:.12g}" for v in r)
        for r in rows) + "\n")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8), constrained_layout=True)
    st = [r for r in rows if r[0] == "stick" and r[1] >= 1.0]
    a1.plot([r[3] for r in st], [r[4] for r in st], "o", label="carried by the contact")
    a1.plot([0, applied_max], [0, applied_max], "k-", lw=0.8, label="= applied")
    a1.axhline(MU * N_PRESS, color="tab:red", ls="--", lw=0.8, label="μN")
    a1.set(xlabel="applied force on the left edge", ylabel="contact force along x",
           title="stick: load-controlled")
    a1.legend(fontsize=8)
    sl = [r for r in rows if r[0] == "slide" and r[1] >= 1.0]
    a2.plot([r[2] for r in sl], [r[3] for r in sl], "o-", label="push reaction R_x")
    a2.plot([r[2] for r in sl], [MU * r[5] for r in sl], "k--", lw=0.8, label="μ × normal force")
    a2.set(xlabel="prescribed u_x of the left edge", ylabel="force",
           title="slide: displacement-controlled")
    a2.legend(fontsize=8)
    for a in (a1, a2):
        a.grid(alpha=0.3)
    fig.savefig(OUT / "reactions.png", dpi=120)
    plt.close(fig)
    frames_png(OUT / "slide.png", pictures, window=(-0.3, 1.35, 0.55, 1.6),
               label=lambda s: f"t = {s.time:g}: push u_x = {0.1 * slide_curve(s.time):.2f}",
               suptitle="B5 slide: block bottom coloured by contact pressure (o = slipping node)")
    print(f"wrote {OUT}/reactions.csv, reactions.png, slide.png")

    assert stick_err < 1e-8 and all_slip and cone < 1e-8 and mu_err < 1e-8 and reaction_err < 1e-8
    print("OK: stuck block carries the applied force, sliding block carries mu x normal force")
