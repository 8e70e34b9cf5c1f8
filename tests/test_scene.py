"""Scene validation: each malformed scene is refused with one message naming the problem,
exit code 2, no traceback."""
import textwrap

import pytest

from conftest import run_cli
from fenicsx_mortar import load_scene
from fenicsx_mortar.cli import main

GOOD = """
title = "ok"
[mesh]
generator = "block_on_slab"
[[bodies]]
name = "block"
material = { model = "neo-hooke", E = 1000.0, nu = 0.3 }
[[bodies]]
name = "slab"
material = { model = "svk", E = 1000.0, nu = 0.3 }
[[dirichlet]]
boundary = "slab_bottom"
x = 0.0
y = 0.0
[[pressures]]
boundary = "block_top"
value = 1.0
[[contacts]]
name = "c"
slave = "block_bottom"
master = "slab_top"
"""


def write(tmp_path, text: str):
    p = tmp_path / "scene.toml"
    p.write_text(textwrap.dedent(text))
    return p


def test_good_scene_parses(tmp_path):
    scene = load_scene(write(tmp_path, GOOD))
    assert [b.name for b in scene.bodies] == ["block", "slab"]
    assert scene.contacts[0].method == "mortar"
    assert any(e.startswith("contact c: mortar, lagrange") for e in scene.effects())


BAD = {
    "unknown key": (GOOD.replace('title = "ok"', 'title = "ok"\ncolour = "red"'), "colour"),
    "unknown nested key": (GOOD.replace("E = 1000.0, nu = 0.3 }",
                                        "E = 1000.0, nu = 0.3, rho = 1.0 }", 1),
                           "bodies[0].material.rho"),
    "wrong type": (GOOD.replace("E = 1000.0", 'E = "stiff"', 1), "bodies[0].material.E"),
    "E <= 0": (GOOD.replace("E = 1000.0", "E = 0.0", 1), "bodies[0].material.E"),
    "nu = 0.5": (GOOD.replace("nu = 0.3", "nu = 0.5", 1), "bodies[0].material.nu"),
    "nu = -1": (GOOD.replace("nu = 0.3", "nu = -1.0", 1), "bodies[0].material.nu"),
    "unknown material": (GOOD.replace('"neo-hooke"', '"mooney"'), "bodies[0].material.model"),
    "missing mesh file": (GOOD.replace('generator = "block_on_slab"', 'file = "nowhere.msh"'),
                          "nowhere.msh"),
    "slave equals master": (GOOD.replace('master = "slab_top"', 'master = "block_bottom"'),
                            "contacts[0]"),
    "missing physical group": (GOOD.replace('boundary = "block_top"', 'boundary = "lid"'), "'lid'"),
    "missing body group": (GOOD.replace('name = "slab"', 'name = "plate"'), "'plate'"),
    "TOML syntax": (GOOD + "\n[[bodies]\n", "TOML syntax"),
    "zero steps": (GOOD + "\n[steps]\ncount = 0\n", "steps.count"),
    "missing required key": (GOOD.replace('value = 1.0\n', ''), "pressures[0].value"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scene_refused(case, tmp_path, capsys):
    text, named = BAD[case]
    code = main(["run", str(write(tmp_path, text)), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2
    assert named in err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "out" / "summary.json").exists()


def test_bad_scene_cli_process(tmp_path):
    """The installed entry point: exit code 2 and no traceback from a real process."""
    p = write(tmp_path, GOOD.replace("nu = 0.3", "nu = 0.7", 1))
    proc = run_cli("run", str(p), "--out", str(tmp_path / "out"))
    assert proc.returncode == 2
    assert "bodies[0].material.nu" in proc.stderr
    assert "Traceback" not in proc.stderr
