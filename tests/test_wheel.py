"""The package installs as a wheel and runs from anywhere: ``pip wheel .``, install into a
fresh virtual environment (which sees Debian's DOLFINx, as the project's own does), then
``fenicsx-mortar run patch_test.toml`` in a directory holding nothing but the scene file.
The mesh generators travel inside the wheel (``fenicsx_mortar.meshes``)."""
import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from conftest import MPI_ENV, ROOT

PYTHON = "/usr/bin/python3" if Path("/usr/bin/python3").exists() else sys.executable


@pytest.mark.slow
def test_wheel_runs_the_patch_test_from_any_directory(tmp_path):
    # build from a copy of the sources: setuptools leaves a build/ folder where it builds
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE", "fenicsx_mortar", "meshes"):
        copy = shutil.copytree if (ROOT / name).is_dir() else shutil.copy
        copy(ROOT / name, src / name, **({"ignore": shutil.ignore_patterns("__pycache__")}
                                         if (ROOT / name).is_dir() else {}))
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps",
                    "--no-build-isolation", "-w", str(wheels), str(src)],
                   check=True, cwd=tmp_path, capture_output=True, text=True)
    (wheel,) = wheels.glob("fenicsx_mortar-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert "fenicsx_mortar/meshes/patch_test.py" in names
    venv = tmp_path / "venv"
    subprocess.run([PYTHON, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", "--no-deps",
                    "--no-index", str(wheel)], check=True, capture_output=True, text=True)
    work = tmp_path / "elsewhere"
    work.mkdir()
    shutil.copy(ROOT / "demos" / "scenes" / "patch_test.toml", work)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run([str(venv / "bin" / "fenicsx-mortar"), "run", "patch_test.toml",
                           "--out", "out"], cwd=work, capture_output=True, text=True,
                          env={**env, **MPI_ENV}, timeout=600)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    summary = json.loads((work / "out" / "summary.json").read_text())
    assert summary["converged"]
    # the installed copy ran (not the source tree), and got the patch test's exact pressure
    where = subprocess.run([str(venv / "bin" / "python"), "-c",
                            "import fenicsx_mortar; print(fenicsx_mortar.__file__)"],
                           cwd=work, capture_output=True, text=True, env=env).stdout
    assert str(venv) in where, where
    (contact,) = summary["steps"][-1]["contact"].values()
    assert contact["max_pressure"] == pytest.approx(1.0, abs=1e-8)
