"""Success criteria (issue 24 item 4): each criterion's evaluation against closed forms on records
built by hand, and a registered controller without a funnel through every command (run, plot,
sweep, capability), whose outputs carry its own criterion and none of the paper's words.

References: the constructed records' errors are chosen so that the violations, the first violation
time and the largest errors follow by hand (a constant error, an error t / 8 crossing 1 at t = 8 s
on a grid of 1/8 s, an offset along and across a reference at 30 deg); the end-to-end runs are
checked against a direct :func:`usv_mj.simulate` of the same scenario and the outcome the PD law's
geometry forces (a 3 m start offset it has no way to correct breaks a 1.5 m tolerance).
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from usv_mj.record.criteria import (FunnelCriterion, NotJudged, PathTolerance, PoseTolerance, criterion_from_dict,
                             criterion_of, criterion_of_record)
from usv_mj.core.errors import ScenarioError
from usv_mj.record.run_record import RunRecord

DT = 0.125  # s: a binary fraction, so that t = k DT and t / 8 are exact
PAPER_WORDS = re.compile(r"funnel|rbf|weight norm|network weight", re.IGNORECASE)


def _record(ex, ey=None, epsi=None, n=129, status="completed", heading_deg=0.0, speed=0.5, extra=None):
    """A record of n rows at DT whose reference moves at ``speed`` [m/s] toward ``heading_deg`` and
    whose pose is the reference plus the errors (callables of t, or constants)."""
    t = np.arange(n) * DT
    f = (lambda v: (v(t) if callable(v) else np.full(n, 0.0 if v is None else float(v))))
    h = math.radians(heading_deg)
    xd, yd = speed * t * math.cos(h), speed * t * math.sin(h)
    cols = {"t": t, "x_d": xd, "y_d": yd, "psi_d": np.full(n, h), "x_d_dot": np.full(n, speed * math.cos(h)),
            "y_d_dot": np.full(n, speed * math.sin(h)), "x": xd + f(ex), "y": yd + f(ey), "psi": h + f(epsi)}
    cols.update(extra or {})
    return RunRecord.from_arrays(cols, status=status)


# --- evaluate against closed forms ----------------------------------------------------------------


def test_pose_tolerance_constant_errors_and_the_settling_window():
    c = PoseTolerance(settle_time_s=2.0, position_m=1.0, heading_deg=10.0)
    judged = int(np.sum(np.arange(129) * DT >= 2.0))  # 16 s of rows, from t = 2 s on: 113
    assert judged == 113
    ok = c.evaluate(_record(0.6, 0.9))  # |p - p_d| = 1.08 m
    assert ok["passed"] is False and ok["violations"] == judged and ok["first_violation_s"] == 2.0
    ok = c.evaluate(_record(0.3, 0.4, math.radians(9.0)))  # 0.5 m, 9 deg
    assert ok["passed"] is True and ok["violations"] == 0 and ok["first_violation_s"] is None
    assert ok["max_position_error_m"] == pytest.approx(0.5) and ok["max_heading_error_rad"] == pytest.approx(
        math.radians(9.0))
    assert ok["judged_steps"] == judged and ok["kind"] == "pose_tolerance"
    # a heading error of 2 pi + 0.05 rad is 0.05 rad (wrapped)
    assert c.evaluate(_record(0.0, 0.0, 2 * math.pi + 0.05))["passed"] is True
    assert c.evaluate(_record(0.0, 0.0, math.radians(10.5)))["violations"] == judged
    # a large error before the settling time is not judged
    assert c.evaluate(_record(lambda t: np.where(t < 2.0, 50.0, 0.1)))["passed"] is True


def test_pose_tolerance_error_crossing_the_bound_at_a_known_time():
    c = PoseTolerance(settle_time_s=0.0, position_m=1.0, heading_deg=10.0)
    r = c.evaluate(_record(lambda t: t / 8.0))  # |x - x_d| = t / 8 reaches 1 m at t = 8 s
    assert r["first_violation_s"] == 8.0
    assert r["violations"] == 129 - 64  # rows k = 64 .. 128
    assert r["passed"] is False and r["max_position_error_m"] == pytest.approx(2.0)


def test_a_run_that_stopped_early_or_ends_before_the_settling_time_is_not_passed():
    c = PoseTolerance(settle_time_s=2.0, position_m=1.0)
    assert c.evaluate(_record(0.1, status="diverged"))["passed"] is None  # no violation, but not finished
    assert c.evaluate(_record(5.0, status="diverged"))["passed"] is False  # broken before it stopped
    short = c.evaluate(_record(0.1, n=10))  # ends at 1.125 s
    assert short["passed"] is None and short["judged_steps"] == 0 and short["max_position_error_m"] is None
    nan = c.evaluate(_record(lambda t: np.where(t > 4.0, np.nan, 0.0)))  # a non-finite error breaks it
    assert nan["passed"] is False and nan["first_violation_s"] == 4.125
    json.dumps(nan, allow_nan=False)  # JSON-ready: no NaN, no inf


def test_path_tolerance_splits_the_offset_along_and_across_the_reference_course():
    h = math.radians(30.0)
    a, c = 2.0, 0.7  # ahead of the reference point by a, left of the path by c
    ex, ey = a * math.cos(h) - c * math.sin(h), a * math.sin(h) + c * math.cos(h)
    for speed in (0.5, 0.0):  # a still reference: its course is psi_d (= 30 deg here)
        rec = _record(ex, ey, heading_deg=30.0, speed=speed)
        r = PathTolerance(settle_time_s=0.0, cross_track_m=1.0).evaluate(rec)
        assert r["passed"] is True and r["max_cross_track_m"] == pytest.approx(c)
        assert r["max_along_track_m"] == pytest.approx(a)
        assert r["params"]["along_track_m"] is None  # inf: not judged, JSON null
        r = PathTolerance(settle_time_s=0.0, cross_track_m=1.0, along_track_m=1.5).evaluate(rec)
        assert r["passed"] is False and r["violations"] == 129
        assert PathTolerance(settle_time_s=0.0, cross_track_m=0.5).evaluate(rec)["violations"] == 129
    # the sign: right of a path going +x is a negative cross-track error, beyond the bound when > 1 m
    rec = _record(0.0, lambda t: -t / 8.0)
    r = PathTolerance(settle_time_s=0.0, cross_track_m=1.0).evaluate(rec)
    assert r["first_violation_s"] == 8.0 and r["max_cross_track_m"] == pytest.approx(2.0)
    assert PathTolerance().errors(rec)["cross"][-1] == pytest.approx(-2.0)


def test_funnel_counts_every_step_with_a_normalized_error_at_or_beyond_one():
    t = np.arange(129) * DT
    z = {"e1": t, "e2": 0 * t, "e3": 0 * t, "rho1": 1 + 0 * t, "rho2": 1 + 0 * t, "rho3": 1 + 0 * t,
         "z1": t / 8.0, "z2": 0 * t, "z3": -t / 32.0}
    r = FunnelCriterion().evaluate(_record(0.0, extra=z))
    assert r["first_violation_s"] == 8.0 and r["violations"] == 129 - 64 and r["passed"] is False
    z["z1"] = 0.5 + 0 * t
    assert FunnelCriterion().evaluate(_record(0.0, extra=z))["passed"] is True
    with pytest.raises(ScenarioError, match="no funnel columns"):
        FunnelCriterion().evaluate(_record(0.0))


def test_not_judged_and_the_round_trip_through_metadata_and_json():
    r = NotJudged("turning circle").evaluate(_record(3.0))
    assert r["passed"] is None and r["violations"] is None and "turning circle" in r["description"]
    for c in (FunnelCriterion(), PoseTolerance(3.0, 0.5, 4.0), PathTolerance(1.0, 0.3), NotJudged("zig-zag")):
        assert criterion_from_dict(c.to_dict()) == c
        assert criterion_from_dict(json.loads(json.dumps({"kind": c.kind, **c.evaluate(
            _record(0.0, extra=({f"z{i}": np.zeros(129) for i in (1, 2, 3)}))).get("params", {})}))) == c
    with pytest.raises(ScenarioError, match="unknown success criterion"):
        criterion_from_dict({"kind": "vibes"})
    with pytest.raises(ScenarioError, match="position_m"):
        PoseTolerance(position_m=float("nan"))
    # an old log: no criterion in the metadata; the funnel columns decide
    funnel_cols = {f: np.zeros(129) for f in ("e1", "e2", "e3", "rho1", "rho2", "rho3", "z1", "z2", "z3")}
    assert criterion_of_record(_record(0.0, extra=funnel_cols)) == FunnelCriterion()
    assert criterion_of_record(_record(0.0)) == PoseTolerance()
    rec = _record(0.0)
    rec.metadata["criterion"] = PathTolerance(2.0, 0.4).to_dict()
    assert criterion_of_record(rec) == PathTolerance(2.0, 0.4)


def test_what_the_built_in_controllers_declare():
    from usv_mj.builder import make_controller
    from usv_mj import load_scenario

    sc = load_scenario(preset="paper")
    assert criterion_of(make_controller(sc, "ppc")) == FunnelCriterion()
    assert criterion_of(make_controller(sc, "pi")) == FunnelCriterion()  # judged as the paper compares it

    class Bad:
        name, criterion = "bad", object()

    with pytest.raises(ScenarioError, match="has no kind, describe, to_dict, evaluate"):
        criterion_of(Bad())

    class NoFunnel:
        name, diagnostic_fields, criterion = "no-funnel", ("e1",), FunnelCriterion()

    with pytest.raises(ScenarioError, match="declares the funnel criterion but not the funnel fields"):
        criterion_of(NoFunnel())


# --- a registered PD law with a pose tolerance, through every command ------------------------------


PD_CRITERION = PoseTolerance(settle_time_s=5.0, position_m=1.5, heading_deg=10.0)


class PDTest:
    """A PD law on the heading and a P law on the speed, corrected by the along-track error; it has no
    way to correct a sideways offset. No funnel, no network: judged by :data:`PD_CRITERION`."""

    name = "pd-test"
    diagnostic_fields = ("heading_error",)
    criterion = PD_CRITERION

    @classmethod
    def from_scenario(cls, gains, scenario):
        return cls()

    def __init__(self):
        self.diag = np.zeros(1)

    def reset(self):
        self.diag[:] = 0.0

    def __call__(self, t, x, ref):
        c, s = math.cos(ref[2]), math.sin(ref[2])
        along = c * (x[0] - ref[0]) + s * (x[1] - ref[1])
        e = math.remainder(x[2] - ref[2], 2 * math.pi)
        self.diag[0] = e
        return 150.0 * (ref[6] - 0.5 * along - x[3]), -60.0 * e - 40.0 * (x[5] - ref[5]), self.diag


SCENARIO = """preset = "paper"
duration = 12.0

