"""``usv-mj manoeuvre turning|zigzag|spiral|stopping``: one standard manoeuvre, with ``run``'s flags.

    usv-mj manoeuvre turning --plant analytic                 the paper hull's turning circle
    usv-mj manoeuvre zigzag --set manoeuvre.angle_deg=20      the 20/20 zig-zag
    usv-mj manoeuvre spiral --out renders/spiral --video      the spiral, with a video
    usv-mj manoeuvre --scenario my.toml                       the scenario's own [manoeuvre]
    usv-mj manoeuvre turning --vessel all                     every vessel's turning circle in one figure

``--vessel A,B,...`` (or ``all``: every registered kind) runs the manoeuvre on each vessel into
--out/VESSEL/ and writes manoeuvre_vessels.png, vessels.json and vessels.md beside them (:mod:`.fleet`).

The manoeuvre's options are ``--set manoeuvre.KEY=VALUE`` (``usv-mj kinds`` does not list them:
:mod:`usv_mj.scenario.manoeuvre`); ``--duration`` sets ``manoeuvre.duration``. Writes into --out
(default renders/manoeuvre-KIND): manoeuvre.json (the measures and the IMO rows), report.md,
figures/ (manoeuvre_track.png, manoeuvre_time.png, manoeuvre_spiral.png and the run's own seven),
run.mcap, summary.json; video.mp4 with --video.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from usv_mj.cli import args as flags
from usv_mj.cli.args import EXIT_OK, EXIT_STOPPED
from usv_mj.cli.commands import COMMANDS
from usv_mj.core.errors import ScenarioError


def add_arguments(p) -> None:
    p.add_argument("kind", nargs="?", metavar="KIND", choices=flags.Choices("usv_mj.core.registry", "MANOEUVRES.kinds"),
                   help="the manoeuvre: %(choices)s (default: the scenario's [manoeuvre])")
    flags.add_scenario_arguments(
        p, duration_help="simulated time [s]: manoeuvre.duration (default: the manoeuvre's, 60 s; not the spiral)",
        sea_note=" (with --set manoeuvre.conditions=scenario: a manoeuvre runs in calm water by default)")
    flags.add_plant_argument(p)
    flags.add_vessel_argument(p, fleet=True)
    flags.add_out_argument(p, "output folder (default renders/manoeuvre-KIND)")
    flags.add_overwrite_argument(p, "--out whole when it holds an earlier usv_mj output")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--video", dest="video", action="store_true", help="also render video.mp4")
    g.add_argument("--no-video", dest="video", action="store_false", help="no video (the default)")
    p.set_defaults(video=False)
    flags.add_video_arguments(p)
    flags.add_quiet_argument(p)


def _scenario(args):
    duration, args.duration = args.duration, None   # the manoeuvre's duration, not the scenario's
    own = None
    if args.scenario:
        from usv_mj.support.example_files import resolve
        from usv_mj.support.toml_values import read_toml

        # a name of a shipped example, as load_scenario reads it
        table = read_toml(resolve(args.scenario, "scenarios"), ScenarioError, "scenario file").get("manoeuvre")
        own = table.get("kind", "turning") if isinstance(table, dict) else None
    if args.kind and own is not None and own != args.kind:
        raise ScenarioError(f"manoeuvre {args.kind}: {args.scenario}'s [manoeuvre] is kind {own!r}; "
                            "name that one or drop the table")
    if args.kind and not any(item.split("=", 1)[0].strip() == "manoeuvre.kind" for item in args.set):
        args.set = [f"manoeuvre.kind={args.kind}"] + list(args.set)  # before the kind's own --set keys
        args.implied_sets = 1   # not typed: an error is not blamed on it (usv_mj.cli.args)
    scenario = flags.scenario_from_args(args)
    spec = scenario.manoeuvre
    kind = spec.kind if spec is not None else None
    if kind is None:
        raise ScenarioError("name the manoeuvre (turning, zigzag, spiral, stopping) or give a scenario with "
                            "a [manoeuvre] table")
    if args.kind and kind != args.kind:
        raise ScenarioError(f"manoeuvre {args.kind}: --set manoeuvre.kind={kind} names another one")
    over = {"manoeuvre": {"kind": kind}}
    if duration is not None:
        if kind == "spiral":
            raise ScenarioError(f"--duration {duration:g}: the spiral's duration is its steps and hold_s "
                                "(--set manoeuvre.hold_s=...)")
        over["manoeuvre"]["duration"] = duration
    return scenario.with_overrides(over), kind


@COMMANDS.register(
    "manoeuvre", arguments=add_arguments,
    help="a standard manoeuvre (turning circle, zig-zag, spiral, stopping): measures, IMO criteria, figures",
    description="Run a standard manoeuvre of the vessel (turning circle, 10/10 or 20/20 zig-zag, Dieudonne's\n"
                "spiral, stopping test) on either plant, and write its measures (manoeuvre.json), the IMO\n"
                "MSC.137(76) criteria beside them, figures, report.md and run.mcap into --out (a video with\n"
                "--video). Options: --set manoeuvre.KEY=VALUE (README, Vessels and manoeuvres).")
def run(args) -> int:
    from usv_mj.jobs.manoeuvres import run_manoeuvre
    from usv_mj.jobs.manoeuvres.fleet import is_fleet
    from usv_mj.jobs.run import RunFailed

    if is_fleet(args.vessel):
        return _run_fleet(args)
    scenario, kind = _scenario(args)
    render_options, out = _outputs(args, f"manoeuvre-{kind}")
    t0 = time.perf_counter()
    try:
        result = run_manoeuvre(scenario, plant_kind=args.plant, out_dir=out, video=args.video,
                               progress=not args.quiet, overwrite=args.overwrite, render_options=render_options)
    except RunFailed as exc:
        print(f"usv-mj manoeuvre: {exc}", file=sys.stderr)
        return EXIT_STOPPED
    print(summary_lines(result, out, time.perf_counter() - t0))
    job = result["job"]
    if job.summary.get("job_stopped"):
        print(f"usv-mj manoeuvre: the job stopped early: {job.summary['job_stopped']}", file=sys.stderr)
        return EXIT_STOPPED
    if job.summary["status"] != "completed":
        print(f"usv-mj manoeuvre: the run {job.summary['status']}: {job.summary.get('stop_reason')}", file=sys.stderr)
        return EXIT_STOPPED
    return EXIT_OK


def _outputs(args, default_name: str):
    """(the video's render options, the output folder: --out or renders/DEFAULT_NAME), checked."""
    render_options = flags.video_options(args)
    if args.out is not None and args.out.strip() == "":
        raise ScenarioError("--out '': an empty path; name the output folder")
    return render_options, (Path(args.out) if args.out is not None else Path("renders") / default_name)


def _run_fleet(args) -> int:
    """``--vessel A,B,...`` / ``--vessel all``: the manoeuvre on each vessel (:mod:`.fleet`)."""
    import copy

    from usv_mj.jobs.manoeuvres.fleet import run_fleet, table_lines, vessel_list
    from usv_mj.jobs.run import RunFailed

    kinds = vessel_list(args.vessel)
    found = {}

    def scenario_for(vessel):
        one = copy.copy(args)
        one.vessel, one.set = vessel, list(args.set)
        scenario, found["kind"] = _scenario(one)
        return scenario

    scenario_for(kinds[0])     # the manoeuvre's kind (and the flags) checked before the list is run
    kind = found["kind"]
    render_options, out = _outputs(args, f"manoeuvre-{kind}-vessels")
    t0 = time.perf_counter()
    try:
        fleet = run_fleet(scenario_for, kinds, kind, out, plant_kind=args.plant, video=args.video,
                          progress=not args.quiet, overwrite=args.overwrite, render_options=render_options,
                          skip_refused=args.vessel.strip() == "all")
    except RunFailed as exc:
        print(f"usv-mj manoeuvre: {exc}", file=sys.stderr)
        return EXIT_STOPPED
    plant = fleet["rows"][0]["plant"] if fleet["rows"] else args.plant
    for vessel, why in fleet["skipped"]:   # --vessel all: those that cannot run this manoeuvre
        print(f"usv-mj manoeuvre: {vessel} left out: {why}", file=sys.stderr)
    kinds = [v for v in kinds if v not in dict(fleet["skipped"])]
    print(f"usv-mj manoeuvre {kind}: {len(kinds)} vessels, {plant} plant ({time.perf_counter() - t0:.1f} s)")
    print("\n".join(table_lines(kind, fleet["rows"])))
    print(f"  outputs in {out}/: manoeuvre_vessels.png, vessels.json, vessels.md and one folder per vessel "
          f"({', '.join(r['folder'] for r in fleet['rows'])})")
    bad = [v for v, job in fleet["jobs"].items() if job.summary.get("status") != "completed" or job.summary.get("job_stopped")]
    missing = [v for v in kinds if v not in fleet["jobs"]]
    if bad or missing:
        print(f"usv-mj manoeuvre: the run of {', '.join(bad)} did not complete"
              + (f"; not run: {', '.join(missing)}" if missing else ""), file=sys.stderr)
        return EXIT_STOPPED
    return EXIT_OK


def summary_lines(result: dict, out: Path, wall_s: float) -> str:
    """What the command prints: the measures, the IMO rows, the outputs."""
    m = result.get("measures", {})
    lines = [f"usv-mj manoeuvre {result['kind']}: {result.get('plant')} plant, L = {result.get('length_m', 0):g} m: "
             f"{result.get('status')} ({wall_s:.1f} s)"]
    for key, value in m.items():
        if isinstance(value, float):
            lines.append(f"  {key:32s} {value:10.3f}")
    if result["kind"] == "spiral":
        unit = m.get("command_unit", "N m")
        name = "rudder" if unit == "deg" else "tau_r"
        for p in m.get("points", []):
            lines.append(f"  {name} {p['command']:+7.2f} {unit} ({p['branch']:>4}): r = {p['yaw_rate']:+.4f} rad/s")
        lines.append(f"  hysteresis loop: {'yes' if m.get('hysteresis') else 'no'}, commands "
                     f"{m.get('loop_commands')} {unit}")
    sat = result.get("saturated_fraction") or {}
    from usv_mj.jobs.manoeuvres import command_cut

    if command_cut(result):   # a rudder's rate limit is by design (command_cut)
        lines.append(f"  warning: the actuators cut the command in {100 * sat['u']:.1f} % (surge) / "
                     f"{100 * sat['r']:.1f} % (yaw) of the steps")
    c = result.get("imo")
    if c:
        lines.append(f"  {c['standard']}: {c['note']}")
        for r in c["rows"]:
            value = "—" if r["value"] is None else f"{r['value']:.3f}"
            met = "—" if r["met"] is None else ("met" if r["met"] else "NOT met")
            lines.append(f"    {r['criterion']:40s} {value:>8} {r['unit']} (limit {r['limit']:g} {r['unit']}): {met}")
    lines.append(f"  outputs in {out}/: manoeuvre.json, report.md, figures/, run.mcap, summary.json"
                 + (", video.mp4" if "video" in result["job"].files else ""))
    return "\n".join(lines)
