"""Issue 38, refusing before writing and one line for the file system's refusals (causes 1, 18).

``usv-mj scene --out F`` follows the rule of ``render`` (usv_mj.outputs.outdir.check_file): a file
that no usv_mj command wrote, or a symbolic link, is refused before anything is built, and the
file is written whole or not at all (usv_mj.outputs.outdir.write_file). What the file system
refuses while a command writes (a full disk) is one line naming the path and the reason, exit 1;
what can be told before (a read-only folder) is bad input, exit 2, before anything is written.
Never "internal error ... a defect of usv_mj".
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import subprocess
from pathlib import Path

import pytest

from usv_mj.cli.main import main

MANIFEST = ".usv_mj-manifest.json"


def one_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err and "internal error" not in err, err
    return lines[0]


def _mount(*args):
    proc = subprocess.run(["mount", *args], capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.skip(f"mount {' '.join(args)} refused here: {proc.stderr.strip()}")


# --- cause 1: scene --out ------------------------------------------------------------------------


def test_scene_refuses_a_file_it_did_not_write_and_a_link(tmp_path, capsys):
    """Before: both were overwritten with the scene (the link's target too), exit 0."""
    notes = tmp_path / "notes.xml"
    notes.write_text("<notes>mine</notes>\n")
    target = tmp_path / "target.txt"
    target.write_text("the link's target\n")
    link = tmp_path / "link.xml"
    link.symlink_to(target)
    for path in (notes, link):
        for extra in ([], ["--overwrite"]):
            assert main(["scene", "--out", str(path), *extra]) == 2
            line = one_line(capsys)
            assert f"--out {path}" in line and "no usv_mj command wrote it" in line, line
    assert notes.read_text() == "<notes>mine</notes>\n"
    assert target.read_text() == "the link's target\n" and os.readlink(link) == str(target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.xml", "notes.xml", "target.txt"]


def test_scene_replaces_only_its_own_file_and_lists_it(tmp_path, capsys):
    out = tmp_path / "scene.xml"
    assert main(["scene", "--out", str(out)]) == 0
    capsys.readouterr()
    data = out.read_bytes()
    assert data.startswith(b"<mujoco")
    listed = json.loads((tmp_path / MANIFEST).read_text())["files"]
    assert listed == {"scene.xml": {"size": len(data), "sha256": hashlib.sha256(data).hexdigest()}}
    assert main(["scene", "--out", str(out)]) == 2          # an earlier scene: --overwrite replaces it
    assert "pass --overwrite" in one_line(capsys)
    assert main(["scene", "--out", str(out), "--overwrite"]) == 0
    assert out.read_bytes() == data
    out.write_bytes(data + b"<!-- edited by hand -->\n")    # changed since usv_mj wrote it: the user's now
    assert main(["scene", "--out", str(out), "--overwrite"]) == 2
    assert "changed since usv_mj wrote it" in one_line(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == [MANIFEST, "scene.xml"]


def test_scene_into_a_read_only_folder_is_refused_before_anything(tmp_path, capsys):
    """Before: "internal error: OSError: [Errno 30] Read-only file system" after the build."""
    ro = tmp_path / "ro"
    ro.mkdir()
    _mount("-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(ro))
    try:
        assert main(["scene", "--out", str(ro / "scene.xml")]) == 2
        line = one_line(capsys)
        assert f"--out {ro / 'scene.xml'}: cannot write in {ro}" in line and "Read-only file system" in line, line
    finally:
        subprocess.run(["umount", str(ro)])


def test_scene_on_a_full_disk_is_one_line_and_leaves_no_file(tmp_path, capsys):
    """Before: "internal error: OSError: [Errno 28]" and a 0-byte scene.xml left behind."""
    full = tmp_path / "full"
    full.mkdir()
    _mount("-t", "tmpfs", "-o", "size=64k", "tmpfs", str(full))
    try:
        with open(full / "pad", "wb", buffering=0) as fh:    # fill it: only the folder entries still fit
            try:
                while True:
                    fh.write(b"\0" * 4096)
            except OSError as exc:
                assert exc.errno == errno.ENOSPC
        assert main(["scene", "--out", str(full / "scene.xml")]) == 1
        line = one_line(capsys)
        assert line == f"usv-mj scene: {full / 'scene.xml'}: No space left on device", line
        assert sorted(p.name for p in full.iterdir()) == ["pad"]
    finally:
        subprocess.run(["umount", str(full)])


# --- cause 18: the file system's refusals in the other commands ------------------------------------


def test_an_os_error_while_a_command_writes_is_one_line(tmp_path, capsys, monkeypatch):
    """The bench (any command) that meets a full disk while it writes: before, "internal error:
    OSError (a defect of usv_mj)"."""
    import usv_mj.jobs.bench as bench

    suite = tmp_path / "tiny.toml"
    suite.write_text('name = "tiny"\nepisodes = 1\nduration = 1.0\nplant = "analytic"\ncontrollers = ["pi"]\n'
                     '[conditions.calm]\n[[tasks]]\nname = "line"\nbase = "paper"\n'
                     'set = { "trajectory.kind" = "line" }\n')
    where = tmp_path / "out" / "results.parquet"

    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(where))

    monkeypatch.setattr(bench, "run_bench", full_disk)
    assert main(["bench", str(suite), "--no-progress", "--out", str(tmp_path / "out")]) == 1
    assert one_line(capsys) == f"usv-mj bench: {where}: No space left on device"


def test_render_live_of_a_cut_log_serves_what_it_holds(tmp_path, capsys):
    """Before: "internal error: RecordLengthLimitExceeded" (the mcap library read the cut file's
    tail as its summary)."""
    pytest.importorskip("foxglove", reason='pip install "usv_mj[live]"')
    out = tmp_path / "run"
    assert main(["run", "--plant", "analytic", "--no-video", "--no-baseline", "-q", "--duration", "3",
                 "--out", str(out)]) == 0
    from usv_mj.outputs.log.reader import scan_summary

    data = (out / "run.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:len(data) * 3 // 4])
    info = scan_summary(cut)
    assert not info["complete"]
    held = sum(t["count"] for t in info["topics"].values())
    capsys.readouterr()
    assert main(["render", str(cut), "--live", "--live-port", "0", "--live-wait", "0"]) == 0
    captured = capsys.readouterr()
    assert "internal error" not in captured.err and "Traceback" not in captured.err, captured.err
    assert f"usv-mj render: served {held} messages of {cut} live" in captured.out
    assert f"live: {cut} is cut short: served the {held} messages it holds" in captured.err