[plant]
kind = "analytic"

[controller]
kind = "pd-test"

[trajectory]
kind = "line"
heading_deg = 0.0

[initial]
eta = [0.0, 0.0, 0.0]

[disturbance]
scale = 0.0
"""


@pytest.fixture(scope="module")
def pd_kind():
    from usv_mj import CONTROLLERS

    CONTROLLERS.register("pd-test")(PDTest)
    try:
        yield "pd-test"
    finally:
        CONTROLLERS.unregister("pd-test")


@pytest.fixture(scope="module")
def scheduler(pd_kind):
    """An in-process Dask cluster (threads): its workers see the controller registered here."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        yield cluster.scheduler_address


def _no_paper_words(text: str, where: str):
    found = sorted(set(m.group(0).lower() for m in PAPER_WORDS.finditer(text)))
    assert not found, f"{where} says {found}"


def test_run_and_plot_speak_in_the_controllers_criterion(tmp_path, pd_kind, capsys):
    from usv_mj import load_scenario, simulate, summarize
    from usv_mj.cli.main import main

    scen = tmp_path / "pd.toml"
    scen.write_text(SCENARIO)
    direct = summarize(simulate(load_scenario(scen)))
    assert direct["criterion"]["passed"] is True  # the PD law settles inside 1.5 m (its lag is about 0.7 m)
    assert 0.5 < direct["criterion"]["max_position_error_m"] < 1.5
    out = tmp_path / "run"
    assert main(["run", "--scenario", str(scen), "--no-video", "-q", "--out", str(out)]) == 0
    console = capsys.readouterr().out
    desc = PD_CRITERION.describe()
    assert f"criterion: {desc}: passed" in console
    assert "PI baseline: completed, " in console
    s = json.loads((out / "summary.json").read_text())
    assert s["criterion"]["kind"] == "pose_tolerance" and s["criterion"]["passed"] is True
    assert s["criterion"]["description"] == desc
    assert s["criterion"]["max_position_error_m"] == pytest.approx(direct["criterion"]["max_position_error_m"])
    assert "funnel_violations" not in s and "first_violation_s" not in s
    assert s["baseline"]["criterion"]["kind"] == "pose_tolerance"  # the PI baseline judged as this run
    report = (out / "report.md").read_text()
    assert desc in report and "Outcome: **passed**" in report
    assert sorted(p.name for p in (out / "figures").glob("fig*.png")) == [
        "fig1_trajectory.png", "fig2_error_x.png", "fig3_error_y.png", "fig4_error_psi.png",
        "fig5_tau_u.png", "fig6_tau_r.png", "fig7_weights.png"]
    assert "Position error x - x_d with the position tolerance" in report
    for text, where in ((console, "the console"), (report, "report.md"), (json.dumps(s), "summary.json")):
        _no_paper_words(text, where)

    again = tmp_path / "plot"  # from the log alone: the same criterion, the same words
    assert main(["plot", str(out / "run.mcap"), "--out", str(again)]) == 0
    replot = (again / "report.md").read_text()
    assert desc in replot and "Outcome: **passed**" in replot
    _no_paper_words(replot, "plot's report.md")
    assert len(list((again / "figures").glob("fig*.png"))) == 7


