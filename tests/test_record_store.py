"""A record streamed to disk (usv_mj.record.store) against the same run in memory; RunRecord.open;
the drawing decimation keeps every extreme; the MCAP at a lower rate; a streamed run's memory."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from usv_mj import load_scenario, simulate
from usv_mj.record.decimate import decimate
from usv_mj.core.errors import ScenarioError
from usv_mj.record.run_record import RunRecord
from usv_mj.record.summary import summarize

ROOT = Path(__file__).resolve().parents[1]
# a box that cuts both channels often: saturation events begin and end across many blocks
LIMITED = {"duration": 12.0, "baseline": {"enabled": False},
           "actuators": {"kind": "box", "max_surge_n": 120.0, "max_yaw_nm": 15.0}}


def _bits(a) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64)).view(np.uint64)


def _same_record(a: RunRecord, b: RunRecord) -> None:
    assert a.column_names == b.column_names and len(a) == len(b)
    for c in a.column_names:
        assert np.array_equal(_bits(a[c]), _bits(b[c])), c
    assert [(e.t, e.kind, e.message, e.values) for e in a.events] == \
        [(e.t, e.kind, e.message, e.values) for e in b.events]
    assert (a.status, a.stop_reason) == (b.status, b.stop_reason)


def _no_timing(s: dict) -> dict:
    return {k: v for k, v in s.items() if k not in ("wall_time_s", "realtime_factor")}


@pytest.mark.parametrize("loop", ["auto", "python"])
def test_streamed_record_equals_the_in_memory_record_bit_for_bit(tmp_path, loop):
    sc = load_scenario(preset="paper", overrides=LIMITED)
    mem = simulate(sc, plant_kind="analytic", loop=loop, store=False, block=500)
    # a block that divides nothing: the window slides at odd rows
    disk = simulate(sc, plant_kind="analytic", loop=loop, store=tmp_path / "rec", block=333)
    assert not mem.stored and disk.stored and disk.path == tmp_path / "rec"
    assert mem.metadata["loop"] == ("compiled" if loop == "auto" else "python")
    assert len(disk.buffer) == 2 * 333 + 2          # only the window is in memory
    assert len(mem.events_of("actuator_saturation")) > 10   # the events were exercised
    _same_record(mem, disk)
    assert _no_timing(summarize(mem)) == _no_timing(summarize(disk))
    from usv_mj.jobs.sweep.runner import transient_errors

    after = mem["t"] > 5.0   # the sweep's reduction, chunked, against the whole columns at once
    ex, ey = mem["x"][after] - mem["x_d"][after], mem["y"][after] - mem["y_d"][after]
    got = transient_errors(disk, 5.0)
    assert got == transient_errors(mem, 5.0)
    assert got["max_abs_error_after_transient.x"] == np.max(np.abs(ex))
    assert got["max_position_error_after_transient"] == np.max(np.hypot(ex, ey))


def test_open_reads_a_stored_record_back_lazily(tmp_path):
    sc = load_scenario(preset="paper", overrides=LIMITED)
    mem = simulate(sc, plant_kind="analytic", store=False)
    back = RunRecord.open(mem.save(tmp_path / "saved"))
    assert isinstance(back["e1"], np.memmap)       # mapped, not read
    _same_record(mem, back)
    assert back.metadata["controller"] == "ppc" and back.diagnostic_fields == mem.diagnostic_fields
    assert _no_timing(summarize(back)) == _no_timing(summarize(mem))
    streamed = RunRecord.open(simulate(sc, plant_kind="analytic", store=tmp_path / "streamed").path)
    _same_record(mem, streamed)
    # the column files are plain .npy: numpy reads them without usv_mj
    np.testing.assert_array_equal(np.load(tmp_path / "streamed" / "x.npy"), mem["x"])
    with pytest.raises(AttributeError, match="stored record has no data array"):
        streamed.data


def test_a_killed_run_s_columns_open_as_the_rows_written(tmp_path):
    """The process died inside the run (no end written): the rows every column file holds."""
    sc = load_scenario(preset="paper", overrides=LIMITED)
    mem = simulate(sc, plant_kind="analytic", store=False)
    rec = RunRecord.streamed(tmp_path / "r", 3000, {"controller": "ppc"}, mem.diagnostic_fields)
    for lo in range(0, 2500, 500):   # five blocks of the run, then nothing (killed)
        rec.buffer[lo:lo + 500] = mem.block(lo, lo + 500)
        rec.n_rows = lo + 500
        rec.spill(lo + 500)
    rec._store.flush()
    with open(tmp_path / "r" / "x.npy", "r+b") as f:   # its last block half-written in one file
        f.truncate(128 + 8 * 2200 + 3)
    back = RunRecord.open(tmp_path / "r")
    assert len(back) == 2200 and back.status == "interrupted" and "row 2200" in back.stop_reason
    assert np.array_equal(_bits(back["psi"]), _bits(mem["psi"][:2200]))
    assert back.metadata == {"controller": "ppc"}


def test_auto_store_streams_a_big_record_into_a_folder_that_goes_with_it(monkeypatch):
    import gc

    import usv_mj.loop.simulate as simulation

    monkeypatch.setattr(simulation, "STREAM_BYTES", 1000 * 8 * 50)   # about 1000 rows
    sc = load_scenario(preset="paper", overrides={"duration": 3.0, "baseline": {"enabled": False}})
    rec = simulate(sc, plant_kind="analytic")
    assert rec.stored and rec.path.is_dir() and len(rec) == 3001
    folder = rec.path
    del rec
    gc.collect()
    assert not folder.exists()
    assert not simulate(sc.with_overrides({"duration": 0.5}), plant_kind="analytic").stored


def test_decimation_keeps_every_extreme():
    """A slow sine with one-row spikes (up and down) between the rows a stride would keep."""
    n = 1_000_003
    t = np.arange(n) * 1e-3
    y = np.sin(2 * np.pi * t / 500.0)
    spikes = {123_457: 9.0, 777_001: -7.5, n - 1: 3.0}
    for k, v in spikes.items():
        y[k] = v
    rec = RunRecord.from_arrays({"t": t, "x": y, "y": -y})
    kept = decimate(rec, ("t", "x", "y"), buckets=1000)
    assert len(kept["t"]) <= 2 * 2 * 1000 + 2 and np.all(np.diff(kept["t"]) > 0)
    for k, v in spikes.items():   # each spike's row, with its time
        assert np.any((kept["t"] == t[k]) & (kept["x"] == v)), k
    assert kept["x"].max() == 9.0 and kept["x"].min() == -7.5 and kept["y"].max() == 7.5
    assert kept["t"][0] == 0.0 and kept["t"][-1] == t[-1]
    # the envelope: in each 1/1000 of the rows the kept points span the signal's own range
    b = -(-n // 1000)
    for i in (0, 123_457 // b, 500, 999):
        seg = slice(i * b, min(n, (i + 1) * b))
        inside = (kept["t"] >= t[seg][0]) & (kept["t"] <= t[seg][-1])
        assert kept["x"][inside].max() == y[seg].max() and kept["x"][inside].min() == y[seg].min()
    short = decimate(RunRecord.from_arrays({"t": t[:50], "x": y[:50]}), ("t", "x"))
    np.testing.assert_array_equal(short["x"], y[:50])


def test_the_log_at_a_lower_rate_holds_every_nth_row(tmp_path):
    from usv_mj.outputs.log import RunLogWriter, read_run
    from usv_mj.outputs.log.writer import log_every

    sc = load_scenario(preset="paper", overrides=LIMITED)
    n = log_every(10.0, sc.control_period)
    assert n == 100
    with RunLogWriter(tmp_path / "run.mcap", sc) as w:
        rec = simulate(sc, plant_kind="analytic", sinks=[w.sink("main", log_every=n)], block=333)
    log = read_run(tmp_path / "run.mcap").record
    assert len(log) == len(range(0, len(rec), 100)) == 121
    for c in rec.column_names:
        assert np.array_equal(_bits(log[c]), _bits(rec[c][::100])), c
    assert log.metadata["control_period_s"] == pytest.approx(0.1) and log.metadata["log_every"] == 100
    assert len(log.events) >= len(rec.events)     # every event of the run is in the log
    with pytest.raises(ScenarioError, match="--log-rate 300"):
        log_every(300.0, 0.001)
    with pytest.raises(ScenarioError, match=r"must be in \(0, 1000\] Hz"):
        log_every(0.0, 0.001)


def test_run_job_streams_a_long_record_into_the_output_folder(tmp_path, monkeypatch):
    import usv_mj.loop.simulate as simulation
    from usv_mj.jobs.run import run_job

    monkeypatch.setattr(simulation, "STREAM_BYTES", 1000 * 8 * 50)
    sc = load_scenario(preset="paper", overrides={"duration": 21.0})
    res = run_job(sc, tmp_path / "out", plant_kind="analytic", video=False, progress=False, log_rate=100.0)
    assert res.record.stored and res.record.path == tmp_path / "out" / "record"
    assert (tmp_path / "out" / "baseline_record" / "record.json").exists()
    back = RunRecord.open(tmp_path / "out" / "record")
    assert len(back) == 21001 and back.status == "completed"
    mem = simulate(sc.with_overrides({"baseline": {"enabled": False}}), plant_kind="analytic", store=False)
    saved = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert saved["errors_at"] == summarize(mem)["errors_at"]
    assert saved["max_abs_error_after_20s"] == summarize(mem)["max_abs_error_after_20s"]


_PEAK = textwrap.dedent("""
    import resource, sys
    from usv_mj import load_scenario, simulate
    from usv_mj.record.summary import summarize
    from usv_mj.outputs.figures import draw_figures
    sc = load_scenario(preset="paper", overrides={"duration": 600.0, "baseline": {"enabled": False}})
    simulate(sc.with_overrides({"duration": 1.0}), plant_kind="analytic")   # imports, compiled loop
    draw_figures(simulate(sc.with_overrides({"duration": 1.0}), plant_kind="analytic"), sys.argv[1] + "/f0")
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    rec = simulate(sc, plant_kind="analytic", store=sys.argv[1] + "/rec")
    s = summarize(rec)
    draw_figures(rec, sys.argv[1] + "/f1")
    after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(len(rec), len(rec.column_names), s["funnel_violations"], (after - before) / 1024.0)
