"""The accuracy-vs-time study (benchmarks/study): a tiny study end to end, the
post-processing functions on known inputs, and the command line."""
from __future__ import annotations

import csv
import importlib.util
import math

import numpy as np
import pytest

from benchmarks import analytics
from benchmarks.study import cases, metrics, plots, runner, scenes
from benchmarks.study.cases import Case, Plan
from benchmarks.study.records import key
from benchmarks.study.report import best_within, report

from conftest import ROOT, run_cli

# B1 at the coarsest level: both methods, without smoothing, ALM and a penalty; Hertz
# (slave-curved) mortar + ALM at the two coarsest levels. (B3 runs take ~30 s even on the
# coarsest mesh with its bspline reference: its post-processing is tested on given curves.)
TINY = ([Case("patch", m, "none", e, 0) for m in ("nts", "mortar") for e in ("alm", "penalty-10")]
        + [Case("hertz", "mortar", "none", "alm", k) for k in (0, 1)])


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("study")
    plan = cases.make_plan("tiny", list(TINY), cpu_limit=120.0, wall_limit=600.0)
    records = runner.run_study(plan, out, jobs=2, log=lambda s: None)
    with (out / "study" / "runs.csv").open() as f:
        rows = list(csv.DictReader(f))
    return out, records, {(r["benchmark"], r["method"], r["smoothing"], r["enforcement"],
                           int(r["level"])): r for r in rows}


def test_csv_has_every_requested_combination_once(tiny):
    out, records, rows = tiny
    assert len(records) == len(TINY)
    assert set(rows) == {c.key for c in TINY}
    for r in rows.values():
        assert r["status"] in ("converged", "failed", "timeout", "error", "crashed", "skipped")
        assert r["converged"] == str(r["status"] == "converged")
        if r["status"] != "skipped":
            assert float(r["cpu_time"]) > 0 and float(r["wall_time"]) > 0
    # the timings by phase are there and account for the total (they overlap a little:
    # building the contact matrix counts as both jit and contact)
    r = rows[("patch", "mortar", "none", "alm", 0)]
    parts = sum(float(r[f"t_{p}"]) for p in ("mesh", "jit", "bulk_assembly", "contact",
                                             "linear_solve", "output"))
    assert 0.5 * float(r["t_total"]) < parts < 1.2 * float(r["t_total"])
    assert float(r["t_contact_kernel"]) > 0 and int(float(r["newton_iterations"])) > 0


def test_patch_test_mortar_exact_nts_not(tiny):
    _, _, rows = tiny
    mortar = rows[("patch", "mortar", "none", "alm", 0)]
    nts = rows[("patch", "nts", "none", "alm", 0)]
    assert mortar["status"] == "converged" and nts["status"] == "converged"
    assert float(mortar["err_sigma_yy"]) < 1e-8
    assert float(nts["err_sigma_yy"]) > 1e-3
    # a penalty lets the bodies overlap by p/epsilon: the patch test is passed only to
    # about that (pressure 1, epsilon = 10 E/h = 1e5 here)
    pen = float(rows[("patch", "mortar", "none", "penalty-10", 0)]["err_sigma_yy"])
    assert 1e-9 < pen < 1e-3


def test_hertz_mortar_error_decreases_with_refinement(tiny):
    _, _, rows = tiny
    coarse, fine = (rows[("hertz", "mortar", "none", "alm", k)] for k in (0, 1))
    assert coarse["status"] == fine["status"] == "converged"
    for err in ("err_l2", "err_p0"):
        assert float(fine[err]) < float(coarse[err])
    assert float(fine["err_l2"]) < 0.15
    assert float(fine["err_force"]) < 1e-8          # contact force = applied force
    assert int(float(fine["augmentations"])) > 0    # ALM did augment


def test_half_rings_errors_against_the_reference_record():
    """finalize_rings: the reference's own error is 0, a converged run gets its error and
    oscillation, a failed run neither."""
    ref_case = Case("half_rings", "mortar", "bspline", "alm", 3)
    t = cases.RINGS_TIMES
    curve = lambda dx: [[tk, 40 * max(tk - 1, 0) + dx * (tk >= 1), -80.0] for tk in t]  # noqa: E731

    def rec(case, status, c):
        return dict(benchmark=case.benchmark, method=case.method, smoothing=case.smoothing,
                    enforcement=case.enforcement, level=case.level, status=status, curve=c)
    records = [rec(ref_case, "converged", curve(0.0)),
               rec(Case("half_rings", "nts", "none", "alm", 0), "converged", curve(2.0)),
               rec(Case("half_rings", "mortar", "none", "alm", 0), "failed", curve(0.0)[:5])]
    metrics.finalize_rings(records, ref_case)
    ref, ok, bad = records
    assert ref["reference"] and ref["err_reaction"] == 0.0
    assert ok["err_reaction"] == pytest.approx(2.0 / max(math.hypot(40 * max(tk - 1, 0), 80)
                                                         for tk in t))
    assert ok["osc_reaction"] < 1e-12          # a straight line plus a constant offset
    assert bad["err_reaction"] == "" and bad["osc_reaction"] == ""


def test_report_and_plots_written(tiny):
    out, _, _ = tiny
    md = (out / "accuracy-vs-time.md").read_text()
    for b in ("patch", "hertz"):
        assert f"study/pareto_{b}.png" in md
        png = out / "study" / f"pareto_{b}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert {p.name for p in (out / "study").glob("*.png")} == {"pareto_patch.png",
                                                               "pareto_hertz.png"}
    assert "## Headline" in md and "CPU" in md
    # regenerating from the CSV gives the same document
    assert report(out, log=lambda s: None) == md


