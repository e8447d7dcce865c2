"""Issue 38, cause 13: file-system oddities beside a run log. A FIFO named ``*.mcap`` is never
opened (opening one waits for a writer that never comes), and a symbolic-link loop named
``*.mcap`` is not a log: neither hangs nor fails the reading of the logs beside them (``read_run``
looks at every ``*.mcap`` of the folder for companions), and each, named itself, is one line.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from usv_mj.cli.main import main



@pytest.fixture(scope="module")
def run_folder(tmp_path_factory):
    """A short run with its baseline (run.mcap + its companion baseline.mcap)."""
    out = tmp_path_factory.mktemp("odd") / "run"
    assert main(["run", "--plant", "analytic", "--no-video", "-q", "--duration", "1", "--out", str(out)]) == 0
    return out


def _read_in_a_thread(path, timeout=60):
    """read_run(path) with a bound (a FIFO used to block its open() for ever)."""
    import threading

    from usv_mj.outputs.log import read_run

    box = {}

    def go():
        try:
            box["log"] = read_run(path)
        except BaseException as exc:  # noqa: BLE001 - handed to the test
            box["error"] = exc

    t = threading.Thread(target=go, daemon=True)
    t.start()
    t.join(timeout)
    if t.is_alive():
        pytest.fail(f"read_run({path}) did not return in {timeout} s")
    if "error" in box:
        raise box["error"]
    return box["log"]


@pytest.mark.parametrize("odd", ["fifo", "loop"])
def test_an_odd_mcap_beside_a_log_is_passed_over(run_folder, tmp_path, capsys, odd):
    """Before: the FIFO blocked read_run, inspect and plot for ever; the loop failed them
    ("internal error: RuntimeError: Symlink loop"). read_run goes first, bounded: the commands
    after it read the same way."""
    folder = tmp_path / "run"
    folder.mkdir()
    for name in ("run.mcap", "baseline.mcap"):
        (folder / name).write_bytes((run_folder / name).read_bytes())
    if odd == "fifo":
        os.mkfifo(folder / "a.mcap")      # sorts before run.mcap: read first
    else:
        os.symlink("a.mcap", folder / "a.mcap")
    log = _read_in_a_thread(folder / "run.mcap")
    assert log.complete and set(log.runs) == {"main", "baseline"}
    assert len(log.runs["baseline"]) == len(log.runs["main"]) == 1001
    assert main(["inspect", str(folder / "run.mcap")]) == 0, capsys.readouterr().err
    assert main(["plot", str(folder / "run.mcap"), "--out", str(tmp_path / "plots")]) == 0, capsys.readouterr().err
    assert (tmp_path / "plots" / "report.md").is_file()


@pytest.mark.parametrize("odd, why", [("fifo", "is not a regular file"), ("loop", "symbolic link")])
def test_an_odd_mcap_named_itself_is_one_line(tmp_path, capsys, odd, why):
    """Before: read_run of the FIFO blocked; the loop was "no such file"."""
    path = tmp_path / "a.mcap"
    if odd == "fifo":
        os.mkfifo(path)
    else:
        os.symlink("a.mcap", path)
    from usv_mj.outputs.log.reader import RunLogReadError

    with pytest.raises(RunLogReadError, match=why):
        _read_in_a_thread(path)
    capsys.readouterr()
    for args in (["inspect", str(path)], ["plot", str(path), "--out", str(tmp_path / "p")]):
        assert main(args) == 2
        err = capsys.readouterr().err
        lines = err.strip().splitlines()
        assert len(lines) == 1 and str(path) in lines[0] and why in lines[0], err
