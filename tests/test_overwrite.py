"""Issue 23: --overwrite replaces only what a usv_mj command wrote (usv_mj/outputs/outdir.py).

Every command with an output path and --overwrite (run, compare, plot, sweep, capability: a folder;
render, env: a video file; scene: an MJCF file) is pointed at a folder of the user's own files (plain files, some with
the names a run writes, a subfolder, a hidden file, symbolic links to files elsewhere) and at a
fake home folder: each must exit 2 with one line and leave every decoy and every link target as it
was, byte for byte. The positive case: a folder an earlier run wrote is replaced, and its manifest
lists exactly the files there, with their sizes and SHA-256 computed here independently.
"""

import hashlib
import json
import os
from pathlib import Path

import pytest

from usv_mj.cli.main import main

ROOT = Path(__file__).resolve().parent.parent
RUN = ["run", "--duration", "0.2", "--plant", "analytic", "--no-video", "--no-baseline", "-q"]
MANIFEST = ".usv_mj-manifest.json"


def tree(folder: Path) -> dict:
    """Every path under ``folder`` (links not followed): bytes of a file, target of a link, 'dir'."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(folder):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            rel = str(p.relative_to(folder))
            out[rel] = ("link", os.readlink(p)) if p.is_symlink() else "dir" if p.is_dir() else p.read_bytes()
    return out


def make_decoys(tmp: Path) -> tuple[Path, Path]:
    """A folder of the user's own files, and a file elsewhere that two links in it point at."""
    target = tmp / "elsewhere" / "target.txt"
    target.parent.mkdir(parents=True)
    target.write_bytes(b"the link's target, not in the folder\n")
    d = tmp / "mine"
    d.mkdir()
    (d / "thesis.txt").write_text("chapter 1\n")
    for name in ("summary.json", "report.md", "video.mp4", "video.png", "run.mp4", "compare.json", "scene.xml"):
        (d / name).write_bytes(f"the user's own {name}\n".encode())
    (d / "data").mkdir()
    (d / "data" / "points.csv").write_text("1,2\n3,4\n")
    (d / ".hidden").write_text("secret\n")
    (d / "link.txt").symlink_to(target)
    (d / "clip.mp4").symlink_to(target)
    (d / "link.xml").symlink_to(target)
    return d, target


@pytest.fixture(scope="module")
def a_run(tmp_path_factory):
    """A real run folder (with its log) written by ``usv-mj run``."""
    out = tmp_path_factory.mktemp("run") / "out"
    assert main([*RUN, "--out", str(out)]) == 0
    return out


def commands(out: Path, mcap: Path) -> list[list[str]]:
    """Every command with an output path, aimed at ``out`` (a folder) with --overwrite."""
    return [
        [*RUN, "--out", str(out), "--overwrite"],
        ["compare", "--duration", "0.2", "-q", "--out", str(out), "--overwrite"],
        ["plot", str(mcap), "--out", str(out), "--overwrite"],
        ["sweep", str(ROOT / "examples/sweeps/quick.toml"), "--no-progress", "--out", str(out), "--overwrite"],
        ["capability", "--load", "current", "--no-progress", "--out", str(out), "--overwrite"],
        ["render", str(mcap), "--no-progress", "--out", str(out / "video.mp4"), "--overwrite"],
        ["render", str(mcap), "--no-progress", "--out", str(out / "clip.mp4"), "--overwrite"],
        ["render", str(mcap), "--no-progress", "--out", str(out), "--overwrite"],
        ["env", "track", "--duration", "0.2", "--video", str(out / "run.mp4"), "--overwrite"],
        ["env", "track", "--duration", "0.2", "--video", str(out), "--overwrite"],
        ["scene", "--out", str(out / "scene.xml"), "--overwrite"],       # issue 38: overwritten before
        ["scene", "--out", str(out / "link.xml"), "--overwrite"],        # written through the link before
    ]


def one_line_exit_2(argv, capsys) -> str:
    assert main(argv) == 2, argv
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, (argv, err)
    return lines[0]


