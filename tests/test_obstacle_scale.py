"""Obstacles at scale: the clearance broad phase, the streamed obstacle log, the video's row reads.

References: the all-pairs clearance (every obstacle measured exactly, ``exact_within = inf``; the
same distance functions, so the entries the broad phase measures must be equal bit for bit and
the ones it leaves out must be farther than its reach); a brute-force reach test for the grid;
an in-memory run of the same scenario for the streamed log (bit for bit); the rows a frame draws
(its row, its trail's and its path's samples) for the video planner.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from usv_mj.scenario.obstacles import from_tables
from usv_mj.obstacles import clearance as clearance_mod
from usv_mj.obstacles.broad_phase import StandingGrid, grid_candidates
from usv_mj.obstacles.clearance import GeometricClearance, MuJoCoClearance
from usv_mj.scenario.spec import load_scenario
from usv_mj.loop.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from bench_obstacles import harbour_toml  # noqa: E402

REACH = 10.0   # the monitors' default exact_within [m]


def random_field(rng, count, moving=0, half=45.0):
    """Circles and boxes (some moving) in a square, as obstacle specs."""
    tables = []
    for i in range(count):
        x, y = rng.uniform(-half, half, 2)
        table = {"name": f"o{i}", "center": [float(x), float(y)]}
        if rng.random() < 0.6:
            table["radius"] = float(rng.uniform(0.3, 2.0))
        else:
            table.update(kind="box", size=[float(rng.uniform(1, 12)), float(rng.uniform(0.5, 4))],
                         yaw=float(rng.uniform(-3, 3)))
        if i < moving:
            table["velocity"] = [float(v) for v in rng.uniform(-1.5, 1.5, 2)]
        tables.append(table)
    return from_tables(tables)


def poses(rng, obstacles, count, t=0.0):
    """Hull poses: half anywhere, half next to an obstacle (within a few metres, some overlapping)."""
    out = []
    for j in range(count):
        if j % 2:
            o = obstacles[rng.integers(len(obstacles))]
            cx, cy = o.center_at(t)
            a, r = rng.uniform(0, 2 * math.pi), o.bounding_radius + rng.uniform(-0.5, 4.0)
            out.append(np.r_[cx + r * math.cos(a), cy + r * math.sin(a), rng.uniform(-3, 3), 0, 0, 0])
        else:
            out.append(np.r_[rng.uniform(-60, 60, 2), rng.uniform(-3, 3), 0, 0, 0])
    return out


def assert_same_as_all_pairs(broad, every, in_broad, in_every):
    """The broad phase's entries against the all-pairs ones (module docstring)."""
    measured = ~np.isnan(broad)
    assert np.array_equal(broad[measured].view(np.uint64), every[measured].view(np.uint64))
    assert (every[~measured] > REACH).all()
    assert np.array_equal(in_broad, in_every)
    if every.min() <= REACH:     # the minimum is within reach: the same value, the same (first) obstacle
        assert np.nanmin(broad) == every.min() and int(np.nanargmin(broad)) == int(np.argmin(every))


def test_the_grid_finds_every_obstacle_within_reach():
    rng = np.random.default_rng(27)
    centers, radii = rng.uniform(-300, 300, (400, 2)), rng.uniform(0.1, 30.0, 400)
    for reach in (11.05, 3.0, 80.0):
        grid = StandingGrid(centers, radii, reach)
        seen, stamp, out = np.zeros(400, np.int64), np.zeros(1, np.int64), np.zeros(400, np.int64)
        for x, y in rng.uniform(-350, 350, (300, 2)):
            found = set(out[:grid_candidates(*grid.args, x, y, seen, stamp, out)].tolist())
            assert len(found) == len(out[:len(found)])            # each once
            near = np.flatnonzero(np.hypot(centers[:, 0] - x, centers[:, 1] - y) - radii < reach)
            assert set(near.tolist()) <= found
    spread = StandingGrid([[0, 0], [1e7, 1e7]], [1.0, 1.0], 11.0)   # cells never outnumber the limit
    assert spread.shape.prod() <= StandingGrid.MAX_CELLS_PER_OBSTACLE * 64


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_geometric_broad_phase_equals_all_pairs_on_random_scenes(seed):
    rng = np.random.default_rng(seed)
    obstacles = random_field(rng, 60, moving=6)
    broad = GeometricClearance(obstacles, broad_phase=True)
    every = GeometricClearance(obstacles, exact_within=math.inf)
    assert broad.broad_phase
    for t in (0.0, 7.5):
        for state in poses(rng, obstacles, 120, t):
            b = broad.update(t, state).copy()
            e = every.update(t, state).copy()
            assert_same_as_all_pairs(b, e, broad.in_contact, every.in_contact)


