"""The wheel's start-up file (packaging/usv_mj-gymnasium.pth, usv_mj/envs/gymnasium_hook.py), run as site.py runs
it, in fresh interpreters: gymnasium's import registers the ids; start-up imports nothing of usv_mj; a
failure anywhere in the hook leaves gymnasium importable and prints nothing; the opt-out turns it off.
(tests/test_wheel.py runs it from the installed wheel.)"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PTH = ROOT / "packaging" / "usv_mj-gymnasium.pth"

PRELUDE = f"""
import site, sys
{{before}}
site.addpackage({str(PTH.parent)!r}, {PTH.name!r}, set())
started = sorted(m for m in sys.modules if m.startswith("usv_mj"))
import gymnasium
print(started, "usv_mj/Track-v0" in gymnasium.registry, any(type(f).__name__ == "UsvMjGymnasiumHook" for f in sys.meta_path))
"""


def _run(before: str = "", **env_extra):
    env = {k: v for k, v in os.environ.items() if k != "USV_MJ_NO_GYMNASIUM_HOOK"}
    env.update(PYTHONPATH=str(ROOT), **env_extra)
    proc = subprocess.run([sys.executable, "-c", PRELUDE.format(before=before)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout.strip(), proc.stderr


def test_the_start_up_file_is_one_executable_line_and_comments():
    lines = [ln for ln in PTH.read_text().splitlines() if ln.strip()]
    assert all(ln.startswith("#") for ln in lines[:-1]) and lines[-1].startswith("import ")


def test_importing_gymnasium_registers_the_ids_and_start_up_imports_nothing_of_usv_mj():
    out, err = _run()
    assert out == "[] True False" and err == ""   # registered; the finder left sys.meta_path


@pytest.mark.parametrize("broken", ["usv_mj.envs.gymnasium_hook", "usv_mj.envs"])
def test_a_broken_hook_leaves_gymnasium_importable_and_says_nothing(broken):
    out, err = _run(before=f"sys.modules[{broken!r}] = None   # importing it raises ImportError")
    # the hook lives in usv_mj.envs: either broken, its finder cannot import it and stays (harmless)
    assert out.split()[1:] == ["False", "True"] and err == "", (out, err)


def test_the_opt_out_leaves_no_finder():
    out, err = _run(USV_MJ_NO_GYMNASIUM_HOOK="1")
    assert out == "[] False False" and err == ""
