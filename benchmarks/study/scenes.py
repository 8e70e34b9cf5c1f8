"""The scene of one study run: a demo scene with the case's mesh level, contact method,
smoothing and enforcement, changed by dataclass fields only."""
from __future__ import annotations

from pathlib import Path

from fenicsx_mortar.scene import Enforcement, OutputSettings, Scene, load_scene

from .cases import LEVELS, RINGS_TIMES, Case

SCENES = Path(__file__).resolve().parents[2] / "demos" / "scenes"


def make_scene(case: Case, times: list[float] | None = None) -> Scene:
    """The scene of one run, with no file outputs. ``times`` overrides the load steps."""
    b, lv = case.benchmark, LEVELS[case.benchmark][case.level]
    if b == "patch":
        scene = load_scene(SCENES / "patch_test.toml")
    elif b in ("hertz", "hertz_mc"):
        scene = load_scene(SCENES / "hertz.toml")
    elif b == "half_rings":
        scene = load_scene(SCENES / "half_rings.toml")
        scene.steps.times = list(RINGS_TIMES)
        scene.steps.count = None
    else:
        raise ValueError(f"unknown benchmark {b!r}")
    scene.mesh.params = dict(scene.mesh.params, **lv.params)
    pair = scene.contacts[0]
    if b == "hertz_mc":
        pair.slave, pair.master = pair.master, pair.slave
    pair.method, pair.smoothing = case.method, case.smoothing
    tol = pair.enforcement.tolerance
    if case.enforcement in ("alm", "lagrange"):
        pair.enforcement = Enforcement(type=case.enforcement, tolerance=tol)
    else:
        factor = float(case.enforcement.split("-")[1])
        pair.enforcement = Enforcement(type="penalty", epsilon=factor * slave_modulus(scene) / lv.h,
                                       tolerance=tol)
    scene.output = OutputSettings(xdmf=False, plots=False)
    if times is not None:
        scene.steps.times, scene.steps.count = list(times), None
    # a run that needs increments below 1/16 of the scene's smallest one counts as failed
    # (the package default, 1e-4 of the final time, lets a stalled run creep on for minutes)
    targets = scene.steps.targets()
    scene.steps.min_increment = min(b - a for a, b in zip([0.0] + targets, targets)) / 16
    return scene


def slave_modulus(scene: Scene) -> float:
    """Young's modulus of the body whose boundary is the slave surface (by group name)."""
    slave = scene.contacts[0].slave
    slave = slave if isinstance(slave, str) else slave[0]
    for body in scene.bodies:
        if slave.startswith(body.group):
            return body.material.E
    return scene.bodies[0].material.E