def test_mujoco_broad_phase_equals_all_pairs_with_contacts():
    from usv_mj.plants.harbour import HarbourPlant

    rng = np.random.default_rng(5)
    obstacles = random_field(rng, 40, moving=4)
    sc = load_scenario(preset="paper")
    with HarbourPlant(sc.ship, sc.disturbance, obstacles) as plant:
        broad = MuJoCoClearance(plant, broad_phase=True)
        every = MuJoCoClearance(plant, exact_within=math.inf)
        assert broad.broad_phase
        touched = 0
        for j, state in enumerate(poses(rng, obstacles, 160, 2.0)):
            plant.reset(state[:3], (0, 0, 0))
            plant.move_obstacles(2.0)
            mujoco.mj_forward(plant.model, plant.data)   # contacts at this pose
            b = broad.update().copy()
            e = every.update().copy()
            assert_same_as_all_pairs(b, e, broad.in_contact, every.in_contact)
            assert np.array_equal(broad.normal_force, every.normal_force)
            touched += bool(every.in_contact.any())
        assert touched > 3                            # contacts were among the poses


def _harbour(tmp_path, count=40, **overrides):
    path = tmp_path / f"harbour_{count}.toml"
    path.write_text(harbour_toml(count))
    return load_scenario(path, overrides=overrides)


def _fingerprint(rec):
    ob = rec.metadata["obstacles"]
    per = [(o["min_clearance_m"], i) for i, o in enumerate(ob["per_obstacle"]) if o["min_clearance_m"] is not None]
    return (ob["min_clearance_m"], min(per)[1] if per else None, ob["contacts"], ob["near_misses"],
            [(e.t, e.kind, e.message) for e in rec.events])


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_a_run_with_the_broad_phase_keeps_the_minimum_its_obstacle_near_misses_and_contacts(plant, tmp_path,
                                                                                             monkeypatch):
    """A 40-buoy harbour, both loops: the same minimum, obstacle, events and record as the run whose
    monitor measures every obstacle (all pairs); the log's measured entries are those values."""
    rng = np.random.default_rng(11)
    tables = [{"name": f"buoy_{i}", "center": [float(rng.uniform(-20, 60)), float(y)],
               "radius": float(rng.uniform(0.3, 1.0))}
              for i, y in enumerate(rng.choice([-1, 1], 40) * rng.uniform(1.6, 30, 40))]
    tables.append({"name": "pier", "kind": "box", "center": [9.0, 0.0], "size": [1.0, 8.0]})
    sc = load_scenario(preset="paper").with_overrides({
        "duration": 14.0, "plant": {"kind": plant}, "initial": {"eta": [0.0, 0.0, 0.0]},
        "trajectory": {"kind": "line", "start": [0.0, 0.0], "heading_deg": 0.0}, "obstacles": tables,
        "guidance": {"avoid": False, "margin_m": 1.0}})
    runs = {loop: simulate(sc, loop=loop) for loop in ("auto", "python")}
    real = clearance_mod.make_clearance_monitor
    monkeypatch.setattr(clearance_mod, "make_clearance_monitor",
                        lambda p, o, dims=None: (MuJoCoClearance(p, exact_within=math.inf)
                                                 if hasattr(p, "obstacle_geoms")
                                                 else GeometricClearance(o, exact_within=math.inf, dimensions=dims)))
    every = simulate(sc, loop="python")
    monkeypatch.setattr(clearance_mod, "make_clearance_monitor", real)
    assert runs["auto"].metadata["loop"] == "compiled"
    n = every.n_rows
    e = every.statics.obstacle_log.clearance[:n]
    assert _fingerprint(every)[2] > 0 and _fingerprint(every)[3] > 0   # contacts and near misses happened
    for rec in runs.values():
        assert _fingerprint(rec) == _fingerprint(every)
        assert all(np.array_equal(rec[c], every[c], equal_nan=True) for c in rec.column_names)
        b = rec.statics.obstacle_log.clearance[:n]
        measured = ~np.isnan(b)
        assert np.array_equal(b[measured], e[measured]) and (e[~measured] > REACH).all()
        assert rec.metadata["obstacles"]["beyond_reach_m"] == REACH
        assert np.isnan(b).any()                                             # some were beyond reach
    from usv_mj.outputs.report import write_report
    from usv_mj.record.summary import summarize

    summary = summarize(runs["auto"])
    assert summary["beyond_reach_m"] == REACH and summarize(every)["beyond_reach_m"] is None
    text = write_report(tmp_path / "report.md", summary).read_text()
    assert f"never came within {REACH:g} m" in text


