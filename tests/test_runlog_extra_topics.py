"""The run log's per-step obstacle and environment topics (issues 7 and 8; usv_mj.outputs.log.extra_topics).

References: the ObstacleLog's own arrays (what the loop measured) and the obstacles' constant
velocity (centre = center + velocity t); direct ``Environment.loads`` / ``elevation`` /
``current`` / ``wind`` calls at single rows (the writer uses the vectorised ``loads_record``), the
body-to-world rotation done by hand.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from usv_mj import load_scenario
from usv_mj.record.run_record import COL
from usv_mj.outputs.log import RunLogWriter, read_run
from usv_mj.outputs.log.reader import load_topic
from usv_mj.loop.simulate import make_environment, simulate

SCENARIOS = Path(__file__).resolve().parent.parent / "examples" / "scenarios"


def _run_through_build(scenario, **kwargs):
    """A run of an obstacle scenario through usv_mj.build / simulate: the record and its statics."""
    from types import SimpleNamespace

    from usv_mj.loop.simulate import simulate

    record = simulate(scenario, **kwargs)
    return SimpleNamespace(record=record, log=record.statics.obstacle_log, plan=record.statics.plan,
                           guidance=record.statics.guidance)


def test_obstacle_run_logs_clearance_force_and_centres_per_step(tmp_path):
    osc = load_scenario(SCENARIOS / "crossing_boat.toml", overrides={"duration": 2.0})
    path = tmp_path / "obs.mcap"
    with RunLogWriter(path, osc) as writer:
        run = _run_through_build(osc, plant_kind="analytic", sinks=[writer.sink("main")])
    rec, olog = run.record, run.log
    n = rec.n_rows
    log = read_run(path)
    assert log.topic_counts["/usv/obstacles"] == n
    o = log.obstacles
    assert o["names"] == [ob.name for ob in osc.obstacles]
    assert np.isfinite(olog.clearance[:n]).all()
    np.testing.assert_array_equal(o["clearance_m"], olog.clearance[:n])          # bit-exact
    np.testing.assert_array_equal(o["normal_force_N"], olog.normal_force[:n])
    np.testing.assert_array_equal(o["t"], rec["t"])
    # centres: center + velocity t (the crossing boat moves)
    for i, ob in enumerate(osc.obstacles):
        want = np.array(ob.center) + np.outer(rec["t"], ob.velocity)
        np.testing.assert_allclose(o["center"][:, i, :], want, rtol=0, atol=1e-12)
    assert any(ob.moving for ob in osc.obstacles)
    # the record itself still round-trips bit-exactly next to the new topics
    np.testing.assert_array_equal(log.record.data[:n], rec.data[:n])
    # Foxglove scene: a moving obstacle is redrawn at the frame rate (every 20 ms) and all at t = 0
    scene = load_topic(path, "/usv/scene/obstacles")
    assert len(scene["log_time"]) == len(range(0, n, 20))
    first = scene["entities"][0]
    assert {e["id"] for e in first} == {f"obstacle/{ob.name}" for ob in osc.obstacles}
    meta = log.metadata["runs"]["main"]["start"]
    assert "obstacles" in meta


def test_environment_topic_equals_direct_environment_calls(tmp_path):
    sc = load_scenario(preset="paper", overrides={
        "duration": 1.5, "sea": {"preset": "moderate", "current": {"speed": 0.3, "direction_deg": 30.0},
                                 "wind": {"speed": 5.0, "direction_deg": 90.0, "gust_sigma": 1.0}}})
    path = tmp_path / "env.mcap"
    with RunLogWriter(path, sc, background=False) as writer:
        rec = simulate(sc, plant_kind="analytic", sinks=[writer.sink("main")])
    log = read_run(path)
    e = log.environment
    n = rec.n_rows
    assert log.topic_counts["/usv/environment"] == n and e["zeta"].shape == (n,)
    env = make_environment(sc)
    for k in (0, 1, 777, n - 1):
        row = rec.data[k]
        t = row[COL["t"]]
        eta = row[[COL["x"], COL["y"], COL["psi"]]]
        nu = row[[COL["u"], COL["v"], COL["r"]]]
        loads = env.loads(t, eta, nu)
        np.testing.assert_allclose(e["tau_wave"][k], loads.tau_wave1, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(e["tau_drift"][k], loads.tau_drift, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(e["tau_wind"][k], loads.tau_wind, rtol=1e-12, atol=1e-12)
        assert e["zeta"][k] == pytest.approx(env.elevation(eta[0], eta[1], t), abs=1e-12)
        np.testing.assert_allclose(e["current"][k], env.current(t)[0], rtol=0, atol=1e-12)   # world frame
        speed, direction = env.wind(t)
        assert e["wind_speed"][k] == pytest.approx(speed, abs=1e-12)
        assert e["wind_direction"][k] == pytest.approx(math.radians(90.0), abs=1e-15) == pytest.approx(direction)
    assert np.abs(e["zeta"][n // 2:]).max() > 1e-3      # waves reach the hull once the ramp is up
    np.testing.assert_array_equal(log.record.data[:n], rec.data[:n])


def test_calm_run_has_no_environment_topic(tmp_path):
    sc = load_scenario(preset="paper", overrides={"duration": 0.2})
    path = tmp_path / "calm.mcap"
    with RunLogWriter(path, sc, background=False) as writer:
        simulate(sc, plant_kind="analytic", sinks=[writer.sink("main")])
    log = read_run(path)
    assert "/usv/environment" not in log.topic_counts and log.environment is None
    assert "/usv/obstacles" not in log.topic_counts and log.obstacles is None


def test_an_obstacle_log_cut_before_its_first_chunk_still_reads(tmp_path):
    """A harbour run killed within its first 2000 rows leaves channels but no obstacle message:
    the log reads (no rows, no obstacle arrays) instead of failing on the missing topic data."""
    osc = load_scenario(SCENARIOS / "crossing_boat.toml", overrides={"duration": 0.5})
    path = tmp_path / "obs.mcap"
    with RunLogWriter(path, osc) as writer:
        _run_through_build(osc, plant_kind="analytic", sinks=[writer.sink("main")])
    data = path.read_bytes()
    pos = 8                                  # after the magic: record by record to the first Chunk (0x06)
    while data[pos] != 0x06:
        pos += 9 + int.from_bytes(data[pos + 1:pos + 9], "little")
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:pos + 20])
    log = read_run(cut)
    assert "/usv/obstacles" in log.topic_counts      # the channel is there, its messages are not
    assert log.truncated and len(log.record) == 0 and log.obstacles is None