def test_every_command_refuses_a_folder_of_the_users_files(tmp_path, a_run, capsys):
    d, target = make_decoys(tmp_path)
    before, target_bytes = tree(d), target.read_bytes()
    for argv in commands(d, a_run / "run.mcap"):
        line = one_line_exit_2(argv, capsys)
        assert str(d) in line, line
        assert tree(d) == before, argv
        assert target.read_bytes() == target_bytes
    assert sorted(p.name for p in tmp_path.iterdir()) == ["elsewhere", "mine"]   # no staging, no lock


def test_every_command_refuses_the_home_folder(tmp_path, a_run, capsys, monkeypatch):
    home = tmp_path / "home"
    (home / "Documents").mkdir(parents=True)
    (home / "Documents" / "cv.txt").write_text("my cv\n")
    monkeypatch.setenv("HOME", str(home))
    before = tree(home)
    for out in (home, home.parent):
        for argv in commands(out, a_run / "run.mcap"):
            if argv[0] in ("render", "env", "scene") and \
                    not argv[argv.index("--out" if "--out" in argv else "--video") + 1] == str(out):
                continue                       # a new video file inside the home folder is allowed
            if argv[0] == "render":            # --out FOLDER: the video goes in as FOLDER/run.mp4 (issue 38)
                assert main(argv) in (0, 2), argv
                capsys.readouterr()
                after = tree(home)
                assert {k: after.get(k) for k in before} == before, argv     # nothing of the user's touched
                # the video, its still and the record of what usv_mj wrote there (and matplotlib's
                # cache folder, as HOME is this folder)
                new = {k for k in set(after) - set(before) if not k.startswith(".config")}
                assert new <= {"run.mp4", "run.png", ".usv_mj-manifest.json"}, sorted(new)
                for name in new:
                    (home / name).unlink()
                before = tree(home)
                continue
            one_line_exit_2(argv, capsys)
            assert tree(home) == before, argv


def test_a_run_folder_with_a_file_the_run_did_not_write_is_refused(tmp_path, a_run, capsys):
    out = tmp_path / "out"
    assert main([*RUN, "--out", str(out)]) == 0
    (out / "figures" / "my_notes.txt").write_text("keep me\n")
    before = tree(out)
    line = one_line_exit_2([*RUN, "--out", str(out), "--overwrite"], capsys)
    assert "figures/my_notes.txt" in line and "no usv_mj command wrote" in line
    assert tree(out) == before
    (out / "figures" / "my_notes.txt").unlink()
    (out / "report.md").write_text("edited by hand\n")          # a file the run wrote, changed since
    before = tree(out)
    line = one_line_exit_2([*RUN, "--out", str(out), "--overwrite"], capsys)
    assert "report.md" in line and "changed since" in line
    assert tree(out) == before


def test_a_legacy_looking_folder_with_a_foreign_file_is_refused(tmp_path, capsys):
    out = tmp_path / "old"
    out.mkdir()
    for name in ("summary.json", "run.mcap", "thesis.txt"):
        (out / name).write_text(name)
    before = tree(out)
    line = one_line_exit_2([*RUN, "--out", str(out), "--overwrite"], capsys)
    assert "thesis.txt" in line
    assert tree(out) == before


def test_a_folder_an_earlier_run_wrote_is_replaced(tmp_path, capsys):
    out = tmp_path / "out"
    assert main([*RUN, "--out", str(out)]) == 0
    first = tree(out)
    line = one_line_exit_2([*RUN, "--out", str(out)], capsys)      # without --overwrite: refused
    assert "already holds a run" in line and "--overwrite" in line
    assert tree(out) == first
    next((out / "figures").glob("*.png")).unlink()                  # a listed file gone: still ours
    assert main([*RUN, "--duration", "0.3", "--out", str(out), "--overwrite"]) == 0
    assert json.loads((out / "summary.json").read_text())["simulated_s"] == pytest.approx(0.3)
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["tool"] == "usv_mj" and "--overwrite" in manifest["command"]
    files = {rel for rel, v in tree(out).items() if isinstance(v, bytes) and rel != MANIFEST}
    assert set(manifest["files"]) == files
    for rel, entry in manifest["files"].items():
        data = (out / rel).read_bytes()
        assert entry == {"size": len(data), "sha256": hashlib.sha256(data).hexdigest()}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]        # no staging or old folder left