def test_sweep_and_capability_use_the_criterion(tmp_path, pd_kind, scheduler, capsys):
    from usv_mj.cli.main import main
    from usv_mj.jobs.sweep.runner import read_results

    scen = tmp_path / "pd.toml"
    scen.write_text(SCENARIO)
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(f'name = "pd"\nbase = "{scen}"\ntransient = 5.0\n\n[vary]\n"initial.eta[1]" = [0.0, 3.0]\n')
    out = tmp_path / "sweep"
    assert main(["sweep", str(sweep), "--out", str(out), "--scheduler", scheduler, "--no-progress"]) == 0
    console = capsys.readouterr().out
    desc = PD_CRITERION.describe()
    assert f"1 of 2 passed: {desc}" in console  # the 3 m sideways start is never corrected
    rows, _ = read_results(out / "results.parquet")
    assert [r["passed"] for r in rows] == [True, False]
    assert [r["criterion.kind"] for r in rows] == ["pose_tolerance"] * 2
    assert rows[1]["criterion.first_violation_s"] == pytest.approx(5.0)  # off by 3 m from the start
    report = (out / "report.md").read_text()
    assert f"1 of 2 passed: {desc}" in report
    _no_paper_words(report, "the sweep's report.md")
    _no_paper_words(console, "the sweep's console")

    cap = tmp_path / "cap"
    assert main(["capability", "--load", "disturbance", "--base", str(scen), "--min", "1e-6", "--max", "1e-3",
                 "--tol", "0.6", "--scheduler", scheduler, "--no-progress", "--out", str(cap)]) == 0
    console = capsys.readouterr().out
    md = (cap / "capability.md").read_text()
    data = json.loads((cap / "capability.json").read_text())
    assert data["criterion"] == {"kind": "pose_tolerance", "description": desc}
    assert desc in md and "pose tolerance holds up to" in md and "pose tolerance holds up to" in console
    (res,) = data["results"]
    held = [r["load"] for r in data["runs"] if r["passed"]]
    lost = [r["load"] for r in data["runs"] if not r["passed"]]
    assert res["holds"] == max(held) and res["fails"] == min(lost) and res["fails"] <= res["holds"] / 0.4
    # the bracket checked by direct runs: the PD law has no integral action against d(t)
    from usv_mj import load_scenario, simulate, summarize

    for scale, passed in ((res["holds"], True), (res["fails"], False)):
        sc = load_scenario(scen, overrides={"disturbance": {"scale": scale}})
        assert summarize(simulate(sc))["criterion"]["passed"] is passed
    for text, where in ((md, "capability.md"), (console, "the capability console")):
        _no_paper_words(text, where)


