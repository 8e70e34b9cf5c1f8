"""Contact patch test (B1): mortar transmits the uniform pressure exactly across the
non-matching interface, with Lagrange multipliers (both bases, every smoothing) and with the
Uzawa ALM; node-to-segment does not (docs/design.md §9, docs/benchmarks.md B1)."""
import importlib.util

import pytest

from conftest import ROOT

spec = importlib.util.spec_from_file_location("demo_patch_test", ROOT / "demos/demo_patch_test.py")
demo = importlib.util.module_from_spec(spec)
spec.loader.exec_module(demo)


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_mortar_passes_patch_test(cell):
    stress_error, pressure_error, iterations, augmentations = demo.patch_errors("mortar", cell)
    assert stress_error <= 1e-8       # σ_yy = −1 in every cell of both blocks
    assert pressure_error <= 1e-8     # p = 1 at every active slave node


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_nts_fails_patch_test(cell):
    stress_error, pressure_error, _, _ = demo.patch_errors("nts", cell)
    assert stress_error > 1e-3


@pytest.mark.parametrize("smoothing", ["averaged-simple", "averaged-weighted", "averaged-tangent",
                                       "hermite", "bspline"])
def test_mortar_patch_test_with_smoothing(smoothing):
    """A flat master: every smoothed curve is the straight line (averaged normals equal the
    segment normals; Hermite and B-spline reproduce it with a linear parametrization, and
    test the traction with the master's linear shape functions, mortar.py), so smoothing
    must not spoil the exact transmission of the uniform pressure."""
    from fenicsx_mortar import load_scene, solve
    scene = load_scene(ROOT / "demos/scenes/patch_test.toml")
    scene.contacts[0].smoothing = smoothing
    result = solve(scene, log=lambda s: None)
    assert result.converged
    assert abs(result.stress.values()[:, 1, 1] + 1).max() <= 1e-8


@pytest.mark.parametrize("smoothing", ["averaged-simple", "averaged-weighted", "averaged-tangent",
                                       "hermite", "bspline"])
def test_nts_with_smoothing_converges(smoothing):
    """NTS with a smoothed master converges on the patch test (slave nodes sit exactly on
    master nodes at x = 1, 2, 3) and, as with the polyline, does not pass it."""
    from fenicsx_mortar import load_scene, solve
    scene = load_scene(ROOT / "demos/scenes/patch_test.toml")
    scene.contacts[0].smoothing = smoothing
    scene.contacts[0].method = "nts"
    result = solve(scene, log=lambda s: None)
    assert result.converged, result.message
    assert abs(result.stress.values()[:, 1, 1] + 1).max() > 1e-3


@pytest.mark.parametrize("basis", ["dual", "standard"])
@pytest.mark.parametrize("smoothing", ["none", "averaged-simple", "averaged-weighted",
                                       "averaged-tangent", "hermite", "bspline"])
def test_multipliers_pass_the_patch_test(smoothing, basis):
    """Lagrange multipliers (semi-smooth Newton), every smoothing and both bases: σ_yy = −1
    in every cell to 1e-10, p = 1 at the active nodes, in at most 5 Newton iterations (one
    solve, no augmentation)."""
    from fenicsx_mortar import load_scene, solve
    scene = load_scene(ROOT / "demos/scenes/patch_test.toml")
    c = scene.contacts[0]
    c.smoothing, c.basis, c.enforcement.type = smoothing, basis, "lagrange"
    result = solve(scene, log=lambda s: None)
    assert result.converged, result.message
    assert abs(result.stress.values()[:, 1, 1] + 1).max() <= 1e-10
    p = result.pairs[0].interface()["pressure"]
    assert abs(p[p > 0] - 1).max() <= 1e-10
    step = result.steps[-1]
    assert step["newton_iterations"] <= 5 and step["augmentations"] == 0


def test_alm_passes_the_patch_test():
    from fenicsx_mortar import load_scene, solve
    scene = load_scene(ROOT / "demos/scenes/patch_test.toml")
    scene.contacts[0].enforcement.type = "alm"
    result = solve(scene, log=lambda s: None)
    assert result.converged, result.message
    assert abs(result.stress.values()[:, 1, 1] + 1).max() <= 1e-8


@pytest.mark.parametrize("smoothing", ["none", "hermite", "bspline"])
def test_two_sided_smoothing_passes_the_patch_test(smoothing):
    """The slave's geometry from its own Hermite curve: on a flat slave that curve is the
    chord with its linear parametrization, and the traction is tested with the linear
    functions of both sides, so the uniform pressure is still transmitted exactly."""
    from fenicsx_mortar import load_scene, solve
    scene = load_scene(ROOT / "demos/scenes/patch_test.toml")
    c = scene.contacts[0]
    c.smoothing, c.slave_smoothing = smoothing, "hermite"
    result = solve(scene, log=lambda s: None)
    assert result.converged, result.message
    assert result.pairs[0].state.gap.tail_nodes is not None
    assert abs(result.stress.values()[:, 1, 1] + 1).max() <= 1e-10