def test_standing_obstacles_are_posed_once_and_the_dynamics_do_not_change():
    """MuJoCo's sleeping (the hull never asleep) leaves the harbour plant's trajectory bit for bit
    what it is without it, and its static geoms are where the scenario puts them."""
    from usv_mj.plants.harbour import HarbourPlant

    obstacles = random_field(np.random.default_rng(8), 30, moving=2)
    sc = load_scenario(preset="paper")
    runs = []
    for sleep in (True, False):
        with HarbourPlant(sc.ship, sc.disturbance, obstacles) as plant:
            m = plant.model
            assert m.opt.enableflags & mujoco.mjtEnableBit.mjENBL_SLEEP
            assert (m.tree_sleep_policy == mujoco.mjtSleepPolicy.mjSLEEP_NEVER).all()
            if not sleep:
                m.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
            plant.reset((0, 0, 0.3), (0.4, 0, 0))
            xs = []
            for k in range(1500):
                plant.move_obstacles(k * 1e-3)
                plant.step(60.0, 4.0 * math.sin(k * 1e-2))
                xs.append(plant.state.copy())
            mujoco.mj_kinematics(m, plant.data)
            for i, o in enumerate(obstacles):
                assert tuple(plant.data.geom_xpos[plant.obstacle_geoms[i], :2]) == pytest.approx(o.center_at(1.499))
            runs.append(np.array(xs))
    assert np.array_equal(runs[0], runs[1])


@pytest.mark.parametrize("loop", ["auto", "python"])
def test_the_obstacle_log_streams_with_the_record_and_its_memory_does_not_grow(loop, tmp_path):
    """A streamed run keeps a window of the log in memory whatever its duration, and its rows (read
    back lazily from disk, in the run and after it) and summary equal an in-memory run's bit for bit;
    ramming_pier: the contact forces too."""
    from usv_mj.obstacles.sink import StoredObstacleLog

    sizes = {}
    for name, sc in (("harbour", _harbour(tmp_path, plant={"kind": "analytic"})),
                     ("pier", load_scenario(ROOT / "examples/scenarios/ramming_pier.toml"))):
        for duration in ((2.0, 4.0) if name == "harbour" else (31.0,)):
            run = sc.with_overrides({"duration": duration})
            mem = simulate(run, loop=loop, block=300, store=False)
            folder = tmp_path / f"{name}_{duration}_{loop}"
            disk = simulate(run, loop=loop, block=300, store=folder)
            lm, ld = mem.statics.obstacle_log, disk.statics.obstacle_log
            assert ld.stored and not lm.stored
            sizes[(name, duration)] = ld._clear.nbytes + ld._force.nbytes
            assert len(ld._clear) == len(disk.buffer)                     # the record's window
            n = mem.n_rows
            stored = StoredObstacleLog(folder / "obstacles")
            assert stored.rows == n
            for log in (ld, stored):
                for field in ("clearance", "normal_force", "obstacle_xy"):
                    a, b = np.asarray(getattr(lm, field)[:n]), np.asarray(getattr(log, field)[:n])
                    assert np.array_equal(a.view(np.uint64), b.view(np.uint64)), field
                lo = n // 3
                assert np.array_equal(log.clearance[lo:lo + 7], lm.clearance[lo:lo + 7], equal_nan=True)
            assert mem.metadata["obstacles"] == disk.metadata["obstacles"]
            if name == "pier":
                assert disk.metadata["obstacles"]["contacts"] == 1 and np.asarray(ld.normal_force[:n]).max() > 0
    assert sizes[("harbour", 2.0)] == sizes[("harbour", 4.0)]


def _stored_run(tmp_path, rows=120_001, dt=0.01, name="rec"):
    from usv_mj.record.run_record import RunRecord

    t = np.arange(rows) * dt
    cols = {"t": t, "x": 0.5 * t, "y": np.sin(0.01 * t), "psi": 0.1 + 0.0 * t, "x_d": 0.5 * t + 1.0,
            "y_d": np.zeros(rows), "psi_d": np.zeros(rows), "tau_u": 10 * np.sin(t), "q_tau_u": 10 * np.sin(t),
            "tau_r": np.cos(t), "q_tau_r": np.cos(t)}
    mem = RunRecord.from_arrays(cols, metadata={"preset": "test", "controller": "pi", "plant": "analytic"})
    mem.save(tmp_path / name)
    return mem, RunRecord.open(tmp_path / name)


