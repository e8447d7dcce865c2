"""What a sweep's and a benchmark's Dask workers must do (issue 34): run a scenario whose vessel is a
user's TOML data file, and, when a run cannot be set up on a worker, end the command within a bound
with one line naming the run and the cause (exit 1), never wait without end.

Every test runs the command line as a user does (``python -m usv_mj.cli``, a local cluster of 2
worker processes) with a time limit: on the old code the first two waited until killed.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
OTTER = ROOT / "usv_mj" / "vessels" / "data" / "otter.toml"

BASE = """
[vessel]
kind = "../vessels/boat.toml"
[trajectory]
kind = "line"
"""

SWEEP = """
base = "base.toml"
duration = 3.0
plant = "analytic"
samples = 4
seed = 1
transient = 1.0
[vary]
"initial.eta[1]" = { uniform = [-1.0, 1.0] }
"""

SUITE = """
name = "tiny"
episodes = 2
seed = 3
duration = 3.0
plant = "analytic"
controllers = CONTROLLERS
vessels = ["../vessels/boat.toml"]
[conditions.calm]
[[tasks]]
name = "line"
base = "base.toml"
set = { "initial.eta" = [0.0, 0.0, 0.0] }
vary = { "initial.eta[1]" = { uniform = [-1.0, 1.0] } }
settle_time_s = 2.0
"""

# Plug-in controllers that work in the process that read the scenario and break in any other one
# (a worker): one whose gains cannot be unpickled there, one that cannot be built there.
PLUGIN = '''
import dataclasses
import os

from usv_mj.controllers.pi_baseline import PIController, PIGains


def _unpickle(home, values):
    if os.getpid() != home:
        raise RuntimeError("poisoned gains: they unpickle only in the process that pickled them")
    return UnpicklableGains(**values)


@dataclasses.dataclass(frozen=True)
class UnpicklableGains(PIGains):
    def __reduce__(self):
        return _unpickle, (os.getpid(), dataclasses.asdict(self))


class UnpicklablePI(PIController):
    options = UnpicklableGains


@dataclasses.dataclass(frozen=True)
class HomeGains(PIGains):
    home: int = os.getpid()    # the process that made the scenario


class UnbuildablePI(PIController):
    options = HomeGains

    @classmethod
    def from_scenario(cls, gains, scenario):
        if gains.home != os.getpid():
            raise RuntimeError("poisoned controller: it builds only in the process that read its scenario")
        return super().from_scenario(gains, scenario)
'''

LIMIT = 60.0   # s: the bound on a command whose worker fails


@pytest.fixture
def folder(tmp_path):
    """A user's folder: vessels/boat.toml (the Otter's numbers under another name), sw/base.toml, and a
    plug-in module on PYTHONPATH (the workers inherit the environment)."""
    (tmp_path / "vessels").mkdir()
    (tmp_path / "vessels" / "boat.toml").write_text(OTTER.read_text())
    sw = tmp_path / "sw"
    sw.mkdir()
    (sw / "base.toml").write_text(BASE)
    (tmp_path / "plug").mkdir()
    (tmp_path / "plug" / "poison_plugin.py").write_text(textwrap.dedent(PLUGIN))
    return tmp_path


def _cli(folder, *args, timeout, env=None):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(folder / "plug")]), **(env or {}))
    try:
        return subprocess.run([sys.executable, "-m", "usv_mj.cli", *args], cwd=folder / "sw", env=env,
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as exc:   # the old code: the parent waits with 0 runs done
        pytest.fail(f"usv-mj {args[0]} still waiting after {timeout} s; stderr so far: {exc.stderr!r}")


def test_a_data_file_vessels_options_unpickle_in_a_fresh_process(folder):
    """The options class is made at runtime from the file: a process that never read the file (a
    worker) rebuilds it from what the pickle carries, with the same values."""
    code = textwrap.dedent("""
        import pickle, sys
        from usv_mj.scenario.spec import load_scenario
        s = load_scenario(sys.argv[1])
        sys.stdout.buffer.write(pickle.dumps(s.vessel.options))
    """)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    blob = subprocess.run([sys.executable, "-c", code, str(folder / "sw" / "base.toml")], env=env,
                          capture_output=True, check=True).stdout
    (folder / "vessels" / "boat.toml").unlink()          # the worker needs no file: the pickle carries it
    check = textwrap.dedent("""
        import pickle, sys
        o = pickle.loads(sys.stdin.buffer.read())
        from usv_mj.core.registry import VESSELS
        entry = VESSELS.get(sys.argv[1])
        assert type(o) is entry.options_class, (type(o), entry.options_class)
        print(o.m, o.L, o.X_u)
    """)
    out = subprocess.run([sys.executable, "-c", check, str(folder / "vessels" / "boat.toml")], input=blob,
                         env=env, capture_output=True, check=True).stdout.decode().split()
    import tomllib

    data = tomllib.loads(OTTER.read_text())
    assert [float(v) for v in out] == [data["derivatives"]["m"], data["dimensions"]["L"], data["derivatives"]["X_u"]]


def test_a_sweep_and_a_benchmark_with_a_data_file_vessel_complete_on_two_workers(folder):
    (folder / "sw" / "sweep.toml").write_text(SWEEP)
    done = _cli(folder, "sweep", "sweep.toml", "--out", str(folder / "out"), "--workers", "2", "--no-progress",
                timeout=240)
    assert done.returncode == 0, done.stderr
    from usv_mj.jobs.sweep.runner import read_results

    rows, _ = read_results(folder / "out" / "results.parquet")
    assert [r["run_id"] for r in rows] == [0, 1, 2, 3]
    assert all(r["status"] == "ok" and r["simulated_s"] == pytest.approx(3.0) for r in rows), rows

    (folder / "sw" / "suite.toml").write_text(SUITE.replace("CONTROLLERS", '["pi", "ppc"]'))
    done = _cli(folder, "bench", "suite.toml", "--out", str(folder / "bench"), "--workers", "2", "--no-progress",
                "--no-figures", timeout=240)
    assert done.returncode == 0, done.stderr
    rows, _ = read_results(folder / "bench" / "results.parquet")
    assert len(rows) == 4 and all(r["status"] == "ok" for r in rows), rows   # 2 controllers x 2 episodes
    assert {r["vary.vessel"] for r in rows} == {"../vessels/boat.toml"}


@pytest.mark.parametrize("plugin, stage, cause", [
    ("UnpicklablePI", "unpickling its scenario", "RuntimeError: poisoned gains"),
    ("UnbuildablePI", "building it", "RuntimeError: poisoned controller"),
])
def test_a_run_that_cannot_be_set_up_on_a_worker_ends_the_sweep_and_the_bench(folder, plugin, stage, cause):
    (folder / "sw" / "base.toml").write_text(BASE + f'[controller]\nkind = "poison_plugin:{plugin}"\n')
    (folder / "sw" / "sweep.toml").write_text(SWEEP)
    done = _cli(folder, "sweep", "sweep.toml", "--out", str(folder / "out"), "--workers", "2", "--no-progress",
                timeout=LIMIT)
    assert done.returncode == 1, (done.stdout, done.stderr)
    lines = [l for l in done.stderr.splitlines() if l.startswith("usv-mj sweep:")]
    assert len(lines) == 1, done.stderr
    assert "could not be set up on worker tcp://" in lines[0] and f"({stage})" in lines[0] and cause in lines[0]
    assert lines[0].startswith("usv-mj sweep: stopped: run ") and int(lines[0].split()[4]) in range(4)
    assert "Traceback" not in done.stderr

    (folder / "sw" / "suite.toml").write_text(SUITE.replace("CONTROLLERS",
                                                            f'[{{ name = "bad", kind = "poison_plugin:{plugin}" }}]'))
    (folder / "sw" / "base.toml").write_text(BASE)
    done = _cli(folder, "bench", "suite.toml", "--out", str(folder / "bench"), "--workers", "2", "--no-progress",
                "--no-figures", timeout=LIMIT)
    assert done.returncode == 1, (done.stdout, done.stderr)
    lines = [l for l in done.stderr.splitlines() if l.startswith("usv-mj bench:")]
    assert len(lines) == 1 and f"({stage})" in lines[0] and cause in lines[0], done.stderr
    assert "Traceback" not in done.stderr


def test_a_setup_error_crosses_back_from_the_worker_whole():
    """The exception a worker raises is pickled back to the parent: its run, stage and cause survive."""
    from usv_mj.core.errors import WorkerError, WorkerSetupError

    exc = pickle.loads(pickle.dumps(WorkerSetupError(3, "building it", "RuntimeError: no", "tcp://h:1")))
    assert isinstance(exc, WorkerError) and (exc.run_id, exc.stage, exc.cause) == (3, "building it", "RuntimeError: no")
    assert str(exc) == "run 3 could not be set up on worker tcp://h:1 (building it): RuntimeError: no"


def test_runs_that_raise_or_kill_their_worker_are_named_and_exit_1(folder):
    """A run that raises once running and one whose worker dies are recorded as failed rows (the sweep
    goes on); the command then names each with its reason and exits 1 instead of 0."""
    (folder / "sw" / "sweep.toml").write_text(SWEEP.replace('base = "base.toml"', 'base = "paper"')
                                              + "[test_hooks]\nraise = [1]\nexit_worker = [2]\n")
    # the hooks read; a task that took down one worker is given up (KilledWorker) at once
    env = {"USV_MJ_SWEEP_TEST_HOOKS": "1", "DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "0"}
    done = _cli(folder, "sweep", "sweep.toml", "--out", str(folder / "out"), "--workers", "2", "--no-progress",
                timeout=240, env=env)
    assert done.returncode == 1, (done.stdout, done.stderr)
    lines = [l for l in done.stderr.splitlines() if l.startswith("usv-mj sweep:")]
    assert lines[0] == "usv-mj sweep: run 1 failed: RuntimeError: test hook: run 1 raises", done.stderr
    assert lines[1].startswith("usv-mj sweep: run 2 failed: worker died"), done.stderr
    assert "2 run(s) failed" in lines[2] and "--retry-failed" in lines[2]
    assert "Traceback" not in done.stderr


def test_a_cluster_that_lost_every_worker_stops_the_sweep(tmp_path, monkeypatch):
    """A scheduler whose only worker is killed mid-run (no nanny brings it back): the sweep stops
    after ``lost_workers_s`` with the reason, instead of waiting for a worker forever."""
    import signal
    import socket
    import time

    from distributed import Client

    from usv_mj.core.errors import WorkerError
    from usv_mj.jobs.sweep import load_sweep, run_sweep
    from usv_mj.jobs.sweep.spec import TEST_HOOKS_ENV

    release = tmp_path / "release"   # never made: run 0 holds its worker until the worker is killed
    monkeypatch.setenv(TEST_HOOKS_ENV, "1")
    monkeypatch.setenv("USV_MJ_SWEEP_TEST_RELEASE", str(release))
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP.replace('base = "base.toml"', 'base = "paper"') + "[test_hooks]\nhold = [0, 1, 2, 3]\n")
    plan = load_sweep(path)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    procs = [subprocess.Popen(["dask", "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)]
    try:
        procs.append(subprocess.Popen(["dask", "worker", address, "--nthreads", "1", "--no-nanny",
                                       "--no-dashboard"], env=env, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL, start_new_session=True))
        with Client(address, timeout="60s") as client:
            client.wait_for_workers(1, timeout=120)
            worker = procs[1]

            def kill_when_held():       # once a run holds the worker, the worker goes for good
                deadline = time.monotonic() + 120
                while not any(tmp_path.glob("release.started-*")) and time.monotonic() < deadline:
                    time.sleep(0.05)    # a poll interval
                os.killpg(worker.pid, signal.SIGKILL)

            import threading

            killer = threading.Thread(target=kill_when_held, daemon=True)
            killer.start()
            t0 = time.monotonic()
            with pytest.raises(WorkerError, match="every Dask worker has been gone for 3 s"):
                run_sweep(plan, tmp_path / "out", client=client, progress=False, echo=None, lost_workers_s=3.0)
            assert time.monotonic() - t0 < LIMIT
            killer.join(timeout=5)
    finally:
        for p in reversed(procs):
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            p.wait(timeout=20)
    from usv_mj.jobs.sweep.runner import read_results

    rows, _ = read_results(tmp_path / "out" / "results.parquet")
    assert rows == []    # nothing finished; --resume runs all four
