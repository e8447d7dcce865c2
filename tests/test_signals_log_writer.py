"""Issue 38, signals and the log writer (causes 2, 3, 11, 19): a signal to the whole process group
(a terminal's Ctrl-C or hang-up, ``timeout``, ``kill -TERM -PGID``) leaves a run log that holds
exactly what its end record and summary.json say; a live server waiting for a viewer stops on
Ctrl-C or SIGTERM; the benchmark's cluster start stops quietly.

Every test starts the program in its own process group (as a terminal does) and signals the group.
Each waits for a condition the program reports (rows in the staging folder's log, a line on
stderr, worker processes in the group), with a bound, never a fixed time, and asserts one outcome.
"""

from __future__ import annotations

import json
import math
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BOUND_S = 300.0          # the longest any condition may take on a loaded two-core machine


class Group:
    """``python -m usv_mj.cli.main ARGS`` as the leader of its own process group (a terminal's job),
    its stderr read line by line as it comes."""

    def __init__(self, args, cwd: Path, env: dict | None = None):
        self.proc = subprocess.Popen([sys.executable, "-m", "usv_mj.cli.main", *map(str, args)], cwd=cwd,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     env={**os.environ, "PYTHONPATH": str(ROOT), **(env or {})},
                                     start_new_session=True)
        self.lines: queue.Queue = queue.Queue()
        self.err: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stderr:
            self.err.append(line)
            self.lines.put(line)
        self.lines.put(None)

    def wait_for_line(self, text: str, timeout: float = BOUND_S) -> str:
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                self.kill()
                pytest.fail(f"no line with {text!r} in {timeout} s: {''.join(self.err)}")
            if line is None:
                pytest.fail(f"the program ended before a line with {text!r}: {''.join(self.err)}")
            if text in line:
                return line

    def wait_until(self, condition, what: str, timeout: float = BOUND_S) -> None:
        deadline = time.monotonic() + timeout
        while not condition():
            if self.proc.poll() is not None:
                pytest.fail(f"the program ended before {what}: {''.join(self.err)}")
            if time.monotonic() > deadline:
                self.kill()
                pytest.fail(f"{what}: not in {timeout} s")
            time.sleep(0.02)          # a poll interval, not a wait for the outcome

    def signal_group(self, sig) -> None:
        os.killpg(self.proc.pid, sig)

    def finish(self, timeout: float = 120.0) -> tuple[int | None, str, str]:
        """The exit code (None: it did not end in ``timeout`` s and was killed), stdout, stderr."""
        out: list[str] = []
        reader = threading.Thread(target=lambda: out.append(self.proc.stdout.read()), daemon=True)
        reader.start()             # stdout here; stderr is the line reader's alone
        try:
            code = self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            self.proc.wait()
            code = None
        reader.join(10)
        deadline = time.monotonic() + 10
        while self.lines.get(timeout=max(0.0, deadline - time.monotonic())) is not None:
            pass
        return code, "".join(out), "".join(self.err)

    def kill(self) -> None:
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def rows_in_staging_log(folder: Path, name: str = "out", at_least: int = 1) -> bool:
    """The run writes its log into ``.NAME.staging-PID/run.mcap``: True once it holds ``at_least``
    complete chunks' worth of /usv/state messages (the loop is running)."""
    from usv_mj.outputs.log.reader import RunLogReadError, scan_summary

    for log in folder.glob(f".{name}.staging-*/run.mcap"):
        try:
            if scan_summary(log)["topics"].get("/usv/state", {}).get("count", 0) >= at_least:
                return True
        except (RunLogReadError, OSError):   # the header not written yet
            pass
    return False


def _spawned(pid: int, pgid: int) -> bool:
    """``pid`` is a process of group ``pgid`` that multiprocessing spawned (a worker)."""
    try:
        return os.getpgid(pid) == pgid and b"--multiprocessing-fork" in Path(f"/proc/{pid}/cmdline").read_bytes()
    except (OSError, ProcessLookupError):
        return False


