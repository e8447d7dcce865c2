"""Several vessels in one sea (issue 35): the [[vessels]] tables, the fleet plants, the loop over
vessels, the contacts between hulls and the fleet's outputs."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from usv_mj import load_scenario, simulate
from usv_mj.core.errors import ScenarioError

NORTH, SOUTH = math.pi / 2, -math.pi / 2
EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "scenarios"


def fleet(plant: str, vessels: list, duration: float = 10.0, **extra):
    return load_scenario(preset="paper", overrides={"duration": duration, "control_period": 0.01,
                                                    "plant": {"kind": plant}, "vessels": vessels, **extra})


APART = [  # two vessels 500 m apart, on parallel courses: they never meet
    {"name": "own", "steer": "keep", "initial": {"eta": [0.0, 0.0, NORTH], "nu": [0.6, 0.0, 0.0]}},
    {"name": "far", "initial": {"eta": [500.0, 0.0, 0.0], "nu": [0.0, 0.0, 0.0]},
     "controller": {"kind": "pi"}, "trajectory": {"kind": "line", "start": [500.0, 0.0], "heading_deg": 0.0}},
]


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_a_vessel_of_a_fleet_runs_as_it_runs_alone(plant):
    """Each vessel's record in the fleet equals its own single run's (its vessel's scenario through
    simulate), column by column: the vessel index is a dimension, not a second model. On MuJoCo the
    fleet's one model holds both hulls (their dofs a block each of the mass matrix, the callback a
    block each of userdata) and the result is still the single plant's."""
    sc = fleet(plant, APART)
    record = simulate(sc)
    assert record.status == "completed" and record.names == ("own", "far") and record.own == "own"
    for v in sc.vessels:
        alone = simulate(v.scenario.with_overrides({"baseline": {"enabled": False}}), loop="python")
        mine = record[v.name]
        assert mine.column_names == alone.column_names
        for c in ("x", "y", "psi", "u", "v", "r", "tau_u", "tau_r", "q_tau_u", "f_u", "f_r"):
            assert np.array_equal(mine[c], alone[c]), (plant, v.name, c)
    assert not record.contact_rows().any()


def test_the_vessels_tables_are_checked_with_the_place_named():
    ok = {"name": "a", "initial": {"eta": [0.0, 0.0, 0.0]}}
    cases = [
        ([ok, dict(ok)], r"vessels\[1\] \(a\): the name 'a' is given twice"),
        ([ok, {"name": "b", "own_ship": True, "initial": {"eta": [9.0, 0, 0]}},
          {"name": "c", "own_ship": True, "initial": {"eta": [19.0, 0, 0]}}], r"own_ship = true on b, c"),
        ([ok, {"name": "b"}], r"vessels\[1\] \(b\): give the vessel's start"),
        ([ok, {"name": "b", "initial": {"eta": [9.0, 0, 0]}, "duration": 5}], r"unknown key 'duration'"),
        ([ok, {"name": "b", "initial": {"eta": [9.0, 0, 0]}, "steer": "drift"}], r"steer must be one of"),
        ([ok, {"name": "b", "initial": {"eta": [9.0, 0, 0]}, "steer": "route"}], r"steer = 'route' needs speed"),
        ([ok, {"name": "b/c", "initial": {"eta": [9.0, 0, 0]}}], r"name must be letters, digits"),
        ([ok, {"name": "b", "initial": {"eta": [9.0, 0, 0]}, "vessel": {"kind": "nope"}}],
         r"vessels\[1\] \(b\).*unknown vessel kind 'nope'"),
        ([ok], r"\[\[vessels\]\] holds 1 vessel\(s\): give two or more"),
        # two paper hulls (L = 1.98 m) 1.5 m apart: closer than 1.98 / 2 + 1.98 / 2 = 1.98 m
        ([ok, {"name": "b", "initial": {"eta": [0.9, 1.2, 0]}}],
         r"vessels 'a' and 'b' start 1.5 m apart, closer than their half-lengths added \(1.98 m\)"),
    ]
    for tables, message in cases:
        with pytest.raises(ScenarioError, match=message):
            fleet("analytic", tables)
    # --set cannot name one table of the list (it was taken for a table of tables, and the file blamed)
    from usv_mj.scenario.overrides import parse_set

    with pytest.raises(ScenarioError, match=r"^--set 'vessels.0.controller.horizon_s=-1': \[\[vessels\]\] is a "
                                            r"list of tables, which --set cannot reach into"):
        parse_set(["vessels.0.controller.horizon_s=-1"])
    assert parse_set(['vessels=[{name = "a"}]']) == {"vessels": [{"name": "a"}]}


