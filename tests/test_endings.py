"""Every ending tells the truth (issue 27, item 4): interrupted commands exit 1 with one line and
record the interruption; a burst of signals still leaves the summary; --max-runs submits only what
it runs. The signal tests wait for a condition the program reports (a line on stderr, a file that
grows), never a fixed time, and assert one outcome.
"""

from __future__ import annotations

import json
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


class Program:
    """``python -m usv_mj.cli.main ARGS`` with its stderr read line by line as it comes."""

    def __init__(self, args, cwd):
        self.proc = subprocess.Popen([sys.executable, "-m", "usv_mj.cli.main", *args], cwd=ROOT if cwd is None else cwd,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     env=dict(os.environ, PYTHONPATH=str(ROOT)))
        self.lines: queue.Queue = queue.Queue()
        self.err: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stderr:
            self.err.append(line)
            self.lines.put(line)
        self.lines.put(None)

    def wait_for_line(self, text: str, timeout: float = 300) -> None:
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                pytest.fail(f"no line with {text!r} in {timeout} s: {''.join(self.err)}")
            if line is None:
                pytest.fail(f"the program ended before a line with {text!r}: {''.join(self.err)}")
            if text in line:
                return

    def finish(self, timeout: float = 300) -> tuple[int, str, str]:
        out = self.proc.stdout.read()
        self.proc.wait(timeout)
        deadline = time.monotonic() + 10
        while self.lines.get(timeout=max(0.0, deadline - time.monotonic())) is not None:
            pass
        return self.proc.returncode, out, "".join(self.err)


def wait_until(condition, what: str, proc, timeout: float = 300):
    deadline = time.monotonic() + timeout
    while not condition():
        assert proc.poll() is None, f"the program ended before {what}"
        assert time.monotonic() < deadline, f"{what}: not in {timeout} s"
        time.sleep(0.02)          # a poll interval, not a wait for the outcome


# --- compare ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("phase, sig, name", [
    ("compare: closed loop", signal.SIGINT, "Ctrl-C"),       # before: exit 0, passed: true beside an interrupted run
    ("compare: open loop,", signal.SIGINT, "Ctrl-C"),        # before: SystemError: CPUDispatcher(...) traceback
    ("compare: closed loop", signal.SIGTERM, "SIGTERM"),     # before: exit 1, nothing printed
])
def test_an_interrupted_compare_exits_1_in_one_line_and_never_passes(tmp_path, phase, sig, name):
    out = tmp_path / "C"
    prog = Program(["compare", "--duration", "300", "--out", str(out)], None)
    prog.wait_for_line(phase)
    prog.proc.send_signal(sig)
    code, _, err = prog.finish()
    assert code == 1, err
    assert "Traceback" not in err and "SystemError" not in err, err
    last = [line for line in err.splitlines() if line.startswith("usv-mj compare:")]
    assert len(last) == 1 and "interrupted" in last[0] and name in last[0], err
    result = json.loads((out / "compare.json").read_text())
    assert result["passed"] is False and name in result["interrupted"]
    assert ("closed" in result["interrupted"]) == ("closed" in phase)


# --- a burst of signals to a run -----------------------------------------------------------------


@pytest.mark.parametrize("gaps_ms", [(10, 10), (30, 50)])
def test_a_burst_of_signals_still_leaves_the_summary_and_the_report(tmp_path, gaps_ms):
    """SIGTERM, SIGINT and SIGHUP 10-50 ms apart. Before: "finish failed: KeyboardInterrupt" and
    only run.mcap left."""
    out = tmp_path / "out"
    prog = Program(["run", "--plant", "analytic", "--no-video", "--no-baseline", "-q", "--duration", "3000",
                    "--out", str(out)], tmp_path)

    def running():   # the loop is writing chunks of rows into the staging folder's log
        logs = list(tmp_path.glob(".out.staging-*/run.mcap"))
        return bool(logs) and logs[0].stat().st_size > 300_000

    wait_until(running, "the run writing its log", prog.proc)
    for sig, gap in zip((signal.SIGTERM, signal.SIGINT, signal.SIGHUP), (*gaps_ms, 0)):
        prog.proc.send_signal(sig)
        time.sleep(gap / 1000)    # the case itself: signals this far apart
    code, _, err = prog.finish()
    assert code == 1, err
    assert "Traceback" not in err, err
    assert (out / "summary.json").is_file() and (out / "report.md").is_file(), (sorted(os.listdir(out)), err)
    summary = json.loads((out / "summary.json").read_text())
    # which one stopped the loop: the first Python ran (signals pending together are run in signal-number
    # order, SIGHUP, SIGINT, SIGTERM, so on a busy machine it need not be the first sent)
    names = [n for n in ("SIGTERM", "Ctrl-C", "SIGHUP") if n in summary["stop_reason"]]
    assert summary["status"] == "interrupted" and len(names) == 1, summary["stop_reason"]
    report = (out / "report.md").read_text()
    assert "interrupted" in report and names[0] in report


