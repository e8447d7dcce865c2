"""Issue 38, cause 20: words that misled. Each test builds the case of the issue and checks that
the message names the real cause (the value, the place, the plug-in) and that nothing true is
hidden behind a consequence."""

from __future__ import annotations

import json
import sys
import textwrap
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import usv_mj
from usv_mj.core.errors import PluginWarning, ScenarioError, SweepError
from usv_mj.scenario.spec import load_scenario

ROOT = Path(__file__).resolve().parents[1]


# --- MuJoCo's reason kept (vessel.m = 1e-30) ---------------------------------------------------------


def test_a_multi_line_reason_is_kept_whole():
    from usv_mj.jobs.run import _one_line

    exc = ValueError("Error: mass and inertia of moving bodies must be larger than mjMINVAL\n"
                     "Element name 'hull', id 1, line 54")
    assert _one_line(exc) == ("ValueError: Error: mass and inertia of moving bodies must be larger than mjMINVAL; "
                              "Element name 'hull', id 1, line 54")


def test_a_massless_hull_on_mujoco_says_why(tmp_path):
    from usv_mj.jobs.run import RunFailed, run_job

    sc = load_scenario(preset="paper", overrides={"duration": 0.1, "baseline": {"enabled": False},
                                                  "vessel": {"kind": "otter", "m": 1e-30}})
    with pytest.raises(RunFailed, match="mass and inertia of moving bodies must be larger than mjMINVAL; "
                                        "Element name 'hull'"):
        run_job(sc, tmp_path / "o", plant_kind="mujoco", video=False, progress=False, step_check=False)


# --- a vessel data file's [manoeuvre] value is the file's, not a --set's -------------------------------


def _bad_boat(tmp_path) -> Path:
    text = (ROOT / "usv_mj" / "vessels" / "data" / "otter.toml").read_text()
    assert "yaw_moment = 19.264" in text
    path = tmp_path / "boat.toml"
    path.write_text(text.replace("yaw_moment = 19.264", "yaw_moment = -19.264"))
    return path