def test_route_and_keep_are_los_on_the_vessel_s_path():
    sc = fleet("analytic", [
        {"name": "own", "steer": "keep", "initial": {"eta": [1.0, 2.0, 0.5]}, "speed": 0.8},
        {"name": "r", "steer": "route", "route": [[50.0, 0.0], [50.0, 50.0]], "speed": 0.7,
         "initial": {"eta": [0.0, -20.0, 0.0]}}])
    keep, route = sc.vessels
    assert (keep.scenario.controller.kind, keep.scenario.trajectory.kind) == ("los", "line")
    assert keep.scenario.trajectory.start == (1.0, 2.0)
    assert keep.scenario.trajectory.heading_deg == pytest.approx(math.degrees(0.5))
    assert keep.scenario.trajectory.speed == 0.8
    assert route.scenario.trajectory.points == ((0.0, -20.0), (50.0, 0.0), (50.0, 50.0))
    assert keep.own_ship and not route.own_ship   # the first vessel when none says so


HEAD_ON = [
    {"name": "own", "steer": "keep", "initial": {"eta": [0.0, 0.0, NORTH], "nu": [0.6, 0.0, 0.0]}},
    {"name": "target", "steer": "keep", "initial": {"eta": [0.0, 30.0, SOUTH], "nu": [0.6, 0.0, 0.0]}},
]


def test_head_on_without_avoidance_collides_and_the_contact_is_recorded():
    """Two vessels head-on 30 m apart at 0.6 m/s keep course: they meet after about 25 s. On MuJoCo
    the hulls' collision geoms touch (centres about one hull length apart, 1.98 m for the paper
    hull: bow to bow), a contact force is recorded and a "vessel_contact" event is in both vessels'
    records and the fleet's. On the analytic plant the hulls pass through each other (no contact
    model): the range falls to about 0."""
    m = simulate(fleet("mujoco", HEAD_ON, duration=30.0))
    a = simulate(fleet("analytic", HEAD_ON, duration=30.0))
    rng = lambda r: np.hypot(r["own"]["x"] - r["target"]["x"], r["own"]["y"] - r["target"]["y"])  # noqa: E731
    assert m.contact_rows().max() > 0
    assert 1.5 < rng(m).min() < 2.1          # stopped bow to bow (the paper hull is 1.98 m long)
    assert rng(a).min() < 0.1                # the analytic hulls pass through each other
    kinds = [e.kind for e in m.events]
    assert "vessel_contact" in kinds
    for name in ("own", "target"):
        assert any(e.kind == "vessel_contact" and e.values["pair"] == ["own", "target"] for e in m[name].events)
    first = next(e for e in m.events if e.kind == "vessel_contact")
    # they meet at about (30 - 1.98) / (2 x 0.6) s after a short acceleration: 23-27 s
    assert 20.0 < first.t < 28.0