def test_paper_words_stay_for_the_paper_controller():
    """The funnel controller's outputs keep the paper's wording (the check above is not vacuous)."""
    from usv_mj.outputs.figures import FIGURES, figure_titles
    from usv_mj.record.summary import criterion_line

    assert figure_titles("funnel", True) == FIGURES
    assert "funnel" in figure_titles("funnel", True)["fig2_error_x.png"]
    line = criterion_line({"funnel_violations": 0, "first_violation_s": None, "s2_clamps": 0,
                           "quantizer_switches": {"u": 1, "r": 2}, "criterion": {}})
    assert line == "  funnel violations: 0 steps; s2 clamps: 0; quantizer switches: u 1, r 2"
    assert not any(PAPER_WORDS.search(t) for t in figure_titles("pose_tolerance", False).values())


@pytest.mark.parametrize("criterion", [PathTolerance(settle_time_s=5.0, cross_track_m=1.0),
                                       NotJudged("open-loop test input")], ids=["path", "not_judged"])
def test_path_and_not_judged_outputs(tmp_path, pd_kind, criterion, monkeypatch):
    """The other two criteria through the summary, figures, report and a sweep row (in-process)."""
    from usv_mj import load_scenario, simulate, summarize
    from usv_mj.outputs.figures import draw_figures
    from usv_mj.outputs.report import write_report
    from usv_mj.jobs.sweep.runner import run_one

    scen = tmp_path / "pd.toml"
    scen.write_text(SCENARIO)
    sc = load_scenario(scen)
    law = PDTest()
    law.criterion = criterion
    rec = simulate(sc, controller=law)
    assert rec.metadata["criterion"] == criterion.to_dict()
    s = summarize(rec)
    text = json.dumps(s, allow_nan=False)  # summary.json: an infinite along-track bound is null
    block = s["criterion"]
    assert block["kind"] == criterion.kind and block["description"] == criterion.describe()
    if criterion.kind == "path_tolerance":
        # on a line along +x the cross-track error is y - y_d and the along-track one x - x_d
        assert block["passed"] is True
        after = rec["t"] >= 5.0
        assert block["max_cross_track_m"] == pytest.approx(np.max(np.abs(rec["y"] - rec["y_d"])[after]))
        assert block["max_along_track_m"] == pytest.approx(np.max(np.abs(rec["x"] - rec["x_d"])[after]))
    else:
        assert block["passed"] is None and block["violations"] is None
    draw_figures(rec, tmp_path / "figures")
    assert len(list((tmp_path / "figures").glob("fig*.png"))) == 7
    report = write_report(tmp_path / "report.md", s).read_text()
    assert criterion.describe() in report
    for t, where in ((report, "report.md"), (text, "summary.json")):
        _no_paper_words(t, where)
    # a sweep row of the kind declaring it: passed only when judged and kept (a run not judged never passes)
    monkeypatch.setattr(PDTest, "criterion", criterion)
    row = run_one(0, sc, {})
    assert row["criterion.kind"] == criterion.kind and row["passed"] is (criterion.kind == "path_tolerance")


