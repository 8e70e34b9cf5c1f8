"""output.write_file, the one way a run writes a file (issue 28): it stays under --out
whatever the names and the links inside it, and leaves no temporary file."""
import errno
import fcntl
import os

import pytest

from fenicsx_mortar.io.output import locked, path_for, write_file
from fenicsx_mortar.scene import SceneError


@pytest.mark.parametrize("rel", ["../x", "/tmp/x", "a/../../x", "", ".", "a\x00b"])
def test_names_that_leave_out_are_refused(tmp_path, rel):
    out = tmp_path / "out"
    out.mkdir()
    with pytest.raises(ValueError):
        write_file(out, rel, "x")
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["out"]


def test_a_link_to_a_directory_is_refused_and_a_link_to_a_file_replaced(tmp_path):
    out, elsewhere, victim = tmp_path / "out", tmp_path / "elsewhere", tmp_path / "victim"
    out.mkdir()
    elsewhere.mkdir()
    victim.write_text("keep")
    (out / "interface").symlink_to(elsewhere)
    with pytest.raises(OSError) as e:
        write_file(out, "interface/c_0001.csv", "s,x\n")
    assert e.value.errno in (errno.ELOOP, errno.ENOTDIR)
    assert e.value.filename == str(out / "interface/c_0001.csv")
    assert list(elsewhere.iterdir()) == []
    (out / "summary.json").symlink_to(victim)
    write_file(out, "summary.json", "{}")
    assert victim.read_text() == "keep" and not (out / "summary.json").is_symlink()
    assert (out / "summary.json").read_text() == "{}"
    assert sorted(p.name for p in out.iterdir()) == ["interface", "summary.json"]


def test_directories_are_made_and_out_may_be_a_link(tmp_path):
    real = tmp_path / "real"
    real.mkdir()
    (tmp_path / "out").symlink_to(real)
    write_file(tmp_path / "out", "interface/c_0001.csv", b"bytes")
    assert (real / "interface/c_0001.csv").read_bytes() == b"bytes"


def test_path_for_removes_links_at_the_xdmf_and_h5_names(tmp_path):
    out, victim = tmp_path / "out", tmp_path / "victim"
    out.mkdir()
    victim.write_text("keep")
    for name in ("solution.xdmf", "solution.h5"):
        (out / name).symlink_to(victim)
    assert path_for(out, "solution.xdmf") == out / "solution.xdmf"
    assert list(out.iterdir()) == [] and victim.read_text() == "keep"


def test_the_lock_refuses_a_second_holder(tmp_path):
    other = os.open(tmp_path, os.O_RDONLY)
    try:
        fcntl.flock(other, fcntl.LOCK_EX)
        with pytest.raises(SceneError, match="another run"):
            with locked(tmp_path):
                pass
    finally:
        os.close(other)
    with locked(tmp_path):          # free again: taken, and released on leaving
        pass
    with locked(tmp_path):
        pass