def test_the_fleet_job_logs_every_vessel_and_the_encounter(tmp_path):
    from usv_mj.jobs.fleet import run_fleet_job
    from usv_mj.outputs.log import read_run

    sc = fleet("analytic", HEAD_ON, duration=5.0)
    result = run_fleet_job(sc, tmp_path / "out", progress=False)
    out = tmp_path / "out"
    assert (out / "run.mcap").is_file() and (out / "vessel-target.mcap").is_file()
    log = read_run(out / "run.mcap")
    assert set(log.runs) == {"main", "target"}
    assert np.array_equal(log.runs["target"]["x"], result.record["target"]["x"])
    assert np.array_equal(log.runs["main"]["y"], result.record["own"]["y"])
    pair = result.summary["encounters"]["pairs"]["own-target"]
    # 30 m apart closing at about 1.2 m/s: after 5 s the range is 30 - (distance covered) (> 25 m)
    assert 20.0 < pair["min_range_m"] < 30.0 and pair["t_min_range_s"] == pytest.approx(5.0)
    assert (out / "figures" / "fleet_tracks.png").is_file() and (out / "report.md").read_text().count("own-target")


def test_the_fleet_video_draws_every_vessel_where_the_record_has_it():
    """The planner puts each other vessel in every frame at its recorded pose (the frame's row), with
    its trail and the own ship's safety domain; the renderer draws its hull in its colour and its name
    where the top camera sees it (a pixel of the target's colour at its projected position)."""
    from usv_mj.outputs.render.planner import VESSEL_RGBA, add_fleet, plan_frames
    from usv_mj.outputs.render.video import render_frames

    record = simulate(fleet("analytic", HEAD_ON, duration=12.0))
    plan = add_fleet(plan_frames(record.own_record, width=320, height=180, max_frames=4), record, 320, 180,
                     domain=5.94)
    for spec, k in zip(plan.frames, plan.rows):
        (name, pose, trail, rgba, size), = spec.others
        assert name == "target" and rgba == VESSEL_RGBA[0] and size == pytest.approx((1.98, 0.76))
        assert pose == (record["target"]["x"][k], record["target"]["y"][k], record["target"]["psi"][k])
        assert spec.domain == 5.94 and spec.own_name == "own"
        v = spec.view     # every vessel inside the top view (half-height vertically, aspect 16:9)
        assert abs(pose[1] - v.cy) < v.half_height and abs(spec.pose[1] - v.cy) < v.half_height
    spec = plan.frames[-1]
    (frame,) = render_frames(record.own_record, rows=[int(plan.rows[-1])], width=320, height=180,
                             layers=("trail",), views=spec.view, fleet=record)
    (_, (x, y, _), _, rgba, _), = spec.others
    scale = 90.0 / spec.view.half_height
    px, py = int(round(160 + (x - spec.view.cx) * scale)), int(round(90 - (y - spec.view.cy) * scale))
    patch = frame[max(0, py - 2):py + 3, max(0, px - 2):px + 3].reshape(-1, 3).astype(float)
    target = np.array(rgba[:3]) * 255
    assert np.min(np.linalg.norm(patch - target, axis=1)) < 90   # lit and shaded, the target's orange


def test_plot_and_render_of_a_fleet_log_redraw_the_fleet(tmp_path, monkeypatch):
    """``usv-mj plot`` and ``usv-mj render`` of a fleet's run.mcap read its companions back as the
    fleet (usv_mj.outputs.log.fleet_log): the fleet's figures and report, and a video handed every
    vessel, from the log alone: the positions equal the simulated record's."""
    from usv_mj.cli.main import main
    from usv_mj.jobs.fleet import run_fleet_job
    from usv_mj.outputs.log import read_run
    from usv_mj.outputs.log.fleet_log import fleet_of_log
    from usv_mj.outputs.render import video

    result = run_fleet_job(fleet("analytic", HEAD_ON, duration=5.0), tmp_path / "run", progress=False, video=False)
    back = fleet_of_log(read_run(tmp_path / "run" / "run.mcap"))
    assert back.names == ("own", "target") and back.own == "own"
    for name in back.names:
        assert np.array_equal(back[name]["x"], result.record[name]["x"])
    assert main(["plot", str(tmp_path / "run"), "--out", str(tmp_path / "again")]) == 0
    assert (tmp_path / "again" / "figures" / "fleet_tracks.png").is_file()
    assert "own-target" in (tmp_path / "again" / "report.md").read_text()
    seen = {}

    def fake_render(record, out, **kw):
        seen.update(kw, own=record.metadata.get("vessel_name"))
        return {"mp4": out, "png": out, "frames": 1, "width": 2, "height": 2, "video_fps": 1.0, "speedup": 1.0,
                "fps": 1.0, "wall_s": 0.0, "workers": 1, "gl": "none", "gl_renderer": ""}

    monkeypatch.setattr(video, "render_run", fake_render)
    assert main(["render", str(tmp_path / "run"), "--out", str(tmp_path / "v.mp4"), "--quiet"]) == 0
    assert seen["own"] == "own" and seen["fleet"].names == ("own", "target")
    assert seen["domain"] == pytest.approx(3 * 1.98)   # the own ship's safety domain: 3 hull lengths