def test_plot_and_render_add_to_the_run_folders_manifest(tmp_path, a_run, capsys):
    out = tmp_path / "out"
    assert main([*RUN, "--out", str(out)]) == 0
    line = one_line_exit_2(["plot", str(out / "run.mcap")], capsys)           # would replace report.md
    assert "report.md" in line and "--overwrite" in line
    assert main(["plot", str(out / "run.mcap"), "--overwrite"]) == 0
    manifest = json.loads((out / MANIFEST).read_text())
    data = (out / "report.md").read_bytes()
    assert manifest["files"]["report.md"]["sha256"] == hashlib.sha256(data).hexdigest()
    assert any(c.startswith("usv-mj plot") for c in manifest["commands"])
    capsys.readouterr()
    assert main([*RUN, "--out", str(out), "--overwrite"]) == 0                 # still a usv_mj folder


def test_refused_outputs_are_not_created(tmp_path, capsys):
    new = tmp_path / "a" / "b"
    one_line_exit_2(["capability", "--load", "current", "--min", "5", "--max", "1", "--no-progress",
                     "--out", str(new)], capsys)
    sc = tmp_path / "sc.toml"
    sc.write_text('[initial]\neta = [0.0, 0.0, 0.0]\n[[obstacles]]\nkind = "circle"\ncenter = [0.0, 0.0]\n'
                  'radius = 2.0\n')
    one_line_exit_2([*RUN, "--scenario", str(sc), "--out", str(new), "--overwrite"], capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sc.toml"]


@pytest.mark.parametrize("cmd", ["run", "compare", "sweep", "capability", "render"])
def test_a_name_whose_staging_name_is_too_long_is_refused_in_one_line(tmp_path, a_run, capsys, cmd):
    name = "n" * 240                        # fits 255 bytes; ".NAME.staging-PID" does not
    out = tmp_path / name
    argv = {"run": [*RUN, "--out", str(out)],
            "compare": ["compare", "--duration", "0.2", "--out", str(out)],
            "sweep": ["sweep", str(ROOT / "examples/sweeps/quick.toml"), "--out", str(out)],
            "capability": ["capability", "--load", "current", "--out", str(out)],
            "render": ["render", str(a_run / "run.mcap"), "--out", str(tmp_path / (name + "xxxxxxxx.mp4"))]}[cmd]
    line = one_line_exit_2(argv, capsys)
    assert "over 255" in line
    assert list(tmp_path.iterdir()) == []


def test_a_sweep_folder_resumes_in_place_and_is_replaced_with_overwrite(tmp_path, capsys):
    """A sweep claims its outputs by name before it writes them (a killed one stays resumable):
    --resume continues in it, --overwrite replaces it; a file of the user's in it stops both."""
    out = tmp_path / "sw"
    base = ["sweep", "quick", "--workers", "1", "--max-runs", "1", "--no-progress", "--out", str(out)]
    assert main(base) == 0
    manifest = json.loads((out / MANIFEST).read_text())
    assert "results.parquet" in manifest["patterns"]
    assert main([*base, "--resume"]) == 0
    assert "2 of" in capsys.readouterr().out                   # the second run added to the first
    (out / "notes.txt").write_text("mine\n")
    for flag in ("--resume", "--overwrite"):
        line = one_line_exit_2([*base, flag], capsys)
        assert "notes.txt" in line
    (out / "notes.txt").unlink()
    assert main([*base, "--overwrite"]) == 0
    assert "1 of" in capsys.readouterr().out                   # a new sweep: one run again
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sw"]
