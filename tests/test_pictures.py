"""fenicsx_mortar.io.pictures: snapshots of a solved state, save/load, PNG and GIF output."""
import numpy as np
import pytest

from conftest import ROOT
from fenicsx_mortar import load_scene, solve
from fenicsx_mortar.io.pictures import (Snapshot, animation_gif, frames_png, load_snapshots,
                                     pressure_scale, save_snapshots, snapshot, von_mises)


def toy(t: float) -> Snapshot:
    """Two unit squares, the upper one's bottom edge the 'slave' with pressures."""
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1],
                    [0, 1.0 + t], [1, 1.0 + t], [1, 2], [0, 2]], float)
    return Snapshot(time=t, points=pts, cells=np.array([[0, 1, 2, 3], [4, 5, 6, 7]]),
                    body=np.array([1, 2]), sigma=np.zeros((2, 2, 2)),
                    surface=pts[[4, 5]], segments=np.array([[0, 1]]),
                    pressure=np.array([1.0 + t, 0.0]), t_tangential=np.array([0.3, 0.0]),
                    status=np.array([2, 0]))


def test_save_load_roundtrip(tmp_path):
    snaps = [toy(0.0), toy(0.5)]
    save_snapshots(tmp_path / "s.npz", snaps)
    back = load_snapshots(tmp_path / "s.npz")
    assert [s.time for s in back] == [0.0, 0.5]
    for a, b in zip(snaps, back):
        for name in ("points", "cells", "pressure", "status", "segments"):
            assert np.array_equal(getattr(a, name), getattr(b, name))


def test_png_and_gif_are_written(tmp_path):
    snaps = [toy(t) for t in (0.0, 0.25, 0.5)]
    png = frames_png(tmp_path / "f.png", snaps, label=lambda s: f"t={s.time}")
    gif = animation_gif(tmp_path / "a.gif", snaps, fps=4)
    from PIL import Image
    assert Image.open(png).size[0] > 300
    with Image.open(gif) as im:
        assert im.n_frames == 3


def test_pressure_scale_ignores_a_single_spike():
    s = toy(0.0)
    s.pressure = np.r_[np.ones(99), 1e4]
    assert pressure_scale([s]) < 10


def test_von_mises_of_uniaxial_stress():
    sigma = np.zeros((1, 2, 2))
    sigma[0, 1, 1] = -1.0
    assert von_mises(sigma, nu=0.0)[0] == pytest.approx(1.0)


def test_snapshot_of_a_solved_state(tmp_path):
    scene = load_scene(ROOT / "demos/scenes/block_on_slab.toml")
    scene.steps.times = [1.0]
    snaps = []
    result = solve(scene, log=lambda s: None,
                   on_step=lambda rec, state: snaps.append(snapshot(state, rec["time"])))
    assert result.converged
    s = snaps[0]
    msh = result.domain.mesh
    # every mesh node appears and the deformed nodes are geometry nodes + displacement
    assert s.points.shape == (msh.geometry.x.shape[0], 2)
    assert s.cells.shape[0] == len(s.body) == len(s.sigma)
    assert set(np.unique(s.body)) == set(result.domain.cell_groups.values())
    # pressures and positions are those of the pair's interface, and the cells are
    # counter-clockwise polygons (positive area) in the deformed configuration
    d = result.pairs[0].interface()
    assert np.allclose(s.pressure, d["pressure"]) and np.allclose(s.surface[:, 0], d["x"])
    p = s.points[s.cells]
    area = 0.5 * np.sum(p[:, :, 0] * np.roll(p[:, :, 1], -1, 1)
                        - np.roll(p[:, :, 0], -1, 1) * p[:, :, 1], axis=1)
    assert np.all(area > 0)
    assert np.isclose(area.sum(), 3.0 + 0.5, rtol=1e-2)  # slab 3 × 1 + block 1 × 0.5
    assert set(s.status[s.pressure > 0]) <= {1, 2}
    frames_png(tmp_path / "b5.png", snaps)
