"""MuJoCo's interactive viewer on a running scenario (the job of ``usv-mj view``, :mod:`usv_mj.cli.view`).

The scenario is built once (:func:`usv_mj.build`, the MuJoCo plant: the hull of ``models/usv.xml``
or the harbour with its obstacles, the hydrodynamic callback and the sea acting) and run by the
project's own loop (:func:`usv_mj.simulate`) with the controller in it; a loop hook poses the
viewer's model from the plant every 1/60 s of paced time and holds the simulated time to ``speed``
times the wall clock. Closing the window ends the run (recorded as interrupted).

What the viewer draws (:func:`display_of`): in open water the plant simulates the hull of
``models/usv.xml`` alone, with no water, sky or light, and MuJoCo's default camera looks at the
origin, so once the hull has left it (the paper starts at (2, -3) m) the 3-D view was all black.
The viewer draws ``models/scene.xml`` instead (water, sky, sun), with the plant's hull (scaled to
the vessel) posed from the plant; a harbour's plant already runs in that scene and is drawn as it
is. The camera follows the hull (MuJoCo's tracking camera; the mouse still turns and zooms it).
With ``manual`` the controller is replaced by the keyboard (open loop):

    arrow up / down      surge force tau_u + / - SURGE_STEP_N
    arrow left / right   yaw moment tau_r + / - YAW_STEP_NM (left turns to port, counter-clockwise)
    space                both back to 0

(the loop's quantizers and actuator limits act on these commands as on any controller's).
Without a display (no ``DISPLAY`` / ``WAYLAND_DISPLAY``, or the viewer failing to open):
:class:`NoDisplay`, one line.
"""

from __future__ import annotations

import os
import threading
import time

import numpy as np

from usv_mj.builder import build
from usv_mj.core.errors import ScenarioError
from usv_mj.loop.simulate import simulate
from usv_mj.record.criteria import NotJudged

SURGE_STEP_N = 10.0     # N per key press
YAW_STEP_NM = 1.0       # N m per key press
FRAME_S = 1.0 / 60.0    # wall time between two viewer syncs [s]
STALL_S = 0.25          # behind the paced clock by more than this [s]: the clock waits instead
KEY_UP, KEY_DOWN, KEY_LEFT, KEY_RIGHT, KEY_SPACE = 265, 264, 263, 262, 32   # GLFW key codes


class NoDisplay(RuntimeError):
    """No desktop to open the viewer on (the CLI prints it in one line, exit 3)."""