def assert_log_holds_what_it_says(out: Path) -> None:
    """run.mcap is complete, holds every row the run simulated (summary.json's simulated_s is its
    last row's t) and its end record counts exactly the rows it holds."""
    from usv_mj.outputs.log import read_run

    summary = json.loads((out / "summary.json").read_text())
    log = read_run(out / "run.mcap")
    assert log.complete, log.notice
    assert log.notice == ""
    record = log.record
    assert record.value("t", -1) == summary["simulated_s"]
    dt = record.metadata["control_period_s"]
    assert len(record) == round(summary["simulated_s"] / dt) + 1
    end = log.metadata["runs"]["main"]["end"]
    assert int(end["rows"]) == len(record)


# --- cause 3: SIGTERM or SIGHUP to the process group ------------------------------------------------


RUN = ["run", "--plant", "analytic", "--no-video", "--no-baseline", "-q", "--duration", "3000"]


@pytest.mark.parametrize("sig, name", [(signal.SIGTERM, "SIGTERM"), (signal.SIGHUP, "SIGHUP")])
def test_a_signal_to_the_process_group_leaves_the_whole_log(tmp_path, sig, name):
    """Before: the background writer died of the signal: run.mcap cut 2-4 s short of the run and
    without its footer while summary.json said ``missing_outputs: []``; SIGHUP added the resource
    tracker's KeyError tracebacks and "leaked" warnings."""
    prog = Group([*RUN, "--out", tmp_path / "out"], tmp_path)
    prog.wait_until(lambda: rows_in_staging_log(tmp_path), "the run writing rows into its log")
    prog.signal_group(sig)
    code, _, err = prog.finish()
    assert code == 1, err
    assert "Traceback" not in err and "leak" not in err and "resource_tracker" not in err, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "interrupted" and name in summary["stop_reason"]
    assert "job_stopped" not in summary, summary.get("job_stopped")
    assert_log_holds_what_it_says(tmp_path / "out")


def test_a_hang_up_to_a_manoeuvre_leaves_the_whole_log(tmp_path):
    """The same writer serves ``manoeuvre``: before, its log was cut as ``run``'s."""
    prog = Group(["manoeuvre", "turning", "--plant", "analytic", "-q", "--duration", "3000",
                  "--out", tmp_path / "out"], tmp_path)
    prog.wait_until(lambda: rows_in_staging_log(tmp_path), "the manoeuvre writing rows into its log")
    prog.signal_group(signal.SIGHUP)
    code, _, err = prog.finish()
    assert code == 1, err
    assert "Traceback" not in err and "leak" not in err, err
    assert_log_holds_what_it_says(tmp_path / "out")


FLEET = """
preset = "paper"
control_period = 0.01
[plant]
kind = "analytic"
[[vessels]]
name = "own"
own_ship = true
steer = "keep"
speed = 0.6
initial = { eta = [0.0, 0.0, 1.5707963267948966], nu = [0.6, 0.0, 0.0] }
[[vessels]]
name = "target"
steer = "keep"
speed = 0.6
initial = { eta = [30.0, 0.0, 1.5707963267948966], nu = [0.6, 0.0, 0.0] }
"""