# --- sweep --max-runs --------------------------------------------------------------------------------


def test_max_runs_submits_only_the_runs_it_runs(tmp_path, monkeypatch):
    """Before: every run of the sweep was submitted (60,000 for --max-runs 10)."""
    from usv_mj.jobs.sweep import runner
    from usv_mj.jobs.sweep.spec import load_sweep

    path = tmp_path / "s.toml"
    path.write_text('base = "paper"\nduration = 0.2\nplant = "analytic"\nsamples = 20\nseed = 3\n'
                    'transient = 0.1\n[vary]\n"initial.eta[0]" = { uniform = [-1.0, 1.0] }\n')
    submitted = []

    def counting(client, jobs, on_row, *args, **kwargs):
        submitted.append(len(jobs))
        return gather(client, jobs, on_row, *args, **kwargs)

    gather = runner.gather_rows
    monkeypatch.setattr(runner, "gather_rows", counting)
    result = runner.run_sweep(load_sweep(path), tmp_path / "out", workers=1, max_runs=3, progress=False, echo=None)
    assert submitted == [3] and result.ran == 3 and not result.complete


# --- a damaged numba cache ----------------------------------------------------------------------------


def test_a_damaged_numba_cache_is_rebuilt_with_one_warning_line(tmp_path):
    """Files of numba's disk cache zeroed (as a full disk leaves them). Before: ``EOFError: Ran out of
    input`` on every later run. The same wrapper serves the compiled loops' cache (cache_dir()) and the
    package's own __pycache__: here a kernel of a module of its own, so that the test compiles in a second."""
    (tmp_path / "kern.py").write_text("from numba import njit\n\n\n@njit(cache=True)\ndef twice(x):\n"
                                      "    return 2.0 * x\n")
    code = "import usv_mj, kern; assert kern.twice(21.0) == 42.0; print('ok')"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(tmp_path)]))

    def run():
        return subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                              timeout=300)

    first = run()
    assert first.returncode == 0 and first.stderr == "", first.stderr
    cached = sorted((tmp_path / "__pycache__").glob("kern.twice-*.nb[ic]"))
    assert {p.suffix for p in cached} == {".nbi", ".nbc"}
    for p in cached:
        p.write_bytes(b"")
    damaged = run()
    assert damaged.returncode == 0 and damaged.stdout == "ok\n", damaged.stderr
    lines = damaged.stderr.splitlines()
    assert len(lines) == 1 and "damaged" in lines[0] and "compiled again" in lines[0] and ".nbi" in lines[0], lines
    again = run()                      # rebuilt: read from the cache again, no warning
    assert again.returncode == 0 and again.stderr == "", again.stderr


# --- overrides before the step-count check ----------------------------------------------------------------


def test_duration_flag_is_applied_before_the_step_count_is_checked(tmp_path):
    """``--duration 0.05 --set control_period=1e-6``: 50,000 steps. Before: refused, "over 5e7 steps",
    checked on the preset's 300 s."""
    from usv_mj.cli.main import main

    out = tmp_path / "o"
    assert main(["run", "--plant", "analytic", "--no-video", "--no-baseline", "-q", "--duration", "0.05",
                 "--set", "control_period=1e-6", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed" and abs(summary["simulated_s"] - 0.05) < 1e-9


# --- a cancelled sweep ------------------------------------------------------------------------------------


def test_a_cancelled_sweep_prints_one_line_not_the_schedulers_tracebacks(tmp_path):
    """Ctrl-C to ``usv-mj sweep -q`` with runs in flight. Before: the in-process Dask scheduler's
    CRITICAL "Closed comm ... lost-data" tracebacks and the workers' heartbeat ERRORs."""
    sweep = tmp_path / "s.toml"
    sweep.write_text('base = "paper"\nduration = 0.5\nplant = "analytic"\nsamples = 100\nseed = 11\n'
                     'transient = 0.1\n[vary]\n"initial.eta[0]" = { uniform = [-4.0, 4.0] }\n'
                     '"disturbance.scale" = [1e-4, 1e-3]\n')
    out = tmp_path / "out"
    prog = Program(["sweep", str(sweep), "-q", "--workers", "2", "--out", str(out)], None)
    wait_until(lambda: (out / "results.parquet").exists(), "the first rows written", prog.proc)
    prog.proc.send_signal(signal.SIGINT)
    code, _, err = prog.finish()
    assert code == 1
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "interrupted" in lines[0] and "--resume" in lines[0], err