""")


@pytest.mark.slow
def test_a_streamed_run_s_memory_does_not_grow_with_its_length(tmp_path):
    """600 s at 1 kHz: its record in memory is 600001 rows x 48 columns x 8 B = 230 MB; streamed,
    the run, its summary and its figures add less than 80 MB to the peak (a window of two blocks,
    chunked reductions, decimated drawing)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    out = subprocess.run([sys.executable, "-c", _PEAK, str(tmp_path)], capture_output=True, text=True, env=env,
                         cwd=ROOT, timeout=600)
    assert out.returncode == 0, out.stderr
    rows, cols, violations, grew_mb = out.stdout.split()[-4:]
    assert int(rows) == 600001 and violations == "0"
    in_memory_mb = int(rows) * int(cols) * 8 / 2 ** 20
    assert in_memory_mb > 200
    assert float(grew_mb) < 80, f"the peak grew by {grew_mb} MB (in memory the record alone is {in_memory_mb:.0f} MB)"


def test_an_append_cut_by_ctrl_c_is_finished_by_the_next(tmp_path):
    """Ctrl-C inside a block's append (some columns written): the next append completes the others."""
    from usv_mj.record.store import ColumnStore

    store = ColumnStore(tmp_path / "s", ("t", "a", "b"))
    rows = np.arange(30, dtype=float).reshape(10, 3)
    store.append(rows[:4])
    real = store._files["b"]

    class Cut:
        def write(self, data):
            raise KeyboardInterrupt

    store._files["b"] = Cut()
    with pytest.raises(KeyboardInterrupt):
        store.append(rows[4:7])
    store._files["b"] = real
    store.append(rows[4:10])     # the loop's final flush: the rows after the last complete append
    store.finish({"status": "interrupted"})
    for i, name in enumerate(("t", "a", "b")):
        np.testing.assert_array_equal(np.load(tmp_path / "s" / f"{name}.npy"), rows[:, i])


@pytest.mark.parametrize("loop", ["auto", "python"])
@pytest.mark.parametrize("limit,rows", [({"max_force": 150.0}, 1), ({"max_speed": 0.79}, 9000)])
def test_a_run_that_stops_early_is_the_same_streamed(tmp_path, loop, limit, rows):
    """The force check (at the first row: |tau_r| = 730 N m) and the state check (u reaches 0.79 m/s
    near t = 10 s, inside the 30th block) stop the run."""
    sc = load_scenario(preset="paper", overrides={**LIMITED, "actuators": {}, "limits": limit})
    mem = simulate(sc, plant_kind="analytic", loop=loop, store=False, block=333)
    disk = simulate(sc, plant_kind="analytic", loop=loop, store=tmp_path / "r", block=333)
    assert mem.status == "diverged" and len(mem) >= rows, (mem.status, len(mem))
    _same_record(mem, disk)
    _same_record(mem, RunRecord.open(tmp_path / "r"))