def test_time_limit_is_recorded_not_fatal(tmp_path):
    """A run stopped at the CPU limit is recorded as 'timeout' and the next one still runs.
    (Hertz at level 3: level 1 finished within 0.5 s CPU with a warm JIT cache on 0.11.)"""
    cases = [Case("hertz", "mortar", "none", "alm", 3), Case("patch", "mortar", "none", "alm", 0)]
    plan = Plan("limit", cases, cpu_limit=0.5, wall_limit=60.0, skip_after=0)
    records = {key(r): r for r in runner.run_cases(plan, jobs=1)}
    slow, fast = records[cases[0].key], records[cases[1].key]
    assert slow["status"] == "timeout" and "time limit" in slow["message"]
    assert slow["err_l2"] in ("", None) or math.isnan(slow["err_l2"])
    assert fast["status"] in ("converged", "timeout")   # it ran (limit 0.5 s may cut it too)


def test_skip_rule_after_two_failures():
    """A combination that failed at the two coarser levels is recorded as skipped. (B3, whose
    load path takes seconds at every level: a warm worker finished Hertz at a/4 and at a/8
    before the pool's first 0.05 s poll saw the 0.01 s limit passed, once in CI each.)"""
    plan = Plan("skip", [Case("half_rings", "mortar", "none", "alm", k) for k in (1, 2, 3)],
                cpu_limit=0.01, wall_limit=60.0)
    records = {r["level"]: r for r in runner.run_cases(plan, jobs=1)}
    assert records[1]["status"] == records[2]["status"] == "timeout"
    labels = ", ".join(cases.LEVELS["half_rings"][k].label for k in (1, 2))
    assert records[3]["status"] == "skipped" and labels in records[3]["message"]


def test_reaction_errors_on_known_curves():
    t = np.array(cases.RINGS_TIMES)
    smooth = [[tk, 3.0 * (tk - 1) ** 2 + tk, -80.0 + (tk - 1) ** 3] for tk in t]
    err, osc = analytics.reaction_errors(smooth, smooth, cases.RINGS_TIMES)
    assert err == 0.0 and osc < 1e-12           # a cubic is its own least-squares cubic
    wiggle = [[tk, rx + (0.4 if k % 2 else -0.4) * (tk > 1), ry]
              for k, (tk, rx, ry) in enumerate(smooth)]
    err, osc = analytics.reaction_errors(wiggle, smooth, cases.RINGS_TIMES)
    scale = max(math.hypot(rx, ry) for _, rx, ry in smooth)
    assert err == pytest.approx(0.4 / scale)
    assert 0.2 / scale < osc < 0.6 / scale      # about the amplitude (the fit absorbs a bit)
    # a curve that stops early has no error (NaN), not a wrong one
    err, osc = analytics.reaction_errors(smooth[:5], smooth, cases.RINGS_TIMES)
    assert math.isnan(err) and math.isnan(osc)


def test_pareto_front_and_budget():
    pts = [(1.0, 0.5), (2.0, 0.6), (3.0, 0.1), (0.5, 0.9), (4.0, 0.1)]
    assert plots.pareto_front(pts) == [(0.5, 0.9), (1.0, 0.5), (3.0, 0.1)]
    rows = [dict(status="converged", cpu_time=t, err_l2=e) for t, e in pts]
    rows.append(dict(status="failed", cpu_time=0.1, err_l2=0.0))
    assert best_within(rows, "err_l2", 2.5)["err_l2"] == 0.5
    assert best_within(rows, "err_l2", 0.2) is None


def test_hertz_constants_match_the_demo():
    spec = importlib.util.spec_from_file_location("demo_hertz", ROOT / "demos" / "demo_hertz.py")
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    assert analytics.HERTZ_A == pytest.approx(demo.a, rel=1e-12)
    assert analytics.HERTZ_P0 == pytest.approx(demo.p0, rel=1e-12)


def test_scene_of_a_case():
    s = scenes.make_scene(Case("hertz_mc", "nts", "hermite", "penalty-100", 2))
    pair = s.contacts[0]
    assert (pair.slave, pair.master) == ("block_top", "disk_arc")
    assert (pair.method, pair.smoothing, pair.enforcement.type) == ("nts", "hermite", "penalty")
    h = cases.LEVELS["hertz_mc"][2].h
    assert h == pytest.approx(analytics.HERTZ_A / 8)
    assert pair.enforcement.epsilon == pytest.approx(100 * 1000.0 / h)
    assert s.mesh.params["h_contact"] == pytest.approx(h)
    r = scenes.make_scene(Case("half_rings", "mortar", "none", "alm", 0))
    assert r.steps.targets() == cases.RINGS_TIMES and r.output.xdmf is False
    assert r.contacts[0].enforcement.epsilon is None       # ALM: the package's default start


def test_full_plan_is_the_documented_matrix():
    plan = cases.full_plan()
    keys = {c.key for c in plan.cases}
    assert len(keys) == len(plan.cases)
    for b in cases.BENCHMARKS:
        for m in cases.METHODS:
            for s in cases.SMOOTHINGS:
                for e in cases.ENFORCEMENTS:
                    lv = [k for k in cases.MATRIX_LEVELS[b] if (b, m, s, e, k) in keys]
                    assert lv == ([0] if s == "averaged-tangent" else [0, 1, 2, 3])
    assert plan.reference == Case(*cases.RINGS_REFERENCE) and plan.reference.key in keys


def test_cli_has_study():
    r = run_cli("study", "--help", timeout=60)
    assert r.returncode == 0 and "--quick" in r.stdout and "--out" in r.stdout