def test_the_video_of_a_stored_run_reads_only_the_rows_it_draws(tmp_path, monkeypatch):
    from usv_mj.record import store as record_store
    from usv_mj.outputs.render.planner import plan_frames

    mem, disk = _stored_run(tmp_path)
    reads = []
    real_read = record_store.ColumnStore.read

    def read(self, name, lo, hi):
        reads.append((name, lo, hi))
        return real_read(self, name, lo, hi)

    def whole(self, name):
        raise AssertionError(f"the planner mapped the whole column {name}")

    monkeypatch.setattr(record_store.ColumnStore, "read", read)
    monkeypatch.setattr(record_store.ColumnStore, "column", whole)
    plan = plan_frames(disk, fps=10, speedup=40.0, width=160, height=120, segments=16)
    monkeypatch.undo()
    expect = plan_frames(mem, fps=10, speedup=40.0, width=160, height=120, segments=16)
    assert len(plan.frames) == len(expect.frames) == 300 and np.array_equal(plan.rows, expect.rows)
    for a, b in zip(plan.frames, expect.frames):
        assert repr((a.t, a.pose, a.ref_pose, a.hud)) == repr((b.t, b.pose, b.ref_pose, b.hud))  # NaN alike
        assert np.array_equal(a.trail, b.trail) and np.array_equal(a.path, b.path)
    drawn = {int(k) for k in plan.rows}
    values = sum(hi - lo for _, lo, hi in reads)
    # a frame reads its row of each column it shows, (x, y) and (x_d, y_d) at its trail's and path's
    # samples and t about each sample (the search): short reads, a small part of the record
    assert max(hi - lo for _, lo, hi in reads) <= 4
    per_frame = 2 * len(disk.column_names) + 4 * 17 + 2 * 2 * (2 * 17) + 10   # (the search: 2 reads of t)
    assert values <= len(plan.frames) * per_frame < 0.03 * len(disk) * len(disk.column_names)
    assert {lo for name, lo, hi in reads if name == "psi"} <= drawn | {len(disk) - 1}


def test_a_streamed_obstacle_log_goes_to_the_run_log_as_an_in_memory_one_does(tmp_path):
    """The MCAP obstacle topic of a streamed run (its rows read from the log's window and files)
    is bit for bit the in-memory run's, NaN beyond reach included."""
    from usv_mj.outputs.log import RunLogWriter, read_run

    sc = _harbour(tmp_path, duration=2.0, plant={"kind": "analytic"})
    topics = []
    for store in (False, tmp_path / "rec"):
        path = tmp_path / f"run_{bool(store)}.mcap"
        with RunLogWriter(path, sc) as writer:
            rec = simulate(sc, sinks=[writer.sink("main")], block=250, store=store)
        assert rec.statics.obstacle_log.stored == bool(store)
        topics.append(read_run(path).obstacles)
    a, b = topics
    assert np.isnan(a["clearance_m"]).any() and np.isfinite(a["clearance_m"]).any()
    for key in ("t", "clearance_m", "normal_force_N", "center"):
        assert np.array_equal(np.asarray(a[key]).view(np.uint64), np.asarray(b[key]).view(np.uint64)), key


def test_a_big_obstacle_log_streams_beside_an_in_memory_record(tmp_path, monkeypatch):
    """Many obstacles make a log bigger than the record: past LOG_STREAM_BYTES it streams into a
    temporary folder (removed with it) even when the record stays in memory; the same values."""
    import gc

    from usv_mj.obstacles import sink

    sc = _harbour(tmp_path, duration=3.0, plant={"kind": "analytic"})
    full = simulate(sc, block=250, store=False)
    monkeypatch.setattr(sink, "LOG_STREAM_BYTES", 1 << 20)       # this log: 3001 rows x 40 x 16 = 1.9 MB
    monkeypatch.setattr(sink, "WINDOW_ROWS", 300)
    small = simulate(sc, block=250, store=False)
    lf, ls = full.statics.obstacle_log, small.statics.obstacle_log
    assert not small.stored and ls.stored and not lf.stored
    assert ls._clear.shape == (300, 40)
    n = full.n_rows
    for field in ("clearance", "normal_force", "obstacle_xy"):
        a, b = np.asarray(getattr(lf, field)[:n]), np.asarray(getattr(ls, field)[:n])
        assert np.array_equal(a.view(np.uint64), b.view(np.uint64)), field
    assert full.metadata["obstacles"] == small.metadata["obstacles"]
    folder = ls._folder
    assert (folder / "clearance.value.npy").exists()
    del small, ls
    gc.collect()
    assert not folder.exists()


def test_render_takes_a_long_runs_stored_record_lazily(tmp_path):
    """``usv-mj render RUN`` of a run directory that kept ``record/`` reads that record lazily (the
    MCAP would be read whole), and a streamed harbour run's record.json carries the obstacle summary
    the video's world needs."""
    from usv_mj.record.run_record import RunRecord
    from usv_mj.outputs.render.video import stored_record

    _stored_run(tmp_path / "run", rows=1001, name="record")
    found = stored_record(tmp_path / "run")
    assert found is not None and found[0].stored and found[1] == tmp_path / "run" / "run.mcap"
    assert stored_record(tmp_path) is None
    sc = _harbour(tmp_path, duration=1.0, plant={"kind": "analytic"})
    rec = simulate(sc, store=tmp_path / "harbour" / "record")
    again = RunRecord.open(tmp_path / "harbour" / "record")
    assert again.metadata["obstacles"] == rec.metadata["obstacles"]
