"""Checks a run passes before anything is created.

Every check raises :class:`usv_mj.scenario.ScenarioError` with one line that starts with the file or
the flag it names, so that ``usv-mj run`` answers bad input with exit 2 and leaves ``--out`` exactly
as it was. :func:`reference_error` is shared with ``usv-mj sweep`` (:mod:`usv_mj.sweep.spec`), which
runs it for every distinct path of a sweep up front.
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

from .errors import ScenarioError
from .scenario import Scenario

#: Files that mark a folder as holding the outputs of a run (``usv-mj run`` or :func:`run_job`).
RUN_MARKERS = ("summary.json", "run.mcap", "report.md")


def reference_error(scenario: Scenario) -> str | None:
    """Why the reference path of ``scenario`` cannot be built (None: it can). The scenario format
    accepts some paths :mod:`usv_mj.trajectories` refuses (one waypoint, a repeated point, a turn
    radius that does not fit, a path that doubles back)."""
    from .trajectories import make_reference

    try:
        make_reference(scenario.trajectory, scenario.duration)
    except ValueError as exc:
        return str(exc)
    return None


def check_reference(scenario: Scenario) -> None:
    problem = reference_error(scenario)
    if problem is not None:
        raise ScenarioError(f"{scenario.source}: the reference path cannot be built: {problem}")


def check_start_pose(scenario: Scenario) -> None:
    """The hull must not start inside an obstacle."""
    from .builder import check_start_clear

    check_start_clear(scenario)


def check_plan(scenario: Scenario) -> None:
    """With ``[guidance] avoid``, the plan around the obstacles must exist (a start or goal inside an
    inflated obstacle, a path the planner cannot open, a trajectory kind without start and goal):
    decided by the inputs alone, so it is bad input."""
    if not (scenario.obstacles and scenario.guidance.avoid):
        return
    from .obstacles.hooks import make_plan
    from .obstacles.planner import PlanningError

    try:
        make_plan(scenario)
    except (PlanningError, ValueError) as exc:
        if isinstance(exc, ScenarioError):
            raise
        raise ScenarioError(f"{scenario.source}: guidance: {exc}") from None


def check_video(render_options: dict | None) -> None:
    """The camera (and size) of the video, before any render worker starts; an option that
    :func:`usv_mj.render.render_run` does not take is refused here, not after the simulation."""
    import inspect

    from .render.video import _check_size, check_camera, render_run

    opts = dict(render_options or {})
    known = [name for name in inspect.signature(render_run).parameters if name not in ("record", "out_path", "progress",
                                                                                       "pool")]
    unknown = sorted(set(opts) - set(known))
    if unknown:
        raise ScenarioError(f"render_options: unknown option(s) {', '.join(map(repr, unknown))}; known: "
                            f"{', '.join(known)}")
    try:
        if "width" in opts or "height" in opts:
            _check_size(opts.get("width", 1280), opts.get("height", 720))
        check_camera(opts.get("camera", "top"), opts.get("model"))
    except ValueError as exc:
        raise ScenarioError(f"--camera/--size: {exc}") from None
    for key in ("fps", "speedup"):
        v = opts.get(key)
        if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ScenarioError(f"--{key}: must be a finite number > 0, got {v!r}")


def holds_run(folder: Path) -> bool:
    return any((folder / name).exists() for name in RUN_MARKERS)


def check_out_dir(out, overwrite: bool = False, flag: str = "--out") -> Path:
    """``out`` can take a run: not empty, not a file nor under one, writable (probed with a folder
    created and removed again beside it), and not an earlier run unless ``overwrite``."""
    if str(out) == "":
        raise ScenarioError(f"{flag} '': an empty path; name the output folder")
    out = Path(out)
    check_path_names(out, flag)
    if out.exists() and not out.is_dir():
        raise ScenarioError(f"{flag} {out}: is a file, not a folder")
    resolved = out.resolve()
    if resolved == Path(resolved.anchor) or resolved == Path.cwd().resolve() or os.path.ismount(resolved):
        # the run's files are moved in by renaming the folder: impossible for /, the current folder
        # or a mount point (and replacing the current folder whole is never what was meant)
        raise ScenarioError(f"{flag} {out}: is the current folder, the root or a mount point; name a folder "
                            "inside it")
    ancestor = out
    while not ancestor.exists():
        if ancestor.is_symlink():
            raise ScenarioError(f"{flag} {out}: {ancestor} is a broken symbolic link")
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise ScenarioError(f"{flag} {out}: {ancestor} is a file, so no folder can be made under it")
    if out.is_dir():
        if holds_run(out) and not overwrite:
            raise ScenarioError(f"{flag} {out}: already holds a run (summary.json, run.mcap or report.md); "
                                "pass --overwrite to replace it whole, or choose another folder")
        if not holds_run(out) and any(out.iterdir()) and not overwrite:
            raise ScenarioError(f"{flag} {out}: is not empty and holds no run; choose an empty or a new folder "
                                "(--overwrite replaces it whole)")
        ancestor = out.parent if out.parent.exists() else ancestor
    try:
        probe = tempfile.mkdtemp(prefix=".usv-mj-probe-", dir=ancestor)
        os.rmdir(probe)
    except OSError as exc:
        raise ScenarioError(f"{flag} {out}: cannot write in {ancestor} ({exc.strerror or exc})") from None
    return out


def check_path_names(path: Path, flag: str) -> None:
    """Every part of ``path`` fits the file system's name limit (255 bytes on Linux)."""
    for part in Path(path).parts:
        if len(os.fsencode(part)) > 255:
            raise ScenarioError(f"{flag} {str(path)[:80]}...: the name {part[:40]}... is over 255 bytes")


def check_output_path(out, flag: str = "--out", *, folder: bool = True) -> Path:
    """An output of a command other than ``run`` (sweep, capability, compare: a folder; render: a
    file): not a file where a folder belongs, not under a file, names within limits, writable."""
    if str(out) == "":
        raise ScenarioError(f"{flag} '': an empty path; name the output")
    out = Path(out)
    check_path_names(out, flag)
    if folder and out.resolve() == Path(out.resolve().anchor):
        raise ScenarioError(f"{flag} {out}: is the root folder; name a folder for the outputs")
    if not folder and out.suffix.lower() != ".mp4":
        raise ScenarioError(f"{flag} {out}: a video file ends in .mp4")
    if folder and out.exists() and not out.is_dir():
        raise ScenarioError(f"{flag} {out}: is a file, not a folder")
    if not folder and out.is_dir():
        raise ScenarioError(f"{flag} {out}: is a folder; name the video file (e.g. {out / 'video.mp4'})")
    ancestor = out if folder else out.parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise ScenarioError(f"{flag} {out}: {ancestor} is a file, so nothing can be made under it")
    if not os.access(ancestor, os.W_OK):
        raise ScenarioError(f"{flag} {out}: {ancestor} is not writable")
    return out


def check_run(scenario: Scenario, out, *, video: bool, render_options: dict | None, overwrite: bool) -> Path:
    """Everything :func:`usv_mj.main_job.run_job` needs to hold before it creates anything."""
    out = check_out_dir(out, overwrite)
    check_reference(scenario)
    check_start_pose(scenario)
    check_plan(scenario)
    if video:
        check_video(render_options)
    return out
