"""Input hardening: every malformed scene or mesh in tests/bad_input/ is refused with one
message naming the problem (the file's ``# expect:`` line), exit code 2, no traceback, and
no outputs written."""
from pathlib import Path

import pytest

from fenicsx_mortar.cli import main

CASES = sorted(p for p in (Path(__file__).parent / "bad_input").glob("*.toml")
               if not p.name.startswith("_"))


def test_suite_is_large_enough():
    assert len(CASES) >= 30


@pytest.mark.parametrize("case", CASES, ids=lambda p: p.stem)
def test_refused(case, tmp_path, capsys):
    expect = case.read_text().splitlines()[0].removeprefix("# expect:").strip()
    out = tmp_path / "out"
    code = main(["run", str(case), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("fenicsx-mortar: error:") and err.count("\n") == 1, err
    assert expect in err, err
    assert not (out / "summary.json").exists()
