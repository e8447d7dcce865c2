"""Checks a run passes before anything is created.

Every check raises :class:`usv_mj.scenario.spec.ScenarioError` with one line that starts with the file or
the flag it names, so that ``usv-mj run`` answers bad input with exit 2 and leaves ``--out`` exactly
as it was. :func:`reference_error` is shared with ``usv-mj sweep`` (:mod:`usv_mj.jobs.sweep.spec`), which
runs it for every distinct path of a sweep up front.
"""

from __future__ import annotations

import math
from pathlib import Path

from usv_mj.core.errors import ScenarioError
from usv_mj.scenario.spec import Scenario

def reference_error(scenario: Scenario) -> str | None:
    """Why the reference path of ``scenario`` cannot be built (None: it can). The scenario format
    accepts some paths :mod:`usv_mj.references.trajectories` refuses (one waypoint, a repeated point, a turn
    radius that does not fit, a path that doubles back)."""
    from usv_mj.references.trajectories import make_reference

    try:
        make_reference(scenario.trajectory, scenario.duration, scenario)
    except ValueError as exc:
        return str(exc)
    return None


def check_reference(scenario: Scenario) -> None:
    problem = reference_error(scenario)
    if problem is not None:
        raise ScenarioError(f"{scenario.source}: the reference path cannot be built: {problem}")


def check_start_pose(scenario: Scenario) -> None:
    """The hull must not start inside an obstacle."""
    from usv_mj.builder import check_start_clear

    check_start_clear(scenario)


def check_plan(scenario: Scenario) -> None:
    """With ``[guidance] avoid``, the plan around the obstacles must exist (a start or goal inside an
    inflated obstacle, a path the planner cannot open, a trajectory kind without start and goal):
    decided by the inputs alone, so it is bad input."""
    if not (scenario.obstacles and scenario.guidance.avoid):
        return
    from usv_mj.obstacles.hooks import make_plan
    from usv_mj.references.planner import PlanningError

    try:
        make_plan(scenario)
    except (PlanningError, ValueError) as exc:
        message = str(exc)
        if isinstance(exc, ScenarioError) and scenario.source and message.startswith(scenario.source):
            raise
        raise (PlanningError if isinstance(exc, PlanningError) else ScenarioError)(
            f"{scenario.source}: guidance: {message}") from None


def check_video(render_options: dict | None) -> None:
    """The camera (and size) of the video, before any render worker starts; an option that
    :func:`usv_mj.outputs.render.render_run` does not take is refused here, not after the simulation."""
    import inspect

    from usv_mj.outputs.render.video import check_size, check_camera, render_run

    opts = dict(render_options or {})
    known = [name for name in inspect.signature(render_run).parameters if name not in ("record", "out_path", "progress",
                                                                                       "pool")]
    unknown = sorted(set(opts) - set(known))
    if unknown:
        raise ScenarioError(f"render_options: unknown option(s) {', '.join(map(repr, unknown))}; known: "
                            f"{', '.join(known)}")
    try:
        if "width" in opts or "height" in opts:
            check_size(opts.get("width", 1280), opts.get("height", 720))
        check_camera(opts.get("camera", "top"), opts.get("model"))
    except ValueError as exc:
        raise ScenarioError(f"--camera/--size: {exc}") from None
    for key in ("fps", "speedup"):
        v = opts.get(key)
        if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ScenarioError(f"--{key}: must be a finite number > 0, got {v!r}")


def check_out_dir(out, overwrite: bool = False, flag: str = "--out") -> Path:
    """``out`` can take a run (see :func:`usv_mj.outputs.outdir.check_folder`: new, empty, or an earlier
    usv_mj output that ``overwrite`` replaces; never a folder holding anything usv_mj did not write)."""
    from usv_mj.outputs.outdir import check_folder

    return check_folder(out, overwrite, flag)


def check_controller(scenario: Scenario, kind: str | None = None) -> None:
    """The contracts of controller ``kind`` (default the scenario's) checked when it is loaded, not
    after the run: it is made as the run makes it (a plug-in's ``from_scenario`` that fails says so,
    :mod:`usv_mj.core.plugins`), its criterion (:func:`usv_mj.record.criteria.criterion_of`) and its
    kernel's diagnostics against its ``diagnostic_fields`` (:func:`usv_mj.core.kernels.diag_contract`).
    A broken contract raises :class:`usv_mj.core.errors.PluginContractError` (exit 2, nothing written)."""
    from usv_mj.builder import make_controller
    from usv_mj.core.errors import PluginContractError
    from usv_mj.core.kernels import diag_contract
    from usv_mj.record.criteria import criterion_of

    controller = make_controller(scenario, kind)
    criterion_of(controller)
    problem = diag_contract(controller)
    if problem is not None:
        raise PluginContractError(problem)


def check_run(scenario: Scenario, out, *, video: bool, render_options: dict | None, overwrite: bool) -> Path:
    """Everything :func:`usv_mj.jobs.run.run_job` needs to hold before it creates anything."""
    out = check_out_dir(out, overwrite)
    check_reference(scenario)
    check_start_pose(scenario)
    check_plan(scenario)
    if video:
        check_video(render_options)
    return out
