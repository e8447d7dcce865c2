"""`usv-mj view`: the no-display path (exit 3, one line), manual driving, a smoke test under Xvfb, and
a screenshot of its window on the virtual display: the hull and the water in the 3-D view (issue 34)."""

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


def test_view_takes_runs_vessel_flag():
    """`usv-mj view --vessel otter` as `usv-mj run --vessel otter` (README): accepted, so with no display
    it reaches the display check (exit 3) instead of argparse's "unrecognized arguments" (exit 2)."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    res = _view(env, "--vessel", "otter")
    assert res.returncode == 3, res.stderr
    assert "no display" in res.stderr and "unrecognized" not in res.stderr
    res = _view(env, "--vessel", "no-such-hull")     # and its value is checked as run's is: bad input
    assert res.returncode == 2 and "no-such-hull" in res.stderr, res.stderr


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


# Runs under xvfb-run: starts `usv-mj view`, grabs the virtual screen (Pillow's XCB grab) until the
# command ends, and prints, for each grab in which the viewer's window is up, what its 3-D viewport
# (the right part of the window: the left part is MuJoCo's panel) holds.
_SCREENSHOTS = r"""
import json, os, subprocess, sys, time
import numpy as np
from PIL import ImageGrab

cmd = json.loads(sys.argv[1])
out_png = sys.argv[2]
proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
shots = []
deadline = time.monotonic() + 400
while proc.poll() is None and time.monotonic() < deadline:
    a = np.asarray(ImageGrab.grab(xdisplay=os.environ["DISPLAY"]).convert("RGB")).astype(int)
    if proc.poll() is not None:
        break                                  # the window may have closed during the grab
    lit = np.argwhere(a.sum(axis=2) > 0)
    if len(lit) == 0:                          # no window yet: the screen is all black
        time.sleep(0.2)                        # a poll interval
        continue
    (y0, x0), (y1, x1) = lit.min(axis=0), lit.max(axis=0)
    view = a[y0:y1 + 1, x0 + int(0.45 * (x1 - x0)):x1 + 1].reshape(-1, 3)
    colours, counts = np.unique(view, axis=0, return_counts=True)
    r, g, b = view.T
    shots.append({"t": time.monotonic(), "colours": int(len(colours)), "top": float(counts.max() / len(view)),
                  "water": float(np.mean((b > r + 40) & (b > g))),
                  "hull": float(np.mean((view.min(axis=1) > 170) & (view.max(axis=1) - view.min(axis=1) < 40)))})
    if len(shots) % 10 == 1:
        ImageGrab.grab(xdisplay=os.environ["DISPLAY"]).save(out_png)
    time.sleep(0.2)                            # a poll interval
if proc.poll() is None:
    proc.kill()
stdout, stderr = proc.communicate()
print(json.dumps({"rc": proc.returncode, "stdout": stdout, "stderr": stderr, "shots": shots}))
"""


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run not installed (apt-get install xvfb)")
def test_the_viewport_shows_the_hull_and_the_water_all_run_long(tmp_path):
    """A screenshot test on the virtual display: the 3-D viewport is not one colour, it shows the water
    (blue) and the hull (white), and it keeps the hull in view while the paper's run moves it from
    (2, -3) m to about (12, 0) m (before: all black, as the default camera looked at the origin of a
    scene with no water, sky or light)."""
    import json

    pytest.importorskip("PIL.ImageGrab")
    from PIL import features

    if not features.check("xcb"):
        pytest.skip("Pillow without XCB: it cannot grab an X display")
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "WAYLAND_DISPLAY",
                                                           "DISPLAY")}
    env["PYTHONPATH"] = os.pathsep.join([ROOT, env.get("PYTHONPATH", "")])
    cmd = [sys.executable, "-m", "usv_mj.cli.view", "--duration", "20", "--speed", "2"]
    png = tmp_path / "view.png"
    res = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", sys.executable, "-c", _SCREENSHOTS,
                          json.dumps(cmd), str(png)], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    report = json.loads(res.stdout.strip().splitlines()[-1])
    assert report["rc"] == 0, report["stderr"]
    assert report["stdout"].strip().splitlines()[-1].startswith("usv-mj view: completed after "), report["stdout"]
    shots = report["shots"]
    drawn = [i for i, s in enumerate(shots) if s["water"] > 0.2 and s["hull"] > 0.002]
    assert drawn, f"the viewport never showed the water and the hull: {shots[-3:]} ({png})"
    after = shots[drawn[0]:]
    # from the first frame that shows them to the end of the run (10 s of wall time at --speed 2)
    assert after[-1]["t"] - after[0]["t"] > 5.0, (len(shots), after[:2])
    for s in after:
        assert s["colours"] > 50 and s["top"] < 0.9, s            # not one colour
        assert s["water"] > 0.2 and s["hull"] > 0.002, s          # the water and the hull, all run long
