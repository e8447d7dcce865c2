"""Off-screen rendering of finished runs to video (the README's Two commands on headless rendering).

Rendering replays a :class:`~usv_mj.record.run_record.RunRecord` (set the hull's qpos from x, y, psi,
``mj_forward``, draw), so a run can be rendered again at another size, speed or camera without
simulating again. Public API::

    from usv_mj.outputs.render import render_run, check_gl
    info = render_run(record, "renders/paper.mp4")      # mp4 + renders/paper.png
    info["fps"], info["frames"], info["wall_s"]

``RenderWorkers(...)`` starts the rendering processes ahead of time (they warm up while the run is
simulated); pass it as ``render_run(..., pool=workers)``. ``check_gl()`` returns the backend in use ("egl" or "osmesa") or raises RuntimeError saying which
Debian packages to install. The command ``usv-mj render RUN`` and the video flags of ``usv-mj run``
are :mod:`usv_mj.cli.render` and :mod:`usv_mj.cli.args` (the defaults and limits they show are
:mod:`usv_mj.outputs.render.defaults`).

Importing this package imports neither numpy nor mujoco (the names below load on first use; the
backend must be chosen before mujoco is imported).
"""

from usv_mj.core.lazy_names import lazy_names

_WHERE = {
    "GLUnavailableError": "gl_backend", "install_message": "gl_backend", "select_backend": "gl_backend",
    "LAYERS": "planner", "FrameSpec": "planner", "TopView": "planner", "plan_frames": "planner",
    "RenderWorkers": "video", "check_gl": "video", "load_run_record": "video", "render_frames": "video",
    "render_run": "video",
}
__getattr__, __dir__, _ = lazy_names(__name__, {name: "." + module for name, module in _WHERE.items()})
__all__ = ["render_run", "RenderWorkers", "render_frames", "check_gl", "load_run_record", "plan_frames", "FrameSpec",
           "TopView", "LAYERS", "GLUnavailableError", "install_message", "select_backend"]
