"""``usv-mj env TASK``: roll out a policy in a USV dm_control task (:mod:`usv_mj.envs`): returns per
episode, and a video of the first one.

Tasks: those of :data:`usv_mj.core.registry.TASKS` (a plug-in's too): ``track`` (the paper's
reference from a randomised start), ``track_waves`` (the same in the moderate sea with current and
wind), ``harbor`` (reach a goal through a randomised harbour without contact), ``harbor_waves``.
Policies: ``ppc`` (the paper's adaptive PPC law on the environment's observations) and ``random``
(uniform actions within the thrust bounds). Observations, rewards and termination:
``pydoc usv_mj.envs.tasks``.

``--vessel KIND`` runs the task on another hull (as ``usv-mj run --vessel``: a registered vessel
kind, a vessel data file or ``module:Name``; its options by ``--set vessel.KEY=VALUE``): its rigid
body, hydrodynamics, actuators (the action bounds and the allocation: on KVLCC2 to its propeller
and rudder) and drawn hull.

Exit codes: 0 done, 2 bad options, 1 other failures (a task the MuJoCo plant cannot run yet, say).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from usv_mj.cli import args as flags
from usv_mj.cli.commands import COMMANDS


def task_kind(value: str) -> str:
    """``TASK``: a kind of :data:`usv_mj.core.registry.TASKS`, read when the value is parsed (never
    for --help), so a task registered by a plug-in's module or entry point is one too; or
    ``package.module:factory``. A bad one is argparse's one line listing the tasks."""
    from usv_mj.core.errors import UnknownKindError
    from usv_mj.core.registry import TASKS

    if value not in TASKS.kinds() and ":" not in value:
        raise argparse.ArgumentTypeError(f"invalid choice: {value!r} (choose from "
                                         f"{', '.join(map(repr, TASKS.kinds()))}); or 'package.module:factory'")
    try:
        TASKS.get(value, "usv-mj env")
    except UnknownKindError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return value


def add_arguments(p) -> None:
    p.add_argument("task", metavar="TASK", type=task_kind,
                   help="a task of usv_mj.envs (usv-mj kinds task: each one's options and tags; a plug-in's too), "
                   "or package.module:factory. track: the paper's reference from a randomised start; track_waves: "
                   "the same in the moderate sea with current and wind; harbor: reach a goal through a randomised "
                   "harbour without contact; harbor_waves: the harbour in that sea")
    p.add_argument("--policy", choices=("ppc", "controller", "random"), default="ppc",
                   help="ppc: the paper's controller (docs/model.md §3) on the observations; controller: the "
                   "scenario's [controller] kind (a plug-in's too); random: uniform actions")
    flags.add_set_argument(p, "task's scenario", "controller.kind=my-pd or --set trajectory.kind=lawnmower")
    flags.add_vessel_argument(p)   # the flag of usv-mj run: the hull the task runs (docs/vessels.md)
    p.add_argument("--episodes", type=int, default=1, help="number of episodes (default 1)")
    p.add_argument("--seed", type=int, default=0, help="environment (and random policy) seed (default 0)")
    flags.add_duration_argument(p, "episode length [s] (default 30, harbor 90)")
    p.add_argument("--no-quantize", action="store_true", help="apply actions without the hysteresis quantizer")
    p.add_argument("--video", default="renders/env.mp4",
                   help="video of the first episode (default renders/env.mp4); 'none' to skip")
    flags.add_size_argument(p, (640, 360))
    flags.add_overwrite_argument(p, "the --video file and its .png still when usv_mj wrote them")
    flags.add_live_arguments(p)   # --live: each episode served to Foxglove as it ends (usv_mj.outputs.log.live)


def rollout(env, policy):
    """One episode: returns (return, steps, info, rows) with rows = (t, state, reference, action, thrust,
    command, saturated) (:meth:`usv_mj.envs.USVEnvironment.history`'s)."""
    ts = env.reset()
    task = env.task
    rows = []

    from usv_mj.envs.environment import step_row

    def row():
        rows.append(step_row(env))

    total, n = 0.0, 0
    row()
    while not ts.last():
        ts = env.step(policy(ts))
        total += ts.reward
        n += 1
        row()
    return total, n, dict(task.info), rows


@COMMANDS.register(
    "env", arguments=add_arguments,
    help="roll out a policy (ppc, random) in a dm_control task (track, track_waves, harbor): returns and a video",
    description="Roll out a policy (ppc: the paper's controller; random) in a dm_control task (track,\n"
                "track_waves, harbor, harbor_waves) and print the returns; --video writes the first episode;\n"
                "--vessel KIND runs it on another hull (as usv-mj run --vessel: plant, actuators, picture).")
