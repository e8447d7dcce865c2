"""`usv-mj view`: the no-display path (exit 3, one line), manual driving, and a smoke test under Xvfb."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from usv_mj import build, load_scenario, simulate
from usv_mj.jobs.view import KEY_DOWN, KEY_LEFT, KEY_SPACE, KEY_UP, SURGE_STEP_N, YAW_STEP_NM, ManualController

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _view(env, *extra):
    return subprocess.run([sys.executable, "-m", "usv_mj.cli.view", "--duration", "1", *extra], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)


def test_no_display_is_one_line_exit_3():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    res = _view(env)
    assert res.returncode == 3
    assert res.stderr.strip().splitlines() == [
        "usv-mj view: no display (DISPLAY and WAYLAND_DISPLAY are unset): MuJoCo's viewer needs a desktop; "
        "`usv-mj run` writes a video instead"]


def test_a_display_that_does_not_open_is_one_line_exit_3():
    env = dict(os.environ, DISPLAY=":97")   # no X server there
    env.pop("WAYLAND_DISPLAY", None)
    res = _view(env)
    assert res.returncode == 3, res.stderr
    assert [ln for ln in res.stderr.splitlines() if ln.strip()] == [
        "usv-mj view: the viewer cannot open the display ':97' (GLFW failed to initialize); "
        "`usv-mj run` writes a video instead"]


def test_manual_keys_drive_the_loop():
    """Keys set the open-loop command the loop quantizes and applies: the record shows them."""
    manual = ManualController()
    scenario = load_scenario(overrides={"duration": 2.0, "plant": {"kind": "analytic"}, "quantizer": {"enabled": False}})

    def press(t, k, plant):
        if k == 500:
            manual.key(KEY_UP), manual.key(KEY_UP), manual.key(KEY_LEFT)
        if k == 1500:
            manual.key(KEY_SPACE)
            manual.key(KEY_DOWN)

    with build(scenario, controller=manual) as parts:
        record = simulate(parts, hooks=[press])
    tau_u, tau_r = record["tau_u"], record["tau_r"]
    assert np.all(tau_u[1:500] == 0.0) and np.all(tau_u[501:1500] == 2 * SURGE_STEP_N)
    assert np.all(tau_r[501:1500] == YAW_STEP_NM) and np.all(tau_r[1501:-1] == 0.0)
    assert np.all(tau_u[1501:-1] == -SURGE_STEP_N)
    assert np.array_equal(record["f_u"][:-1], tau_u[:-1])   # unlimited actuators, no quantizer: applied as commanded


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run not installed (apt-get install xvfb)")
def test_viewer_runs_under_xvfb():
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "WAYLAND_DISPLAY", "DISPLAY")}
    res = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", sys.executable, "-m", "usv_mj.cli.view",
                          "--duration", "2", "--speed", "4", "--manual"], cwd=ROOT, env=env, capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    line = res.stdout.strip().splitlines()[-1]
    assert line.startswith("usv-mj view: completed after "), line
    assert int(line.split("after ")[1].split()[0]) >= 2      # frames were drawn
    assert "at t = 2.00 s" in line                           # the run advanced to its end