def test_a_signal_to_a_fleets_process_group_leaves_every_vessels_log_whole(tmp_path):
    """A fleet (``[[vessels]]``) writes run.mcap and vessel-target.mcap, each by its own background
    writer: SIGTERM to the group stops the run, and both logs end with every row the run made."""
    (tmp_path / "fleet.toml").write_text(FLEET)
    prog = Group(["run", "--scenario", tmp_path / "fleet.toml", "--plant", "analytic", "--no-video", "-q",
                  "--duration", "3000", "--out", tmp_path / "out"], tmp_path)
    prog.wait_until(lambda: rows_in_staging_log(tmp_path), "the fleet writing rows into its log")
    prog.signal_group(signal.SIGTERM)
    code, _, err = prog.finish()
    assert code == 1, err
    assert "Traceback" not in err and "leak" not in err, err
    out = tmp_path / "out"
    assert (out / "summary.json").is_file(), (err, sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*")))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and "SIGTERM" in summary["stop_reason"]
    from usv_mj.outputs.log import read_run

    log = read_run(out / "run.mcap")
    assert log.complete and log.notice == "" and set(log.runs) == {"main", "target"}
    dt = 0.01
    for run, name in (("main", "own"), ("target", "target")):
        record = log.runs[run]
        simulated = summary["vessels"][name]["simulated_s"]
        assert record.value("t", -1) == simulated
        assert len(record) == round(simulated / dt) + 1
        assert int(log.metadata["runs"][run]["end"]["rows"]) == len(record)
        assert record.status == "interrupted"
    companion = read_run(out / "vessel-target.mcap")        # the companion read alone is whole too
    assert companion.complete and companion.notice == ""


class Taker:
    """A fleet vessel's sink that keeps what it is handed; ``cut``: the first ``rows`` call ends
    with a KeyboardInterrupt before it takes the rows (a SIGTERM landing inside the sink: the
    loop hands them again; a sink that took them passes over what it has, as RunLogSink does)."""

    def __init__(self, cut: bool = False):
        self.ranges, self.cut, self.ends, self.held = [], cut, 0, None

    def start(self, record):
        pass

    def rows(self, record, lo, hi):
        if self.cut:
            self.cut = False
            raise KeyboardInterrupt("SIGTERM")
        self.ranges.append((lo, hi))

    def finish(self, record):
        self.ends += 1
        self.held = signal.pthread_sigmask(signal.SIG_BLOCK, [])


def test_a_signal_inside_a_fleets_sink_neither_repeats_nor_loses_rows(tmp_path):
    """In process, no log: before, the fleet's final flush sent the interrupted block again from
    the start (the own ship's sink, which had them, got rows 0..10 twice) and re-detected the
    events; the sinks finished with the group's signals open (a second signal cut an end record)."""
    from usv_mj import load_scenario
    from usv_mj.builder import build_fleet
    from usv_mj.loop.fleet import simulate_fleet

    (tmp_path / "fleet.toml").write_text(FLEET.replace('preset = "paper"', 'preset = "paper"\nduration = 0.3'))
    parts = build_fleet(load_scenario(tmp_path / "fleet.toml"))
    sinks = {"own": Taker(), "target": Taker(cut=True)}       # the own ship's sink is handed rows first
    try:
        record = simulate_fleet(parts, block=10, sinks={name: [s] for name, s in sinks.items()})
    finally:
        parts.close()
    assert record.status == "interrupted" and "SIGTERM" in record.stop_reason
    for name, sink in sinks.items():
        rows = len(record[name])
        assert rows >= 10
        covered = [i for lo, hi in sink.ranges for i in range(lo, hi)]
        assert covered == list(range(rows)), (name, sink.ranges)      # each row once, in order
        assert sink.ends == 1
        assert {signal.SIGINT, signal.SIGTERM, signal.SIGHUP} <= set(sink.held)
    events = [(e.t, e.kind, e.message) for e in record["own"].events]
    assert len(events) == len(set(events)), events


def test_a_log_whose_writer_was_killed_is_named_in_the_summary(tmp_path):
    """The writer killed on its own (SIGKILL, the OOM killer): the run goes on without its log.
    Before: summary.json said ``missing_outputs: []`` beside a run.mcap cut short, and the line
    said only "the background writer exited without a reply"."""
    prog = Group([*RUN, "--out", tmp_path / "out"], tmp_path)
    prog.wait_until(lambda: rows_in_staging_log(tmp_path), "the run writing rows into its log")
    writers = [int(pid) for pid in os.listdir("/proc") if pid.isdigit() and _spawned(int(pid), prog.proc.pid)]
    assert len(writers) == 1                    # --no-video: the log writer is the only spawned worker
    os.kill(writers[0], signal.SIGKILL)
    prog.wait_for_line("the run goes on without its log")
    prog.signal_group(signal.SIGINT)
    code, _, err = prog.finish()
    assert code == 1, err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"usv-mj run: {tmp_path / 'out' / 'run.mcap'}: the background log writer died "
                           "(killed by SIGKILL)"), err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["missing_outputs"] == ["run.mcap"]
    from usv_mj.outputs.log import read_run

    log = read_run(tmp_path / "out" / "run.mcap")
    assert not log.complete and "cut short" in log.notice