def run(args) -> int:
    from usv_mj.core.errors import ScenarioError
    from usv_mj.envs import PPCPolicy, RandomPolicy, load

    if args.episodes < 1:
        print(f"usv-mj env: error: --episodes must be >= 1, got {args.episodes}", file=sys.stderr)
        return 2
    if args.video.lower() == "none":
        args.video = None
    if args.video is not None:  # the video's file is checked before any episode runs (its size when parsed)
        from usv_mj.outputs.outdir import check_file

        try:
            check_file(args.video, args.overwrite, "--video")
        except ValueError as exc:
            print(f"usv-mj env: error: {exc}", file=sys.stderr)
            return 2
    options = {"quantize": False} if args.no_quantize else {}  # else the task's own default
    if args.set:
        try:
            options["overrides"] = flags.parse_set(args.set)
        except ScenarioError as exc:
            print(f"usv-mj env: error: {exc}", file=sys.stderr)
            return 2
    if args.duration is not None:
        options["duration"] = args.duration
    if getattr(args, "vessel", None):
        options["vessel"] = args.vessel
    try:
        env = load(args.task, seed=args.seed, **options)
    except (ValueError, ScenarioError) as exc:
        print(f"usv-mj env: error: {exc}", file=sys.stderr)
        return 2
    except NotImplementedError as exc:
        print(f"usv-mj env: {exc}", file=sys.stderr)
        return 1
    try:
        live = _live_server(args)
        if args.policy == "random":
            policy = RandomPolicy(env, seed=args.seed)
        else:
            from usv_mj.builder import make_controller

            policy = PPCPolicy(env, make_controller(env.task.scenario) if args.policy == "controller" else None)
        first_rows, returns = None, []
        for ep in range(args.episodes):
            wall = time.perf_counter()
            total, n, info, rows = rollout(env, policy)
            wall = time.perf_counter() - wall
            returns.append(total)
            if ep == 0 and args.video is not None:
                first_rows = rows  # rendered now: the harbor model of this episode goes at the next reset
            end = info["reason"] or "time limit"
            print(f"episode {ep + 1}: return {total:.2f} over {n} steps ({total / max(n, 1):.3f} per step), "
                  f"{end}; {n / wall:.0f} steps/s")
            if first_rows is not None:
                _video(env, first_rows, args)
                first_rows = None
            if live is not None:
                _serve_episode(live, env, rows, args, ep)
        mean = sum(returns) / len(returns)
        print(f"{args.task} / {args.policy}: mean return {mean:.2f} over {len(returns)} episode(s)")
        if live is not None:
            live.finish()
    finally:
        env.close()
    return 0


def _live_server(args):
    if getattr(args, "live", False):
        import tempfile

        args.live_folder = tempfile.TemporaryDirectory(prefix="usv_mj_env_live_")
    return flags.live_server(args)


def _serve_episode(live, env, rows, args, ep: int) -> None:
    """Serve one finished episode to Foxglove: its record (episode_record) through the run log's own
    writer (topics /usv/..., the same as a run's), into a file of a temporary folder."""
    from usv_mj.outputs.log import RunLogWriter

    from usv_mj.envs import episode_record

    record = episode_record(env, rows, {"task": args.task, "policy": args.policy, "episode": ep + 1})
    scenario = getattr(env.task, "episode_scenario", None) or env.task.scenario
    with RunLogWriter(Path(args.live_folder.name) / f"episode{ep + 1}.mcap", scenario, live=live) as writer:
        sink = writer.sink("main")
        sink.start(record)
        sink.rows(record, 0, len(record))
        sink.finish(record)


def _video(env, rows, args) -> None:
    """Render the first episode through usv_mj.outputs.render (a RunRecord replay); skipped with a note if the
    renderer or GL is not available."""
    try:
        from usv_mj.outputs.render import render_run

        from usv_mj.envs import episode_record

        w, h = args.size
        record = episode_record(env, rows, {"task": args.task, "policy": args.policy})
        out = Path(args.video)
        out.parent.mkdir(parents=True, exist_ok=True)
        kwargs = {}
        if getattr(env.task, "episode_scenario", env.task.scenario).obstacles:
            kwargs["model"] = env.physics.plant.render_model_path  # the episode's own layout (the harbour's)
        info = render_run(record, out, width=w, height=h, progress=False, **kwargs)
        from usv_mj.outputs.outdir import record_file

        record_file(out)
        print(f"video: {info['mp4']} ({info['frames']} frames)")
    except Exception as exc:  # noqa: BLE001 - the rollout is the result; the video is a bonus
        print(f"usv-mj env: no video ({type(exc).__name__}: {exc})", file=sys.stderr)
