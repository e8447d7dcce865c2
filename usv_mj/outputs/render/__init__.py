"""Off-screen rendering of finished runs to video (the README's Two commands on headless rendering).

Rendering replays a :class:`~usv_mj.record.run_record.RunRecord` (set the hull's qpos from x, y, psi,
``mj_forward``, draw), so a run can be rendered again at another size, speed or camera without
simulating again. Public API::

    from usv_mj.outputs.render import render_run, check_gl
    info = render_run(record, "renders/paper.mp4")      # mp4 + renders/paper.png
    info["fps"], info["frames"], info["wall_s"]

``RenderWorkers(...)`` starts the rendering processes ahead of time (they warm up while the run is
simulated); pass it as ``render_run(..., pool=workers)``. ``check_gl()`` returns the backend in use ("egl" or "osmesa") or raises RuntimeError saying which
Debian packages to install. ``add_arguments(parser)`` / ``run_command(args)`` make ``usv-mj render
RUN``; ``add_video_arguments(parser)`` / ``video_options(args)`` give ``usv-mj run`` the same options.

Importing this package does not import mujoco (the backend must be chosen first).
"""

from usv_mj.outputs.render.gl_backend import GLUnavailableError, install_message, select_backend
from usv_mj.outputs.render.planner import LAYERS, FrameSpec, TopView, plan_frames
from usv_mj.outputs.render.video import (RenderWorkers, add_arguments, add_video_arguments, check_gl, load_run_record, render_frames,
                    render_run, run_command, video_options)

__all__ = ["render_run", "RenderWorkers", "render_frames", "check_gl", "add_arguments", "add_video_arguments", "video_options",
           "run_command", "load_run_record", "plan_frames", "FrameSpec", "TopView", "LAYERS",
           "GLUnavailableError", "install_message", "select_backend"]