# --- cause 2: Ctrl-C to a live run ------------------------------------------------------------------


def test_ctrl_c_to_a_paced_live_run_loses_no_rows(tmp_path):
    """``run --live --speed 1``: Ctrl-C lands while the live server paces a chunk. Before: the
    block being written was dropped from run.mcap (6000 rows in the file) while its end record and
    ``inspect`` said 8000 and complete."""
    pytest.importorskip("foxglove", reason='pip install "usv_mj[live]"')
    prog = Group(["run", "--plant", "analytic", "--no-video", "--no-baseline", "-q", "--duration", "120",
                  "--live", "--live-port", "0", "--live-wait", "0", "--speed", "1", "--out", tmp_path / "out"],
                 tmp_path)
    prog.wait_until(lambda: rows_in_staging_log(tmp_path, at_least=2000), "the live run writing rows")
    prog.signal_group(signal.SIGINT)
    code, _, err = prog.finish()
    assert code == 1, err
    assert "Traceback" not in err, err
    assert_log_holds_what_it_says(tmp_path / "out")


# --- cause 11: a live server waiting for its viewer -------------------------------------------------


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_live_run_waiting_for_a_viewer_stops_on_a_signal(tmp_path, sig):
    """Before: "Ctrl-C stops" was printed, but Ctrl-C and SIGTERM were held until a viewer came
    (the compiled loop held them over its first block, which includes the first flush); only
    SIGKILL ended it, leaving the lock and the staging folder."""
    pytest.importorskip("foxglove", reason='pip install "usv_mj[live]"')
    prog = Group(["run", "--plant", "analytic", "--no-video", "--no-baseline", "-q", "--duration", "30",
                  "--live", "--live-port", "0", "--out", tmp_path / "out"], tmp_path)
    prog.wait_for_line("live: waiting for a viewer")
    prog.signal_group(sig)
    code, _, err = prog.finish(timeout=60)
    assert code == 1, err
    assert "Traceback" not in err, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "interrupted"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]     # no lock, no staging folder left


def test_a_fleet_waiting_for_a_viewer_stops_on_ctrl_c_with_every_vessels_log(tmp_path):
    """A fleet's live run: before, Ctrl-C during the wait (inside the fleet's first flush, after
    2000 steps) made the final flush start the own ship's run again: "the run failed: run 'main'
    was started twice". Now the sinks start before the first step, as a single run's."""
    pytest.importorskip("foxglove", reason='pip install "usv_mj[live]"')
    (tmp_path / "fleet.toml").write_text(FLEET)
    prog = Group(["run", "--scenario", tmp_path / "fleet.toml", "--plant", "analytic", "--no-video", "-q",
                  "--duration", "30", "--live", "--live-port", "0", "--out", tmp_path / "out"], tmp_path)
    prog.wait_for_line("live: waiting for a viewer")
    prog.signal_group(signal.SIGINT)
    code, _, err = prog.finish(timeout=120)
    assert code == 1, err
    assert "Traceback" not in err and "failed" not in err, err
    from usv_mj.outputs.log import read_run

    log = read_run(tmp_path / "out" / "run.mcap")      # every vessel's log holds its run, with its end
    assert log.complete and log.notice == "" and set(log.runs) == {"main", "target"}, log.notice
    assert all(run.status == "interrupted" for run in log.runs.values())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fleet.toml", "out"]   # no lock, no staging folder


@pytest.mark.parametrize("wait", ["nan", "-1", "inf"])
def test_a_live_wait_that_is_not_a_finite_time_is_refused(tmp_path, wait):
    """Before: ``--live-wait nan`` was accepted and waited for ever (the deadline now + nan is never
    reached): a subprocess, bounded."""
    pytest.importorskip("foxglove", reason='pip install "usv_mj[live]"')
    prog = Group(["run", "--plant", "analytic", "--no-video", "-q", "--duration", "1", "--live", "--live-port", "0",
                  "--live-wait", wait, "--out", tmp_path / "out"], tmp_path)
    code, _, err = prog.finish(timeout=120)
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and f"--live-wait {float(wait)!r}" in err, err
    assert not (tmp_path / "out").exists()