def test_a_bad_manoeuvre_default_of_a_data_file_names_the_vessel(tmp_path, capsys):
    from usv_mj.cli.main import main
    from usv_mj.core.registry import VESSELS
    from usv_mj.scenario.manoeuvre import manoeuvre_from_table

    path = _bad_boat(tmp_path)
    try:
        sc = load_scenario(preset="paper", overrides={"vessel": {"kind": str(path)}})
        with pytest.raises(ScenarioError, match=rf"^vessel '{path}': its own \[manoeuvre\] defaults \(yaw_moment = "
                                                rf"-19.264, from its data file\) do not fit the turning: "
                                                rf"manoeuvre.yaw_moment must be > 0, got -19.264$"):
            manoeuvre_from_table({"kind": "turning"}, "x.toml", sc.vessel)
        # the table's own value wins, and then it runs
        assert manoeuvre_from_table({"kind": "turning", "yaw_moment": 5.0}, "x.toml", sc.vessel).yaw_moment == 5.0
        out = tmp_path / "o"
        assert main(["manoeuvre", "turning", "--vessel", str(path), "--plant", "analytic", "--out", str(out),
                     "-q"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith(f"usv-mj manoeuvre: error: vessel '{path}': its own [manoeuvre] defaults"), err
        assert "--set" not in err and not out.exists()
    finally:
        VESSELS.unregister(str(path))


# --- commands = "bogus" is not a rudder controller ------------------------------------------------------


def test_an_unknown_commands_word_is_named():
    from usv_mj.builder import commands_error

    sc = load_scenario(preset="paper")
    problem = commands_error(sc, SimpleNamespace(commands="bogus"), "mine")
    # the word is named with the ones the contract has (usv_mj.physics.channels.run_channels)
    assert problem == ("the 'mine' controller cannot drive the vessel: a controller's commands must be one of "
                       "'forces', 'any', 'rudder', got 'bogus'")
    assert "n_P and a rudder angle, but the vessel" not in problem


# --- a bench policy that does not exist is refused when planned ---------------------------------------


def test_a_missing_policy_is_refused_at_plan(tmp_path):
    from usv_mj.jobs.bench.suite import plan_suite

    with pytest.raises(SweepError, match=rf"controllers\[1\] \('ppo'\): policy file '{tmp_path}/nope.zip' "
                                         rf"does not exist"):
        plan_suite({"controllers": ["los", {"name": "ppo", "policy": "nope.zip"}],
                    "tasks": [{"name": "a", "duration": 2.0}]}, str(tmp_path / "s.toml"), tmp_path)
    with pytest.raises(SweepError, match=r"policy 'no_such_module_x:act': no module 'no_such_module_x'"):
        plan_suite({"controllers": ["los", {"name": "p", "policy": "no_such_module_x:act"}],
                    "tasks": [{"name": "a", "duration": 2.0}]})


# --- entry points: shadowed by a built-in, or declared twice; printing at import -----------------------


class _Dist:
    def __init__(self, name):
        self.name, self.version = name, "1.0"


class _EP:
    def __init__(self, name, value, dist, group="usv_mj.test"):
        self.name, self.value, self.group, self.dist = name, value, group, _Dist(dist)

    def load(self):
        import importlib

        module, _, attr = self.value.partition(":")
        return getattr(importlib.import_module(module), attr)


def test_entry_points_that_are_not_used_say_so(monkeypatch):
    import importlib.metadata

    from usv_mj.core.registry import Registry

    eps = [_EP("ppc", "x:Y", "shadow"), _EP("mine", "usv_mj.controllers.los:LOSController", "first"),
           _EP("mine", "other:Z", "second")]
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda group: [e for e in eps if e.group == group])
    from usv_mj.core.errors import UnknownKindError

    reg = Registry("controller", {"ppc": "usv_mj.controllers.ppc"}, "usv_mj.test")
    with pytest.warns(PluginWarning, match=r"controller kind 'ppc' is built in: the entry point 'ppc' of the group "
                                           r"usv_mj.test \(dist shadow 1.0\) is not used; give it another name"):
        with pytest.raises(UnknownKindError):    # this test registry's built-in module registers elsewhere
            reg.get("ppc")
    with pytest.warns(PluginWarning, match=r"controller kind 'mine': 2 distributions declare the entry point \(dist "
                                           r"first 1.0, dist second 1.0\); the first on sys.path is used \(dist first "
                                           r"1.0: usv_mj.controllers.los:LOSController\)"):
        reg.get("mine")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        reg.get("mine")                                # once per kind
    assert len(reg.notes()) == 2


def test_a_plugin_printing_at_import_leaves_kinds_json_whole(tmp_path, monkeypatch, capsys):
    from usv_mj.cli.main import main
    from usv_mj.core.registry import CONTROLLERS

    (tmp_path / "noisy_plugin.py").write_text(textwrap.dedent('''
        print("hello from the noisy plug-in")
        from usv_mj.controllers.los import LOSController, LOSGains


        class Noisy(LOSController):
            options = LOSGains
    '''))
    monkeypatch.syspath_prepend(str(tmp_path))
    sys.modules.pop("noisy_plugin", None)
    eps = dict(CONTROLLERS._eps())
    eps["noisy"] = _EP("noisy", "noisy_plugin:Noisy", "noisy", "usv_mj.controllers")
    monkeypatch.setattr(CONTROLLERS, "_entry_points", eps)
    try:
        capsys.readouterr()
        assert main(["kinds", "controller", "--json"]) == 0
        out, err = capsys.readouterr()
        table = json.loads(out)
        assert "noisy" in [k["kind"] for k in table["controller"]["kinds"]]
        assert "hello from the noisy plug-in" in err
    finally:
        CONTROLLERS.unregister("noisy")
        sys.modules.pop("noisy_plugin", None)


# --- the spiral's rudder on a ruddered vessel; a single-controller bench --------------------------------


def test_a_ruddered_spiral_is_labelled_by_its_rudder_angle():
    from usv_mj.jobs.manoeuvres.fleet import rudder_label
    from usv_mj.physics.channels import RUDDER_ANGLE

    o = {"max_rudder_deg": 20.0, "max_yaw_moment": 10.0, "steps": 5}
    rudder = RUDDER_ANGLE.to_metadata()   # the result's "rudder_channel" (usv_mj.jobs.manoeuvres.measure)
    assert rudder_label({"kind": "spiral", "rudder_channel": rudder, "options": o}) == "+-20 deg rudder"


def test_a_single_controller_bench_says_there_is_no_ranking(tmp_path):
    from usv_mj.jobs.bench.report import printed_leaderboard, write_report, aggregate

    rows = [{"run_id": i, "vary.task": "t", "vary.condition": "calm", "vary.vessel": "default",
             "vary.controller": "los", "vary.episode": i, "status": "ok", "m.iae_cross_track": 1.0 + i}
            for i in range(2)]
    lines = printed_leaderboard(aggregate(rows), ["los"], False)
    assert lines == ["The suite scores one controller (`los`): a ranking compares two or more, so there is none; "
                     "its metrics are in the tables of each task (report.md, leaderboard.json)."]
    suite = SimpleNamespace(controllers=[SimpleNamespace(name="los")], vessels=[""], episodes={"t": 2}, name="s",
                            source="s.toml", tasks=["t"], conditions=["calm"], skipped=[])
    text = write_report(tmp_path, rows, suite, draw=False).read_text()
    assert "| rank |" not in text and "| task |" not in text


# --- the obstacle and the file of a start or goal inside an inflated obstacle ---------------------------


def test_a_goal_inside_an_inflated_obstacle_names_it_and_the_file():
    from usv_mj.jobs.preflight import check_plan

    path = ROOT / "examples" / "scenarios" / "harbour_gap.toml"
    sc = load_scenario(path, overrides={"trajectory": {"points": [[0.0, 0.0], [14.0, 2.0]]}})
    with pytest.raises(ScenarioError, match=rf"^{path}: guidance: the goal point \(14.00, 2.00\) m lies inside an "
                                            rf"inflated obstacle, obstacles\[1\] \(pier_north\), grown by \d+\.\d\d m"):
        check_plan(sc)


# --- the stopping test's stop speed; --vessel all ---------------------------------------------------------


def test_a_stop_speed_over_the_approach_is_refused():
    from usv_mj.scenario.manoeuvre import StoppingOptions

    with pytest.raises(ScenarioError, match=r"manoeuvre.stop_speed = 0.7 m/s must be below manoeuvre.approach_speed "
                                            r"= 0.6 m/s"):
        StoppingOptions(stop_speed=0.7)


def test_every_vessel_runs_the_stopping_test_that_can(tmp_path):
    from usv_mj.jobs.manoeuvres.fleet import run_fleet

    def scenario_for(vessel):
        return load_scenario(preset="paper", overrides={
            "vessel": {"kind": vessel}, "manoeuvre": {"kind": "stopping", "duration": 5.5}})

    fleet = run_fleet(scenario_for, ["kvlcc2", "paper"], "stopping", tmp_path / "o", plant_kind="analytic",
                      skip_refused=True)
    assert [r["vessel"] for r in fleet["rows"]] == ["paper"]
    assert fleet["skipped"][0][0] == "kvlcc2" and "not available on the vessel 'kvlcc2'" in fleet["skipped"][0][1]
    assert "kvlcc2" in (tmp_path / "o" / "vessels.md").read_text()
    with pytest.raises(ScenarioError, match="not available on the vessel 'kvlcc2'"):
        run_fleet(scenario_for, ["kvlcc2", "paper"], "stopping", tmp_path / "o2", plant_kind="analytic")


# --- render --out a folder ---------------------------------------------------------------------------------


def test_render_out_may_be_a_folder(tmp_path):
    from usv_mj.outputs.render.video import output_path

    run = tmp_path / "run"
    run.mkdir()
    folder = tmp_path / "videos"
    folder.mkdir()
    assert output_path(str(folder), run, run / "run.mcap") == folder / "run.mp4"
    assert output_path(str(folder), tmp_path / "a.mcap", tmp_path / "a.mcap") == folder / "a.mp4"
    assert output_path(str(tmp_path / "v.mp4"), run, run / "run.mcap") == tmp_path / "v.mp4"
    assert output_path(None, run, run / "run.mcap") == run / "run.mp4"


# --- a reference at 1e308: the divergence, and figures that say they cannot be drawn --------------------


def test_a_reference_near_the_float_range_does_not_hide_the_divergence(tmp_path):
    from usv_mj.jobs.run import run_job

    sc = load_scenario(preset="paper", overrides={"duration": 1.0, "baseline": {"enabled": False},
                                                  "trajectory": {"kind": "line", "start": [1e308, 1e308]}})
    job = run_job(sc, tmp_path / "o", plant_kind="analytic", video=False, progress=False, step_check=False)
    assert job.summary["status"] == "diverged" and "not finite" in job.summary["stop_reason"]
    figures = sorted(p.name for p in (tmp_path / "o" / "figures").glob("*.png"))
    assert len(figures) == 7 and "fig1_trajectory.png" in figures


def test_a_figure_beyond_the_drawable_span_is_a_note(tmp_path):
    from usv_mj.outputs.figures import DRAWABLE, plt, save_figure

    fig, ax = plt.subplots()
    ax.plot([0.0, 1.0], [0.0, 1e308])
    ax.set_title("huge")
    path = tmp_path / "f.png"
    save_figure(fig, path)
    assert path.stat().st_size > 0 and 1e308 > DRAWABLE


# --- a KeyboardInterrupt of a plug-in is not a user's Ctrl-C -------------------------------------------


class _Raising:
    name = "raising"
    diagnostic_fields = ()

    def __init__(self, text):
        self.text = text

    def reset(self):
        pass

    def __call__(self, t, state, ref):
        if t >= 0.01:
            raise KeyboardInterrupt(*([self.text] if self.text else []))
        return 0.0, 0.0, np.zeros(0)


def test_a_plugins_keyboard_interrupt_says_where_it_came_from():
    sc = load_scenario(preset="paper", overrides={"duration": 0.1})
    rec = usv_mj.simulate(sc, plant_kind="analytic", controller=_Raising("from plugin"))
    assert rec.status == "interrupted"
    assert rec.stop_reason.startswith("interrupted by a KeyboardInterrupt raised at test_misleading_words.py:")
    assert "('from plugin'), not a signal at t = 0.010 s" in rec.stop_reason
    bare = usv_mj.simulate(sc, plant_kind="analytic", controller=_Raising(""))
    assert bare.stop_reason == "interrupted by the user (Ctrl-C) at t = 0.010 s"
