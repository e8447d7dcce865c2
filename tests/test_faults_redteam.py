"""What the red-team of this session found (534 bad inputs and faults tried, 73 broke): each cause,
fixed, with the promise it broke. Bad input: exit 2, one line naming the flag or key, nothing written.
"""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from usv_mj.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
FAST = ["run", "--plant", "analytic", "--no-video", "--no-baseline", "-q", "--duration", "1"]


def one_line_error(capsys, *needles):
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("usv-mj") and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err
    return err


@pytest.mark.parametrize("argv, needle", [
    (["run", "--fps", "1e9"], "--fps"),            # it filled 24 GB before the kernel killed it
    (["run", "--workers", "0"], "--workers"),
    (["render", "x.mcap", "--fps", "100000"], "--fps"),
    (["frob"], "frob"),
    (["env", "swim"], "swim"),
    (["run", "--size", "abcxdef"], "--size"),
])
def test_bad_options_are_one_line(capsys, argv, needle):
    assert main(argv) == 2
    one_line_error(capsys, needle)


def test_a_preset_is_a_name_not_a_path(tmp_path, capsys):
    assert main([*FAST, "--preset", "../presets/paper", "--out", str(tmp_path / "o")]) == 2
    one_line_error(capsys, "unknown preset")
    assert main(["presets", "../presets/paper"]) == 2
    assert not (tmp_path / "o").exists()


def test_outputs_that_cannot_be_made_are_refused_up_front(tmp_path, capsys):
    afile = tmp_path / "afile"
    afile.write_text("x")
    for argv in (["sweep", str(ROOT / "examples/sweeps/quick.toml"), "--out", str(afile)],
                 ["capability", "--load", "current", "--out", str(afile)],
                 ["compare", "--duration", "1", "--out", str(afile)],
                 [*FAST, "--out", str(tmp_path / ("n" * 300))]):
        assert main(argv) == 2, argv
        one_line_error(capsys)
    assert afile.read_text() == "x" and sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_out_the_current_folder_or_the_root_is_refused(tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    for out in (".", "/"):
        proc = subprocess.run([sys.executable, "-m", "usv_mj.cli.main", *FAST, "--out", out, "--overwrite"],
                              cwd=tmp_path, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2 and "current folder, the root or a mount point" in proc.stderr, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]


def test_deeply_nested_toml_is_bad_input(tmp_path, capsys):
    path = tmp_path / "deep.toml"
    path.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    assert main([*FAST, "--scenario", str(path), "--out", str(tmp_path / "o")]) == 2
    one_line_error(capsys, "nested too deeply")


def test_impossible_guidance_is_bad_input_before_anything_is_written(tmp_path, capsys):
    path = tmp_path / "g.toml"
    path.write_text('[[obstacles]]\nkind = "circle"\ncenter = [30.0, 0.0]\nradius = 1.0\n[guidance]\navoid = true\n')
    assert main([*FAST, "--scenario", str(path), "--out", str(tmp_path / "o")]) == 2
    one_line_error(capsys, "guidance", "waypoints")
    goal = tmp_path / "goal.toml"     # the goal inside an (inflated) obstacle
    goal.write_text('[initial]\neta = [0.0, 0.0, 0.0]\n[trajectory]\nkind = "waypoints"\n'
                    'points = [[0.0, 0.0], [40.0, 0.0]]\n[[obstacles]]\nkind = "circle"\ncenter = [40.0, 0.0]\n'
                    'radius = 3.0\n[guidance]\navoid = true\n')
    assert main([*FAST, "--scenario", str(goal), "--out", str(tmp_path / "o")]) == 2
    one_line_error(capsys, "goal")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("argv, needle", [
    (["--set", "duration=abc", "--duration", "1"], "duration"),     # the flag used to hide the bad --set
    (["--set", "plant.kind=warp"], "warp"),
    (["--sea", ""], "sea preset"),
    (["--set", "sea.waves.components=100000000", "--set", "sea.waves.hs=0.2"], "components"),
])
def test_bad_values_hidden_by_flags_or_too_large_are_bad_input(tmp_path, capsys, argv, needle):
    assert main([*FAST, *argv, "--out", str(tmp_path / "o")]) == 2
    one_line_error(capsys, needle)
    assert not (tmp_path / "o").exists()


def test_a_second_run_into_the_same_out_while_one_runs_is_refused(tmp_path, capsys):
    from usv_mj.jobs.run import _OutLock

    out = tmp_path / "o"
    with _OutLock(out):                        # another job holds the folder
        assert main([*FAST, "--out", str(out)]) == 2
        one_line_error(capsys, "another run is writing")
    assert main([*FAST, "--out", str(out)]) == 0   # and after it, the folder is free
    assert not list(tmp_path.glob(".*.lock"))


def _catches(pid: int, sig: int) -> bool:
    """The process has a handler for ``sig`` (Linux: the SigCgt mask of /proc/PID/status)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("SigCgt:"):
            return bool(int(line.split()[1], 16) >> (sig - 1) & 1)
    return False


def test_sigterm_while_starting_up_exits_1_not_killed(tmp_path):
    """SIGTERM as soon as the program handles it (usv_mj.cli.main's first lines, before the imports and
    long before run_job's handlers): exit 1, one line, nothing left. The run is long (600 s), so
    the signal always lands before it ends: one outcome (before: a fixed 0.6 s wait, and exit 0 or 1)."""
    proc = subprocess.Popen([sys.executable, "-m", "usv_mj.cli.main", *FAST[:-1], "600", "--out", str(tmp_path / "o")],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not _catches(proc.pid, signal.SIGTERM):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.001)                       # a poll interval
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 1, (proc.returncode, err)
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert not [p for p in tmp_path.rglob("*") if ".staging-" in p.name]


def test_a_sweep_with_no_cluster_leaves_out_as_it_was(tmp_path, capsys):
    out = tmp_path / "jq"
    assert main(["sweep", str(ROOT / "examples/sweeps/quick.toml"), "--jobqueue", "nope", "-q",
                 "--out", str(out)]) == 2
    assert "unknown batch system" in capsys.readouterr().err
    assert not out.exists()                      # so the corrected command is not refused


def test_second_pass_findings(tmp_path, capsys):
    """The second red-team pass: a bad value in the file that a flag replaces, a named pipe as an
    input, outputs into the root or onto the input log; each is bad input in one line."""
    bad = tmp_path / "bad.toml"
    bad.write_text("duration = -5.0\n")
    assert main([*FAST, "--scenario", str(bad), "--out", str(tmp_path / "o")]) == 2   # --duration 1 hid it
    one_line_error(capsys, "duration")
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    assert main([*FAST, "--scenario", str(fifo), "--out", str(tmp_path / "o")]) == 2   # used to hang
    one_line_error(capsys, "not a regular file")
    assert main(["inspect", str(fifo)]) == 2
    one_line_error(capsys, "not a regular file")
    assert main(["compare", "--duration", "1", "-q", "--out", "/"]) == 2
    one_line_error(capsys, "root")
    assert main(["env", "track", "--duration", "1", "--video", "/dev/null"]) == 2
    one_line_error(capsys, ".mp4")
    assert not (tmp_path / "o").exists()