def test_each_contact_is_reported_with_its_own_peak():
    """Two touches, 0.3 s and 0.1 s long, with peaks 500 N then 200 N: the summary lists them apart
    (the second's peak is its own, not the first's), counts 2 and 0.4 s in contact; the report's cell
    says so in one line."""
    from usv_mj.outputs.fleet_report import _contacts
    from usv_mj.record.encounters import encounter_summary

    record = simulate(fleet("analytic", APART, duration=2.0))
    dt = 0.01
    record.contacts[:] = 0.0
    record.contacts[100:130, 0] = np.linspace(100.0, 500.0, 30)      # t = 1.00-1.29 s
    record.contacts[150:160, 0] = 200.0                              # t = 1.50-1.59 s
    pair = encounter_summary(record)["pairs"]["own-far"]
    assert [c["t_s"] for c in pair["contacts"]] == pytest.approx([1.0, 1.5])
    assert [c["max_force_N"] for c in pair["contacts"]] == pytest.approx([500.0, 200.0])
    assert pair["n_contacts"] == 2 and pair["in_contact_s"] == pytest.approx(40 * dt)
    assert _contacts(pair) == "from t = 1.0 s: 2 touches, 0.4 s in all, up to 500 N"


def test_hulls_that_overlap_on_the_analytic_plant_are_a_collision():
    """The analytic plant has no contact model: two hulls closer than their half-lengths added
    (L = 2 m and 4 m: 3 m) overlap, and the encounter counts it as a collision; on MuJoCo the contact
    force decides, so the same ranges are no overlap there."""
    from types import SimpleNamespace

    from usv_mj.record.encounters import hulls_overlap

    def record(plant):
        return SimpleNamespace(names=["own", "t"], metadata={"plant": plant},
                               records={"own": SimpleNamespace(metadata={"length_m": 2.0}),
                                        "t": SimpleNamespace(metadata={"length_m": 4.0})})

    ranges = np.array([10.0, 3.5, 3.0, 2.999, 0.02, 5.0])
    assert hulls_overlap(record("analytic"), 0, 1, ranges).tolist() == [False, False, False, True, True, False]
    assert not hulls_overlap(record("mujoco"), 0, 1, ranges).any()


def test_a_sweep_of_a_fleet_is_refused_not_run_as_one_vessel(tmp_path):
    from usv_mj.core.errors import SweepError
    from usv_mj.jobs.sweep.spec import load_sweep

    path = tmp_path / "s.toml"
    path.write_text(f'base = "{EXAMPLES / "head_on_colav.toml"}"\nsamples = 2\n'
                    '[vary]\n"sea.current.speed" = {{ uniform = [0.0, 0.2] }}\n'.replace("{{", "{").replace("}}", "}"))
    with pytest.raises(SweepError, match=r"has \[\[vessels\]\] \(2 vessels\): a sweep runs one vessel per run"):
        load_sweep(path)
