"""Issue 15: every run ends with its reason recorded; bad input leaves --out as it was; nothing mixed.

Each test names the cause of the issue it covers. Runs are short (analytic plant, no video, no
baseline) so that the whole file stays well under three minutes on two cores.
"""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from usv_mj.cli.main import main

FAST = ["run", "--plant", "analytic", "--no-video", "--no-baseline", "-q"]


def cli(args, cwd, timeout=120, **kw):
    return subprocess.run([sys.executable, "-m", "usv_mj.cli.main", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=timeout, **kw)


def snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def leftovers(parent: Path) -> list:
    return [p.name for p in parent.rglob("*") if p.name.endswith(".tmp") or ".staging-" in p.name
            or ".old-" in p.name or p.name.startswith(".render-")]


def fake_run(folder: Path) -> dict:
    folder.mkdir(parents=True)
    (folder / "summary.json").write_text('{"old": true}\n')
    (folder / "report.md").write_text("old report\n")
    (folder / "run.mcap").write_bytes(b"old log")
    return snapshot(folder)


def one_line(stderr: str) -> str:
    lines = [ln for ln in stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, stderr
    assert "Traceback" not in stderr
    return lines[0]


# --- cause 1: a camera the render model lacks --------------------------------------------------


def test_bad_camera_is_refused_up_front_not_retried_forever(tmp_path):
    t0 = time.perf_counter()
    proc = cli(["run", "--plant", "analytic", "--duration", "2", "--no-baseline", "-q", "--camera", "nope",
                "--size", "160x96", "--workers", "1", "--out", str(tmp_path / "o")], tmp_path, timeout=60)
    assert proc.returncode == 2, proc.stderr
    line = one_line(proc.stderr)
    assert "--camera" in line and "'nope'" in line
    assert line.endswith("top, overview, chart, chase")   # cause 9: each camera once
    assert not (tmp_path / "o").exists() and time.perf_counter() - t0 < 60


def test_render_worker_that_cannot_start_fails_the_render(tmp_path):
    """A worker whose set-up raises (here: an unknown layer) fails the render with the reason,
    instead of the pool starting new workers forever."""
    code = (
        "import sys\n"
        "from usv_mj import load_scenario, simulate\n"
        "from usv_mj.outputs.render import RenderWorkers, GLUnavailableError\n"
        "from usv_mj.outputs.render.video import render_run\n"
        "if __name__ == '__main__':\n"
        "    rec = simulate(load_scenario(overrides={'duration': 0.2, 'plant': {'kind': 'analytic'}}))\n"
        "    try:\n"
        "        pool = RenderWorkers(width=160, height=96, workers=1, layers=('bogus',))\n"
        "    except GLUnavailableError as exc:\n"
        "        print('NOGL', exc); sys.exit(0)\n"
        "    with pool:\n"
        "        try:\n"
        "            render_run(rec, sys.argv[1], pool=pool, progress=False, width=160, height=96, workers=1,\n"
        "                       layers=('bogus',))\n"
        "        except Exception as exc:\n"
        "            print('FAILED', type(exc).__name__, exc); sys.exit(1)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code, str(tmp_path / "v.mp4")], capture_output=True, text=True,
                          timeout=90, cwd=tmp_path)
    if proc.stdout.startswith("NOGL"):
        pytest.skip(f"no GL stack here: {proc.stdout}")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "could not start" in proc.stdout or "unknown render layers" in proc.stdout, proc.stdout
    assert proc.stderr.count("Traceback") <= 1


# --- causes 2 and 3: rejected input writes nothing; runs never mixed -------------------------------


def test_start_pose_inside_obstacle_leaves_earlier_run_untouched(tmp_path):
    before = fake_run(tmp_path / "out")
    sc = tmp_path / "sc.toml"
    sc.write_text('[initial]\neta = [0.0, 0.0, 0.0]\n[[obstacles]]\nkind = "circle"\ncenter = [0.0, 0.0]\n'
                  'radius = 2.0\n')
    code = main([*FAST, "--duration", "1", "--scenario", str(sc), "--out", str(tmp_path / "out"), "--overwrite"])
    assert code == 2
    assert snapshot(tmp_path / "out") == before and leftovers(tmp_path) == []


def test_out_holding_a_run_is_refused_then_replaced_whole_with_overwrite(tmp_path, capsys):
    out = tmp_path / "out"
    fake_run(out)
    (out / "figures").mkdir()
    (out / "figures" / "sea_loads.png").write_bytes(b"old sea figure")
    before = snapshot(out)
    assert main([*FAST, "--duration", "0.3", "--no-log", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--out {out}: already holds a run" in err and "--overwrite" in err
    assert snapshot(out) == before
    assert main([*FAST, "--duration", "0.3", "--no-log", "--out", str(out), "--overwrite"]) == 0
    names = set(snapshot(out))
    assert "run.mcap" not in names and "figures/sea_loads.png" not in names     # the old run is gone whole
    assert json.loads((out / "summary.json").read_text())["status"] == "completed"
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("case", ["empty", "file", "under-file"])
def test_bad_out_is_refused_before_anything(tmp_path, capsys, case):
    (tmp_path / "afile").write_text("x")
    out = {"empty": "", "file": str(tmp_path / "afile"), "under-file": str(tmp_path / "afile" / "sub")}[case]
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        assert main([*FAST, "--duration", "0.3", "--out", out]) == 2
    finally:
        os.chdir(cwd)
    assert "--out" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def _mount(*args):
    proc = subprocess.run(["mount", *args], capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.skip(f"mount {' '.join(args)} refused here: {proc.stderr.strip()}")


def test_read_only_out_is_refused_before_the_simulation(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    _mount("-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(ro))
    try:
        t0 = time.perf_counter()
        assert main([*FAST, "--duration", "30", "--out", str(ro / "run")]) == 2
        err = capsys.readouterr().err
        assert f"--out {ro / 'run'}: cannot write in {ro}" in err
        assert time.perf_counter() - t0 < 5           # refused before the 30 s run
    finally:
        subprocess.run(["umount", str(ro)])


def test_killed_runs_staging_is_cleaned_up_by_the_next_run(tmp_path):
    dead = tmp_path / ".out.staging-999999999"
    dead.mkdir()
    (dead / ".usv_mj-staging").touch()    # what a job leaves in its staging folder until it ends
    (dead / "run.mcap.tmp").write_bytes(b"x")
    assert main([*FAST, "--duration", "0.3", "--no-log", "--out", str(tmp_path / "out")]) == 0
    assert leftovers(tmp_path) == []


# --- cause 4: signals ------------------------------------------------------------------------------


def _start(tmp_path, *extra):
    env = dict(os.environ, PYTHONWARNINGS="default")
    # long enough (600 s on the MuJoCo plant, 10 s or more of wall time) that the signal lands inside the loop
    return subprocess.Popen([sys.executable, "-m", "usv_mj.cli.main", *FAST, "--plant", "mujoco", "--duration", "600", *extra,
                             "--out", str(tmp_path / "out")], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)


def _wait_for_staging(tmp_path, proc, seconds=300):
    """Until the loop is running: the staging folder's log holds a complete chunk of rows (the run
    reports it by writing it), not a fixed time."""
    from usv_mj.outputs.log.reader import RunLogReadError, scan_summary

    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        staging = list(tmp_path.glob(".out.staging-*"))
        log = staging[0] / "run.mcap" if staging else None
        if log is not None and log.exists() and log.stat().st_size > 0:
            try:
                if scan_summary(log)["topics"].get("/usv/state", {}).get("count", 0) > 0:
                    return
            except (RunLogReadError, OSError):   # the header not written yet
                pass
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)              # a poll interval
    pytest.fail("the run never started")


@pytest.mark.parametrize("sig,name", [(signal.SIGTERM, "SIGTERM"), (signal.SIGINT, "Ctrl-C"),
                                      (signal.SIGHUP, "SIGHUP")])
def test_signal_during_the_run_is_recorded_everywhere(tmp_path, sig, name):
    proc = _start(tmp_path)
    _wait_for_staging(tmp_path, proc)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 1, err
    assert "leaked" not in err and "Traceback" not in err, err
    assert not (tmp_path / "out" / "traceback.txt").exists(), (tmp_path / "out" / "traceback.txt").read_text()
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "interrupted" and name in summary["stop_reason"]
    assert name in (tmp_path / "out" / "report.md").read_text()
    from usv_mj.outputs.log import read_run

    log = read_run(tmp_path / "out" / "run.mcap")
    assert log.complete and log.record.status == "interrupted"
    assert leftovers(tmp_path) == []


def test_ctrl_c_after_the_simulation_leaves_a_truthful_summary(tmp_path, monkeypatch):
    import usv_mj.jobs.run as mj

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(mj, "draw_figures", interrupted)
    out = tmp_path / "out"
    assert main([*FAST, "--duration", "0.5", "--out", str(out)]) == 1
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "completed" and "while drawing the figures" in s["job_stopped"]
    assert s["missing_outputs"] == ["figures/"]
    assert "job stopped early" in (out / "report.md").read_text()
    from usv_mj.outputs.log import read_run

    assert read_run(out / "run.mcap").complete and leftovers(tmp_path) == []


def test_second_ctrl_c_ends_at_once_with_a_readable_log(tmp_path, monkeypatch):
    import usv_mj.jobs.run as mj

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(mj, "draw_figures", interrupted)
    monkeypatch.setattr(mj, "write_report", interrupted)      # the second Ctrl-C, while the report is written
    out = tmp_path / "out"
    assert main([*FAST, "--duration", "0.5", "--out", str(out)]) == 1
    from usv_mj.outputs.log import read_run

    assert read_run(out / "run.mcap").complete
    assert json.loads((out / "summary.json").read_text())["job_stopped"]
    assert leftovers(tmp_path) == []


# --- cause 5: a full disk ------------------------------------------------------------------------


def test_full_disk_gives_one_line_and_a_log_readable_to_its_last_chunk(tmp_path):
    full = tmp_path / "full"
    full.mkdir()
    _mount("-t", "tmpfs", "-o", "size=2m", "tmpfs", str(full))
    try:
        proc = cli([*FAST, "--duration", "6", "--out", str(full / "run")], tmp_path, timeout=120)
        assert proc.returncode == 1, proc.stderr
        line = one_line(proc.stderr)
        assert "No space left on device" in line and str(full / "run") in line and ".staging" not in line
        from mcap.reader import make_reader

        with open(full / "run" / "run.mcap", "rb") as f:      # the mcap library's CRC-checking reader
            assert sum(1 for _ in make_reader(f, validate_crcs=True).iter_messages()) > 0
        assert leftovers(full) == []
    finally:
        subprocess.run(["umount", str(full)])


# --- cause 6: waypoint paths checked before anything ---------------------------------------------


@pytest.mark.parametrize("table", [
    "points = []", "points = [[0.0, 0.0]]", "points = [[0.0, 0.0], [0.0, 0.0], [10.0, 0.0]]",
    "turn_radius = -1.0", "points = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]]\nturn_radius = 50.0",
    "points = [[0.0, 0.0], [10.0, 0.0], [0.0, 0.0]]",
])
def test_bad_waypoint_path_is_bad_input(tmp_path, capsys, table):
    sc = tmp_path / "wp.toml"
    sc.write_text(f'[trajectory]\nkind = "waypoints"\n{table}\n')
    assert main([*FAST, "--duration", "1", "--scenario", str(sc), "--out", str(tmp_path / "o")]) == 2
    line = one_line(capsys.readouterr().err)
    assert str(sc) in line
    assert not (tmp_path / "o").exists() and leftovers(tmp_path) == []


# --- cause 7: one line instead of a traceback ----------------------------------------------------


@pytest.mark.parametrize("args,needle", [
    (["--scenario", "latin1.toml"], "latin1.toml: not a UTF-8"),
    (["--scenario", "ctrl.toml"], "ctrl.toml: [controller] must be a table"),
    (["--set", "baseline=5"], "[baseline] must be a table"),
    (["--set", "plant=5"], "--set plant=5"),
    (["--scenario", "preset.toml"], "preset.toml: preset: unknown preset 'nonexistent'"),   # cause 9
])
def test_bad_values_are_one_line(tmp_path, capsys, monkeypatch, args, needle):
    (tmp_path / "latin1.toml").write_bytes('duration = 1.0 # caf\xe9\n'.encode("latin-1"))
    (tmp_path / "ctrl.toml").write_text("controller = 5\n")
    (tmp_path / "preset.toml").write_text('preset = "nonexistent"\n')
    monkeypatch.chdir(tmp_path)
    assert main([*FAST, "--duration", "1", *args, "--out", "o"]) == 2
    assert needle in one_line(capsys.readouterr().err)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("content", [b"", b"hello, not a log\n"])
def test_plot_of_a_bad_log_is_one_line(tmp_path, capsys, content):
    (tmp_path / "run.mcap").write_bytes(content)
    assert main(["plot", str(tmp_path / "run.mcap")]) == 2
    assert str(tmp_path / "run.mcap") in one_line(capsys.readouterr().err)


# --- cause 8: a crash in the loop ----------------------------------------------------------------


def test_crash_in_the_loop_is_one_line_recorded_with_a_traceback_file(tmp_path, capsys, monkeypatch):
    from usv_mj.controllers.ppc import PPCController, PPCGains
    from usv_mj.core.registry import CONTROLLERS

    class Crashing(PPCController):  # a user's controller in Python: the loop runs its __call__
        name = "crashing"

        def __call__(self, t, state, reference):
            if t > 0.2:
                raise ZeroDivisionError("boom in the controller")
            return super().__call__(t, state, reference)

    CONTROLLERS.register("crashing", gains=PPCGains)(Crashing)
    try:
        out = tmp_path / "out"
        assert main([*FAST, "--duration", "1", "--set", "controller.kind=crashing", "--out", str(out)]) == 1
    finally:
        CONTROLLERS.unregister("crashing")
    line = one_line(capsys.readouterr().err)
    assert "ZeroDivisionError: boom in the controller" in line and "traceback.txt" in line
    assert "boom in the controller" in (out / "traceback.txt").read_text()
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and "boom" in s["stop_reason"]
    assert "boom" in (out / "report.md").read_text()
    from usv_mj.outputs.log import read_run

    log = read_run(out / "run.mcap")
    assert log.record.status == "failed" and len(log.record) > 100
    assert leftovers(tmp_path) == []


def test_the_summary_line_of_a_baseline_that_did_not_run():
    """A job stopped between the main run and the baseline: ``usv-mj run`` prints the baseline's
    status and reason (it raised KeyError on the missing violation count)."""
    from pathlib import Path

    from usv_mj import load_scenario, simulate, summarize
    from usv_mj.jobs.run import JobResult, one_screen_summary

    rec = simulate(load_scenario(preset="paper", overrides={"duration": 0.2, "plant": {"kind": "analytic"}}))
    summary = summarize(rec)
    summary["baseline"] = {"status": "not run", "stop_reason": "interrupted (SIGHUP) while starting the video"}
    text = one_screen_summary(JobResult(out_dir=Path("."), record=rec, summary=summary), 1.0)
    assert "PI baseline: not run (interrupted (SIGHUP) while starting the video)" in text
