"""``usv-mj plot RUN``: figures/ and report.md again from a run's MCAP log, without simulating."""

from __future__ import annotations

import sys
from pathlib import Path

from usv_mj.cli import args as flags
from usv_mj.cli.args import EXIT_OK
from usv_mj.cli.commands import COMMANDS
from usv_mj.core.errors import ScenarioError


def add_arguments(p) -> None:
    p.add_argument("run", metavar="RUN", help="a run log (run.mcap) or the run folder that holds it")
    flags.add_out_argument(p, "output folder (default: beside the log)")
    flags.add_overwrite_argument(p, "report.md and figures/ in --out that usv_mj wrote")


@COMMANDS.register("plot", arguments=add_arguments, help="figures and report again from a run's MCAP log",
                   description="Remake figures/ and report.md from RUN (an .mcap file or a run folder "
                   "holding run.mcap) without simulating.")
def run(args) -> int:
    from usv_mj.jobs.manoeuvres import record_outputs, spec_of_record
    from usv_mj.outputs.figures import draw_figures
    from usv_mj.outputs.log import read_run
    from usv_mj.outputs.outdir import check_folder, record
    from usv_mj.outputs.report import gains_section, write_report
    from usv_mj.record.criteria import criterion_of_record
    from usv_mj.record.summary import summarize

    path = Path(args.run)
    if path.is_dir():
        path = path / "run.mcap"
    if not path.is_file() and not path.is_symlink():   # a link that leads nowhere: read_run says so
        raise ScenarioError(f"{path}: no such run log" if not path.exists() else f"{path}: is not a regular file")
    from usv_mj.outputs.log.reader import RunLogReadError

    try:
        log = read_run(path)
        record_ = log.record
    except RunLogReadError as exc:
        raise ScenarioError(str(exc)) from None
    except (ValueError, KeyError, OSError) as exc:
        raise ScenarioError(f"{path}: not a readable run log ({exc})") from None
    if len(record_) == 0:
        why = f": {log.problem}" if log.problem else ""
        raise ScenarioError(f"{path}: the log holds no rows of a run (nothing to plot){why}")
    out = Path(args.out) if args.out else path.parent
    from usv_mj.outputs.log.fleet_log import fleet_of_log

    fleet = fleet_of_log(log)
    if fleet is not None:   # several vessels (usv_mj.jobs.fleet): the own ship's figures and the fleet's
        return _plot_fleet(fleet, log, path, out, args.overwrite)
    manoeuvre = ("manoeuvre.json",) if spec_of_record(log.record) is not None else ()
    check_folder(out, args.overwrite, writes=("report.md", "figures", *manoeuvre))
    out.mkdir(parents=True, exist_ok=True)
    if log.notice:
        print(f"usv-mj plot: warning: the log is incomplete: {log.notice}", file=sys.stderr)
    figures = draw_figures(log.record, out / "figures", log.baseline, note=log.notice)
    # a manoeuvre's figures, manoeuvre.json and its report section (nothing for another run)
    sections, manoeuvre_files, _ = record_outputs(log.record, out)
    figures = list(figures) + list(manoeuvre_files.get("manoeuvre_figures", []))
    summary = summarize(log.record)
    base = summarize(log.baseline, criterion_of_record(log.record)) if log.baseline is not None else None
    gains = gains_section(log.record, log.baseline)
    write_report(out / "report.md", summary, base,
                 log.metadata.get("step_check"),
                 extra_sections=sections + ([gains] if gains else []) + ([f"## The log is incomplete\n\n**{log.notice}.** The figures and numbers "
                                             "above are of what was recovered."] if log.notice else []) or None)
    record(out, ["report.md", *(["manoeuvre.json"] if sections else []),
                 *(Path(f).relative_to(out).as_posix() for f in figures)])
    print(f"figures and report from {path} written to {out}/" + (" (from an incomplete log, see above)"
                                                                 if log.notice else ""))
    return EXIT_OK


def _plot_fleet(fleet, log, path: Path, out: Path, overwrite: bool) -> int:
    from usv_mj.outputs.figures import draw_figures
    from usv_mj.outputs.fleet_figures import draw_fleet_figures
    from usv_mj.outputs.fleet_report import write_fleet_report
    from usv_mj.outputs.outdir import check_folder, record
    from usv_mj.record.encounters import encounter_summary
    from usv_mj.record.summary import summarize

    check_folder(out, overwrite, writes=("report.md", "figures"))
    out.mkdir(parents=True, exist_ok=True)
    if log.notice:
        print(f"usv-mj plot: warning: the log is incomplete: {log.notice}", file=sys.stderr)
    encounters = encounter_summary(fleet)
    figures = draw_figures(fleet.own_record, out / "figures", note=log.notice) + \
        draw_fleet_figures(fleet, out / "figures", note=log.notice, summary=encounters)
    own = fleet.own_record
    summary = {"vessels": {n: summarize(fleet[n]) for n in fleet.names}, "encounters": encounters,
               "own_ship": fleet.own, "status": fleet.status, "stop_reason": fleet.stop_reason,
               "plant": own.metadata.get("plant", "?"), "duration_s": float(own["t"][-1]) if len(own) else 0.0}
    write_fleet_report(out / "report.md", summary)
    record(out, ["report.md", *(Path(f).relative_to(out).as_posix() for f in figures)])
    print(f"figures and report of {len(fleet.names)} vessels from {path} written to {out}/")
    return EXIT_OK