def test_the_live_server_refuses_a_wait_that_is_not_a_finite_time():
    pytest.importorskip("foxglove", reason='pip install "usv_mj[live]"')
    from usv_mj.core.errors import ScenarioError
    from usv_mj.outputs.log.live import LiveServer

    for wait in (math.nan, -0.5, math.inf, "5"):
        with pytest.raises(ScenarioError, match="--live-wait"):
            LiveServer(port=0, wait_s=wait)


# --- cause 19: a signal while the benchmark's cluster starts ------------------------------------------


TINY_SUITE = """
name = "tiny"
episodes = 2
seed = 3
duration = 2.0
plant = "analytic"
controllers = ["ppc", "pi"]
[conditions.calm]
[[tasks]]
name = "line"
base = "paper"
set = { "trajectory.kind" = "line", "initial.eta" = [0.0, 0.0, 0.0] }
vary = { "initial.eta[1]" = { uniform = [-2.0, 2.0] } }
settle_time_s = 1.0
"""


def spawned_in_group(pgid: int) -> int:
    """How many processes of group ``pgid`` multiprocessing spawned (the cluster's workers)."""
    return sum(1 for pid in os.listdir("/proc") if pid.isdigit() and _spawned(int(pid), pgid))


class Bench(Group):
    """``python -m usv_mj.cli bench`` (the package's own entry, as the ``usv-mj`` script: its
    spawned workers import it again)."""

    def __init__(self, args, cwd):
        self.proc = subprocess.Popen([sys.executable, "-m", "usv_mj.cli", "bench", *map(str, args)], cwd=cwd,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     env={**os.environ, "PYTHONPATH": str(ROOT)}, start_new_session=True)
        self.lines = queue.Queue()
        self.err = []
        threading.Thread(target=self._read, daemon=True).start()


@pytest.mark.parametrize("sig, resume", [(signal.SIGINT, False), (signal.SIGHUP, True)])
def test_a_signal_while_the_cluster_starts_is_one_truthful_line(tmp_path, sig, resume):
    """Ctrl-C (the terminal signals every process of the group) or a hang-up while the local
    cluster's workers start. Before: ~150 lines of the workers' KeyboardInterrupt tracebacks and
    the scheduler's "Nanny failed to start"; after a hang-up each worker printed "interrupted
    (SIGHUP) while starting; nothing was written" (the workers import usv_mj.cli again and took
    the program's start-up handlers) although results.parquet held the episodes of a first pass."""
    from usv_mj.jobs.sweep.runner import read_results

    suite, out = tmp_path / "tiny.toml", tmp_path / "out"
    suite.write_text(TINY_SUITE)
    done = 0
    if resume:                  # a first pass leaves one episode in results.parquet
        first = Bench([suite, "--workers", "1", "--no-progress", "--max-runs", "1", "--out", out], tmp_path)
        code, _, err = first.finish(timeout=BOUND_S)
        assert code == 0, err
        done = len(read_results(out / "results.parquet")[0])
        assert done == 1
    prog = Bench([suite, "--workers", "2", "--no-progress", "--out", out, *(["--resume"] if resume else [])], tmp_path)
    prog.wait_until(lambda: spawned_in_group(prog.proc.pid) >= 2, "the cluster's workers starting")
    prog.signal_group(sig)
    code, _, err = prog.finish()
    assert code == 1, err
    lines = [line for line in err.splitlines() if line.strip()]
    held = len(read_results(out / "results.parquet")[0])
    assert held == done
    assert len(lines) == 1 and lines[0] == (
        f"usv-mj bench: interrupted: {held} of 4 episodes are in {out}/results.parquet; run the same command "
        "with --resume to finish"), err
