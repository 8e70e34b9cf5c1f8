"""Every demo script runs as a user would run it and ends with its own physical check."""
import sys

import pytest

from conftest import ROOT, run_python

DEMOS = sorted(p.name for p in (ROOT / "demos").glob("demo_*.py"))


@pytest.mark.parametrize("demo", DEMOS)
def test_demo_runs(demo):
    proc = run_python([sys.executable, str(ROOT / "demos" / demo)])
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "OK:" in proc.stdout.splitlines()[-1]