def test_capability_refuses_a_controller_whose_runs_are_not_judged(tmp_path, pd_kind, monkeypatch):
    from usv_mj.jobs.sweep import SweepError
    from usv_mj.jobs.sweep.capability import run_capability

    scen = tmp_path / "pd.toml"
    scen.write_text(SCENARIO)
    monkeypatch.setattr(PDTest, "criterion", NotJudged("open-loop test input"))
    with pytest.raises(SweepError, match="not judged \\(open-loop test input\\): there is no criterion"):
        run_capability("disturbance", base=str(scen), out=tmp_path / "cap", progress=False, echo=None)


def test_compare_judges_the_closed_loop_by_the_controllers_criterion(tmp_path, pd_kind):
    """compare's closed loop with the PD law: both plants pass its pose tolerance (their difference is
    far below it), and compare.json's keys say the criterion, not the funnel."""
    from usv_mj import load_scenario
    from usv_mj.jobs.compare import compare_closed_loop

    scen = tmp_path / "pd.toml"
    scen.write_text(SCENARIO)
    result, _ = compare_closed_loop(load_scenario(scen, overrides={"duration": 6.0}), progress=False)
    assert result["passed_criterion"] == {"analytic": True, "mujoco": True}
    assert result["criterion"] == PD_CRITERION.describe()
    assert "inside_funnels" not in result and "max_abs_z" not in result
    assert result["max_position_m"] < 1e-3


def test_video_hud_of_a_run_without_a_funnel_shows_pose_errors_and_no_funnel(tmp_path, pd_kind):
    """The video's planner and overlay (no OpenGL needed): pose errors in the HUD, no funnel legend entry."""
    from usv_mj import load_scenario, simulate
    from usv_mj.outputs.render.overlay import draw_hud
    from usv_mj.outputs.render.planner import plan_frames

    scen = tmp_path / "pd.toml"
    scen.write_text(SCENARIO)
    rec = simulate(load_scenario(scen, overrides={"duration": 2.0, "initial": {"eta": [0.5, -0.3, 0.2]}}))
    frames = plan_frames(rec, fps=5, speedup=1.0, width=160, height=120).frames
    for f in frames:
        k = int(np.argmin(np.abs(rec["t"] - f.t)))
        assert f.hud["funnel"] is False
        assert f.hud["e"][0] == pytest.approx(rec["x"][k] - rec["x_d"][k])
        assert f.hud["e"][1] == pytest.approx(rec["y"][k] - rec["y_d"][k])
        assert not math.isfinite(f.funnel_half[0])  # no funnel box in the 3-D scene

    def legend_rows(funnel):  # rows of a white frame that the legend panel darkened
        frame = np.full((720, 1280, 3), 255, np.uint8)
        draw_hud(frame, {"funnel": funnel}, hud=False, legend=True)
        return int(np.sum(frame[:, 20, 0] < 255))

    assert legend_rows(True) - legend_rows(False) == 22  # one entry (22 px at 720 px) fewer
