"""The wheel runs: built from this checkout, installed (not editable) into a fresh virtual environment,
run from a folder outside the tree. It must carry the models (usv_mj.models) and install no
top-level package but usv_mj."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _source_tree(base: Path) -> Path:
    """The files git tracks, copied apart: setuptools' build/ folder in a checkout keeps files that
    were since removed (a wheel built in place shipped a deleted examples/train_ppo.py); outside a
    git checkout, the tree itself."""
    listed = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                            capture_output=True, timeout=60)
    if listed.returncode != 0:
        return ROOT
    src = base / "src"
    for rel in filter(None, listed.stdout.decode().split("\0")):
        path = ROOT / rel
        if path.is_file() or path.is_symlink():
            (src / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(path, src / rel, follow_symlinks=True)
    return src


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    base = tmp_path_factory.mktemp("wheel")
    dist = base / "dist"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist),
                    str(_source_tree(base))], check=True, capture_output=True, timeout=600)
    wheel = next(dist.glob("usv_mj-*.whl"))
    venv = base / "venv"
    # the dependencies come from this interpreter's site-packages; usv_mj itself only from the wheel
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True, timeout=300)
    py = venv / "bin" / "python"
    subprocess.run([str(py), "-m", "pip", "install", "--no-deps", "--force-reinstall", "-q", str(wheel)],
                   check=True, capture_output=True, timeout=600)
    outside = base / "elsewhere"
    outside.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",)}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    return wheel, py, outside, env


def test_the_wheel_carries_the_models_and_no_generic_top_level_name(installed):
    wheel = installed[0]
    names = zipfile.ZipFile(wheel).namelist()
    assert "usv_mj/models/usv.xml" in names and "usv_mj/models/scene.xml" in names
    assert "usv_mj/controllers/ppc.py" in names
    top = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert top == {"usv_mj", "usv_mj-gymnasium.pth"}, top  # the package and its one start-up file
    assert any(n.endswith(".dist-info/licenses/LICENSE") or n.endswith(".dist-info/LICENSE") for n in names)


def test_the_installed_wheel_runs_mujoco_with_video_and_an_env(installed):
    _, py, outside, env = installed
    where = subprocess.run([str(py), "-c", "import usv_mj, usv_mj.support.assets as a; print(usv_mj.__file__); "
                            "print(a.model_path())"], cwd=outside, env=env, capture_output=True, text=True,
                           timeout=120, check=True).stdout.split()
    assert all(str(ROOT) not in w for w in where), where  # not the checkout
    out = outside / "run"
    proc = subprocess.run([str(py), "-m", "usv_mj.cli.main", "run", "--plant", "mujoco", "--duration", "2",
                           "--no-baseline", "--size", "160x96", "--out", str(out), "-q"],
                          cwd=outside, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["plant"] == "mujoco" and summary["status"] == "completed"
    assert (out / "video.mp4").stat().st_size > 1000 and (out / "run.mcap").stat().st_size > 1000
    assert "stand-in" not in json.dumps(summary.get("render", {})).lower()
    code = ("from usv_mj import envs; e = envs.load('track', seed=0); ts = e.reset(); "
            "import numpy as np; ts = e.step(np.zeros(2)); print(ts.reward is not None)")
    proc = subprocess.run([str(py), "-c", code], cwd=outside, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0 and proc.stdout.strip().endswith("True"), proc.stderr[-2000:]


def test_the_wheel_finds_the_examples_by_name_and_registers_the_gymnasium_ids(installed):
    wheel, py, outside, env = installed
    names = zipfile.ZipFile(wheel).namelist()
    shipped = sorted(n for n in names if n.startswith("usv_mj/examples/"))
    expected = sorted(f"usv_mj/examples/{p.relative_to(ROOT / 'examples').as_posix()}"
                      for kind in ("scenarios", "sweeps") for p in (ROOT / "examples" / kind).glob("*.toml"))
    assert shipped == expected                               # the .toml files only: no plug-in package as data
    proc = subprocess.run([str(py), "-m", "usv_mj.cli.main", "examples"], cwd=outside, env=env, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0 and "harbour_gap" in proc.stdout and "quick" in proc.stdout, proc.stderr
    assert str(ROOT) not in proc.stdout                      # the wheel's copies, not the checkout's
    proc = subprocess.run([str(py), "-m", "usv_mj.cli.main", "run", "--scenario", "harbour_gap", "--plant", "analytic",
                           "--duration", "0.2", "--no-video", "-q", "--out", str(outside / "harbour")],
                          cwd=outside, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert json.loads((outside / "harbour" / "summary.json").read_text())["min_clearance_m"] is not None
    # gymnasium first, nothing of usv_mj imported: the wheel's start-up file registers the ids (Gymnasium
    # 1.x reads no entry points; usv_mj/envs/gymnasium_hook.py), then a bare gymnasium.make makes one
    code = ("import sys; before = sorted(m for m in sys.modules if m.startswith('usv_mj')); "
            "import gymnasium; hooked = 'usv_mj/Track-v0' in gymnasium.registry; "
            "from usv_mj.jobs.sweep import load_sweep; import importlib.metadata as md; "
            "p = load_sweep('quick'); print(len(p.runs), p.source); "
            "ep = [e for e in md.entry_points(group='gymnasium.envs') if e.name == 'usv_mj']; ep[0].load()(); "
            "print('usv_mj/Track-v0' in gymnasium.registry); "
            "from usv_mj import load_scenario; print(load_scenario('examples/scenarios/harbour_gap.toml').source); "
            "e = gymnasium.make('usv_mj/Track-v0'); print(before, hooked, e.reset(seed=0)[0].shape)")
    proc = subprocess.run([str(py), "-c", code], cwd=outside, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.split("\n")
    assert lines[0].split()[1].endswith("usv_mj/examples/sweeps/quick.toml") and str(ROOT) not in lines[0]
    assert lines[1] == "True"
    assert lines[2].endswith("usv_mj/examples/scenarios/harbour_gap.toml") and str(ROOT) not in lines[2]
    assert lines[3] == "[] True (22,)"       # start-up imported nothing of usv_mj; gymnasium's import registered


def test_the_gymnasium_start_up_file_is_installed_and_can_be_turned_off(installed):
    """The wheel's usv_mj-gymnasium.pth lands at the top of site-packages; USV_MJ_NO_GYMNASIUM_HOOK turns it off
    (then the ids exist only after an import, as with Gymnasium 1.x alone)."""
    _, py, outside, env = installed
    site = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], cwd=outside,
                          env=env, capture_output=True, text=True, timeout=60, check=True).stdout.strip()
    assert (Path(site) / "usv_mj-gymnasium.pth").is_file()
    off = {**env, "USV_MJ_NO_GYMNASIUM_HOOK": "1"}
    proc = subprocess.run([str(py), "-c", "import sys, gymnasium; print('usv_mj/Track-v0' in gymnasium.registry, "
                           "'usv_mj' in sys.modules)"], cwd=outside, env=off, capture_output=True, text=True,
                          timeout=120)
    assert (proc.returncode, proc.stdout.split()) == (0, ["False", "False"]), proc.stderr[-2000:]


def test_the_wheel_carries_the_default_benchmark_suite(installed):
    wheel, py, outside, env = installed
    names = zipfile.ZipFile(wheel).namelist()
    assert "usv_mj/jobs/bench/suites/default.toml" in names   # its harbour task names the shipped example harbour_gap
    assert "usv_mj/jobs/bench/suites/ppo_track.zip" in names   # the default suite's PPO policy, beside it
    # the installed suite planned as load_suite() plans it (its file, its folder: the policy beside it),
    # at 1 episode per cell instead of its 10 (3240 scenarios would take tens of seconds to build)
    code = ("import tomllib; from usv_mj.jobs.bench.suite import default_suite_path, plan_suite; "
            "p = default_suite_path(); d = tomllib.loads(p.read_text()); "
            "s = plan_suite({**d, 'episodes': 1}, str(p), p.parent); print(len(s.plan.runs), d['episodes'], s.source)")
    proc = subprocess.run([str(py), "-c", code], cwd=outside, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    n, episodes, source = proc.stdout.split()
    # 3 x 4 x (7 x 3 + 6) per episode, x 10 episodes = 3240: tests/test_bench_run.py
    assert (n, episodes) == ("324", "10") and str(ROOT) not in source