def check_display(environ=os.environ) -> None:
    if not (environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY")):
        raise NoDisplay("no display (DISPLAY and WAYLAND_DISPLAY are unset): MuJoCo's viewer needs a desktop; "
                        "`usv-mj run` writes a video instead")


def probe_glfw() -> None:
    """NoDisplay unless GLFW (MuJoCo's viewer) opens the display: the viewer's own thread ends the
    process when it cannot (exit 1, "could not initialize GLFW")."""
    import warnings

    import glfw

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ok = glfw.init()
    if not ok:
        where = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
        raise NoDisplay(f"the viewer cannot open the display {where!r} (GLFW failed to initialize); "
                        "`usv-mj run` writes a video instead")
    glfw.terminate()


class ManualController:
    """Open-loop surge force and yaw moment set from the keyboard (module docstring); the loop's
    controller interface as :class:`usv_mj.controllers.open_loop.OpenLoopController`."""

    name = "manual"
    diagnostic_fields = ()
    criterion = NotJudged("manual driving")

    def __init__(self):
        self.lock = threading.Lock()
        self.tau = [0.0, 0.0]   # [N, N m]
        self._diag = np.zeros(0)

    def reset(self) -> None:
        with self.lock:
            self.tau = [0.0, 0.0]

    def key(self, keycode: int) -> None:
        """The viewer's key callback (its own thread)."""
        step = {KEY_UP: (SURGE_STEP_N, 0.0), KEY_DOWN: (-SURGE_STEP_N, 0.0),
                KEY_LEFT: (0.0, YAW_STEP_NM), KEY_RIGHT: (0.0, -YAW_STEP_NM)}.get(keycode)
        with self.lock:
            if keycode == KEY_SPACE:
                self.tau = [0.0, 0.0]
            elif step is not None:
                self.tau = [self.tau[0] + step[0], self.tau[1] + step[1]]

    def __call__(self, t, state, reference):
        with self.lock:
            return self.tau[0], self.tau[1], self._diag


class ViewerHook:
    """The loop hook that shows the plant in the viewer and paces the run (module docstring).
    ``display``: what :func:`display_of` returns (None: the plant's own model and data)."""

    def __init__(self, viewer, speed: float, display=None):
        import mujoco

        self.viewer, self.speed, self._mj = viewer, speed, mujoco
        self.display = display
        self._wall0 = None
        self._next = 0.0
        self.frames = 0

    def __call__(self, t, k, plant):
        shown = t / self.speed   # the wall time [s] at which this state is due on screen
        if self._wall0 is None:
            self._wall0 = time.monotonic() - shown
        if shown < self._next:   # a frame every FRAME_S of paced time (the loop runs faster than that)
            return
        if not self.viewer.is_running():
            raise KeyboardInterrupt("closing the viewer")
        with self.viewer.lock():
            if self.display is None:
                self._mj.mj_kinematics(plant.model, plant.data)
            else:
                model, data, pose = self.display
                pose()
                self._mj.mj_kinematics(model, data)
                self._mj.mj_comPos(model, data)   # subtree_com: where the tracking camera looks
        self.viewer.sync()
        self.frames += 1
        ahead = shown - (time.monotonic() - self._wall0)
        if ahead > 0:
            time.sleep(ahead)
        elif ahead < -STALL_S:   # a stall (a first compile, a slow frame) is not run through faster than speed
            self._wall0 = time.monotonic() - shown
        self._next = shown + FRAME_S


def display_of(plant, scenario):
    """``(model, data, pose)``: what the viewer draws and ``pose()``, which sets it to the plant's
    state (see the module docstring). The plant's own model and data when its scene has the water
    (a plane of the world body: the harbour composed on ``models/scene.xml``)."""
    import mujoco

    m = plant.model
    if any(m.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE and m.geom_bodyid[g] == 0 for g in range(m.ngeom)):
        return m, plant.data, lambda: None
    from usv_mj.outputs.render.replay import build_replay_model
    from usv_mj.outputs.render.world import hull_dimensions

    model, _ = build_replay_model(None, ghost=False, sea=False, hull=hull_dimensions(scenario))
    data = mujoco.MjData(model)
    joints = ("x", "y", "yaw")
    src = [int(m.jnt_qposadr[m.joint(j).id]) for j in joints]
    dst = [int(model.jnt_qposadr[model.joint(j).id]) for j in joints]

    def pose():
        data.qpos[dst] = plant.data.qpos[src]
        data.time = plant.data.time

    pose()
    mujoco.mj_forward(model, data)
    return model, data, pose


def follow_hull(viewer, model, length: float) -> None:
    """Point the viewer's camera at body "hull" and keep it there (MuJoCo's tracking camera), from
    behind and above at a few hull lengths."""
    import mujoco

    with viewer.lock():
        cam = viewer.cam
        cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        cam.trackbodyid = model.body("hull").id
        cam.distance = 4.0 * float(length)
        cam.elevation = -25.0
        cam.azimuth = 210.0


def _wait_closed(viewer, threads, timeout_s: float = 5.0) -> None:
    """Let the viewer's render thread end (``threads``: those launch_passive started) before the
    model and data it draws are freed: a process that exits while it runs crashes in GLFW."""
    end = time.monotonic() + timeout_s
    while viewer.is_running() and time.monotonic() < end:
        time.sleep(0.01)
    for thread in threads:
        thread.join(max(0.0, end - time.monotonic()))


def check_speed(speed) -> None:
    """ScenarioError unless ``speed`` (times real time) is a finite number > 0."""
    if not (speed > 0 and speed < float("inf")):
        raise ScenarioError(f"--speed {speed!r}: must be a finite number > 0 (1 = real time)")


def view(scenario, *, manual: bool = False, speed: float = 1.0):
    """Run ``scenario`` in MuJoCo's viewer at ``speed`` times real time (``manual``: driven by the
    arrow keys); returns (the record, the frames shown). :class:`NoDisplay` (one line) when there
    is no desktop or the viewer does not open; ScenarioError for a bad ``speed``."""
    check_speed(speed)
    try:
        check_display()
        probe_glfw()
        import mujoco.viewer
    except ImportError as exc:
        raise NoDisplay(str(exc)) from None
    controller = ManualController() if manual else None
    with build(scenario, controller=controller) as parts:
        display = display_of(parts.plant, scenario)
        before = set(threading.enumerate())
        try:
            viewer = mujoco.viewer.launch_passive(display[0], display[1], show_right_ui=False,
                                                  key_callback=controller.key if controller is not None else None)
        except Exception as exc:  # noqa: BLE001 - GLFW reports no display in several ways
            raise NoDisplay(f"the viewer did not open ({type(exc).__name__}: {exc}); it needs a desktop "
                            f"(MUJOCO_GL={os.environ.get('MUJOCO_GL', 'unset')})") from None
        threads = [t for t in threading.enumerate() if t not in before]
        follow_hull(viewer, display[0], scenario.vessel.model.dimensions.L)
        hook = ViewerHook(viewer, speed, None if display[0] is parts.plant.model else display)
        try:
            record = simulate(parts, hooks=[hook])
        finally:
            viewer.close()
            _wait_closed(viewer, threads)
    return record, hook.frames
