"""The standard manoeuvres: turning circle, zig-zag, Dieudonné's spiral, stopping test (issue 26 item 3).

::

    from usv_mj import load_scenario
    from usv_mj.jobs.manoeuvres import turning_circle, zigzag, spiral, stopping
    m = turning_circle(load_scenario(preset="paper"), plant_kind="analytic")   # dict of measures
    m["measures"]["tactical_diameter_m"], m["imo"]["rows"]
    zigzag(scenario, angle_deg=20, out_dir="renders/zz20")   # + figures, run.mcap, report.md, manoeuvre.json

Each is one run of the scenario through the one build (:func:`usv_mj.build` via
:func:`usv_mj.simulate`) with the manoeuvre's input as its controller (:mod:`.options`); with
``out_dir`` it goes through :func:`usv_mj.jobs.run.run_job` (the MCAP log, the run's figures and
report, a video on request) and adds the manoeuvre's figures (:mod:`.figures`), a section of
``report.md`` and ``manoeuvre.json``. The measures are those of :mod:`.measures`; the criteria of
IMO MSC.137(76) (:mod:`.imo`) are printed beside them, with whether they apply to the vessel.
The command line: ``usv-mj manoeuvre turning|zigzag|spiral|stopping`` (:mod:`.cli`).
"""

from __future__ import annotations

import json
import math

import numpy as np
from dataclasses import asdict, replace
from pathlib import Path

from usv_mj.physics.channels import FORCES, RUDDER_ANGLE
from usv_mj.jobs.manoeuvres import imo
from usv_mj.jobs.manoeuvres.measures import spiral_measures, stopping_measures, turning_measures, zigzag_measures
from usv_mj.scenario.manoeuvre import KINDS, ManoeuvreSpec, manoeuvre_from_table
from usv_mj.jobs.manoeuvres.trial import execute_time, manoeuvre_scenario

__all__ = ["run_manoeuvre", "turning_circle", "zigzag", "spiral", "stopping", "measure", "vessel_length",
           "record_outputs", "spec_of_record",
           "ManoeuvreSpec", "KINDS"]

#: the paper's hull: models/usv.xml spans x = -0.98 m (transom) to +1.00 m (bow)
PAPER_HULL_LENGTH_M = 1.98   # m: the paper vessel's L (usv_mj.vessels paper; models/usv.xml, x from -0.98 to 1.0)


def vessel_length(scenario) -> float:
    """The vessel's length L [m]: its ``[vessel]``'s main dimensions (:mod:`usv_mj.vessels`), from a
    Scenario or from its ``to_dict()`` (a run's metadata); the paper hull's 2 m for a table that
    names no vessel (an older log)."""
    dims = getattr(vessel_model(scenario), "dimensions", None)
    return float(dims.L) if dims is not None else PAPER_HULL_LENGTH_M


def vessel_model(scenario):
    """The resolved :class:`usv_mj.vessels.Vessel` of a Scenario or of its ``to_dict()`` (a run's
    metadata: its ``[vessel]`` table; ``[ship]`` only for the paper vessel, whose options it is), or
    None for a table that names no vessel (an older log)."""
    if isinstance(scenario, dict):
        from usv_mj.scenario.spec import vessel_of_table as of_table

        return of_table(scenario)
    return getattr(getattr(scenario, "vessel", None), "model", None)


def spec_of_record(record) -> ManoeuvreSpec | None:
    """The manoeuvre a run's record was made by (from its metadata), or None for any other run."""
    table = (record.metadata.get("scenario") or {}).get("manoeuvre")
    if not isinstance(table, dict) or "kind" not in table:
        return None
    return manoeuvre_from_table({"kind": table["kind"], **(table.get("options") or {})}, "the run's metadata")


def record_outputs(record, out, spec: ManoeuvreSpec | None = None, length: float | None = None):
    """The manoeuvre's outputs of a finished run into folder ``out``: its figures in ``figures/``,
    ``manoeuvre.json``; returns (report sections, {name: path}, result). ``spec`` and ``length``
    default to the record's own (:func:`spec_of_record`, :func:`vessel_length` of its metadata); a
    record of no manoeuvre gives ([], {}, None). ``usv-mj plot`` remakes them from a log."""
    from usv_mj.jobs.run import write_json

    from usv_mj.jobs.manoeuvres.figures import draw_manoeuvre_figures

    spec = spec if spec is not None else spec_of_record(record)
    if spec is None:
        return [], {}, None
    if length is None:
        length = vessel_length(record.metadata.get("scenario") or {})
    out = Path(out)
    result = measure(record, spec, length)
    _check_finished(result)
    label = f"{record.metadata.get('plant')} plant"
    figs = [] if result.get("ended_before_execute") else \
        draw_manoeuvre_figures(record, spec.kind, result, out / "figures", execute_time(spec), label)
    write_json(out / "manoeuvre.json", result)
    return [report_section(result)], {"manoeuvre": out / "manoeuvre.json", "manoeuvre_figures": figs}, result


def ended_before_execute(record, spec: ManoeuvreSpec) -> str | None:
    """Why a run has nothing to measure: it ended (diverged, interrupted) before the execute of a
    turning or stopping test (the options refuse a duration that does not pass it); else None."""
    if spec.kind not in ("turning", "stopping"):
        return None
    t, t_execute = record["t"], execute_time(spec)
    end = float(t[-1]) if len(t) else 0.0
    if len(t) and end >= t_execute:
        return None
    return (f"the run ended at t = {end:g} s ({record.status}: {record.stop_reason or 'no reason recorded'}), "
            f"before the execute at {t_execute:g} s: nothing to measure")


def measure(record, spec: ManoeuvreSpec, length: float) -> dict:
    """The measures of manoeuvre ``spec`` in a run's ``record`` (:mod:`.measures`) with the IMO rows."""
    o = spec.options
    t = record["t"]
    vessel = vessel_model(record.metadata.get("scenario") or {})
    ruddered = getattr(vessel, "channels", FORCES).yaw == RUDDER_ANGLE   # its "rudder" is a rudder, not a moment
    scale = getattr(vessel, "scale", None)
    early = ended_before_execute(record, spec)
    if early is not None:
        m = {"note": early}
        crit = imo.criteria(spec.kind, m, length, o.approach_speed, scale=scale)
    elif spec.kind == "turning":
        m = turning_measures(t, record["x"], record["y"], record["psi"], record["u"], record["v"], record["r"],
                             t_execute=o.approach_s, steady_after_deg=o.steady_after_deg, length=length)
        crit = imo.criteria("turning", m, length, o.approach_speed, scale=scale)
    elif spec.kind == "zigzag":
        m = zigzag_measures(t, record["heading_change"], record["tau_r"], o.angle_deg, record["x"], record["y"],
                            length)
        crit = imo.criteria("zigzag", m, length, o.approach_speed, switch_deg=o.angle_deg, scale=scale)
    elif spec.kind == "spiral":   # the commands in N m, or a ruddered vessel's rudder angles in deg
        cmds = o.commands(o.max_rudder_deg if ruddered else None)
        holds = [(i * o.hold_s, (i + 1) * o.hold_s, c, b) for i, (c, b) in enumerate(cmds)]
        m = spiral_measures(t, record["r"], holds, o.settle_fraction)
        m["command_unit"] = "deg" if ruddered else "N m"   # the points' and the loop's commands
        crit = imo.criteria("spiral", m, length, o.approach_speed, scale=scale)
        crit["note"] += "; MSC.137(76) sets no criterion on the spiral"
    else:
        m = stopping_measures(t, record["x"], record["y"], record["psi"], record["u"], record["v"],
                              stop_speed=o.stop_speed, t_execute=o.approach_s, length=length)
        crit = imo.criteria("stopping", m, length, o.approach_speed)
    # where an actuator limit cut the command (usv_mj.physics.actuators): the "rudder" or the approach force
    # was then not what the options asked for
    saturated = {axis: float(np.mean(record[f"sat_{axis}"] > 0)) if len(t) else 0.0 for axis in ("u", "r")}
    rudder = ("commanded yaw moment tau_r [N m], realized by the vessel's actuators (docs/manoeuvres.md)"
              if not ruddered else
              "rudder angle delta [rad] (the tau_r channel, positive to port), moved at the vessel's rudder rate; "
              "the propeller's n_P [1/s] (the tau_u channel) held at the approach's (docs/manoeuvres.md)")
    if ruddered:   # the rudder rate cuts every step of the command by design: not a saturation
        saturated["note"] = "ruddered vessel: sat_r marks the steering gear's rate limit at work"
        m["propeller_rps"] = float(record["f_u"][-1]) if len(t) else None
    return {"kind": spec.kind, "options": asdict(o), "length_m": length, "plant": record.metadata.get("plant"),
            "saturated_fraction": saturated, **({"ended_before_execute": True} if early is not None else {}),
            "status": record.status, "simulated_s": float(t[-1]) if len(t) else 0.0,
            "rudder": rudder, "rudder_channel": getattr(vessel, "channels", FORCES).yaw.to_metadata(),
            "measures": m, "imo": crit}


def _fmt(v, unit=""):
    if v is None:
        return "—"
    if isinstance(v, float):
        return f"{v:.3f}{unit}"
    return f"{v}{unit}"


def command_cut(result: dict) -> bool:
    """True when an actuator limit cut the manoeuvre's command (its ``saturated_fraction``): either
    channel, except a ruddered vessel's rudder, whose rate limit acts on every step by design."""
    sat = result.get("saturated_fraction") or {}
    return bool(sat.get("u")) or (bool(sat.get("r")) and "note" not in sat)


def report_section(result: dict) -> str:
    """The manoeuvre's part of ``report.md``: the measures, the IMO rows, the figures."""
    m, kind = result["measures"], result["kind"]
    lines = [f"## Manoeuvre: {kind}", "",
             f"Options: {json.dumps(result['options'])}. Vessel length L = {result['length_m']:g} m; the "
             f"\"rudder\" is the {result['rudder']}.", "", "| measure | value |", "|---|---|"]
    for key, value in m.items():
        if key in ("points",) or isinstance(value, (list, dict)) and key != "loop_commands":
            continue
        lines.append(f"| {key} | {_fmt(value)} |")
    if kind == "spiral":
        lines += ["", f"| command [{m.get('command_unit', 'N m')}] | branch | steady r [rad/s] | spread [rad/s] |",
                  "|---|---|---|---|"]
        lines += [f"| {p['command']:g} | {p['branch']} | {p['yaw_rate']:+.4f} | {p['spread']:.1e} |" for p in m["points"]]
    sat = result.get("saturated_fraction") or {}
    if command_cut(result):
        lines += ["", f"**The actuators cut the command** in {100 * sat['u']:.1f} % (surge) and "
                  f"{100 * sat['r']:.1f} % (yaw) of the steps: the manoeuvre is not the one its options ask for."]
    c = result["imo"]
    lines += ["", f"**{c['standard']}**: {c['note']}.", ""]
    if c["rows"]:
        lines += ["| criterion | value | limit | met |", "|---|---|---|---|"]
        lines += [f"| {r['criterion']} | {_fmt(r['value'])} {r['unit']} | {r['limit']:g} {r['unit']} | "
                  f"{'—' if r['met'] is None else ('yes' if r['met'] else 'no')} |" for r in c["rows"]]
    lines += ["", "The sections above compare the run with its reference, the original course at the approach "
              "speed; a manoeuvre is not judged on it."]
    if result.get("ended_before_execute"):   # no manoeuvre figures: nothing after the execute
        return "\n".join(lines)
    lines += ["", "![track](figures/manoeuvre_track.png)", "", "![time series](figures/manoeuvre_time.png)"]
    if kind == "spiral":
        lines += ["", "![spiral](figures/manoeuvre_spiral.png)"]
    return "\n".join(lines)


def _check_finished(result: dict) -> None:
    for key, value in result["measures"].items():
        if isinstance(value, float) and not math.isfinite(value):
            result["measures"][key] = None


def run_manoeuvre(scenario, spec: ManoeuvreSpec | None = None, *, plant_kind: str | None = None, out_dir=None,
                  video: bool = False, progress: bool = False, overwrite: bool = False,
                  render_options: dict | None = None) -> dict:
    """Run manoeuvre ``spec`` (default: the scenario's ``[manoeuvre]``) and return its measures (module
    docstring); with ``out_dir`` write every output there (``result["job"]``: the JobResult)."""
    from usv_mj.builder import as_scenario
    from usv_mj.core.errors import expected
    from usv_mj.loop.simulate import simulate

    scenario = as_scenario(scenario, "run_manoeuvre")
    if spec is not None and not isinstance(spec, ManoeuvreSpec):
        raise expected("run_manoeuvre", "spec", "a ManoeuvreSpec (usv_mj.jobs.manoeuvres.ManoeuvreSpec) or None", spec)
    ms = manoeuvre_scenario(scenario, spec)
    spec = ms.manoeuvre
    length = vessel_length(ms)
    if out_dir is None:
        record = simulate(ms, plant_kind=plant_kind)
        result = measure(record, spec, length)
        _check_finished(result)
        return result
    from usv_mj.jobs.run import run_job

    holder = {}

    def outputs(record, out: Path):
        sections, files, holder["result"] = record_outputs(record, out, spec, length)
        return sections, files

    job = run_job(ms, out_dir, plant_kind=plant_kind, baseline=False, video=video, log=True, progress=progress,
                  step_check=False, render_options=render_options, overwrite=overwrite, extra_outputs=outputs)
    result = holder.get("result") or {"kind": spec.kind, "measures": {}, "status": job.summary.get("status")}
    result["job"] = job
    return result


_API_NAMES = {"turning": "turning_circle", "zigzag": "zigzag", "spiral": "spiral", "stopping": "stopping"}


def _run_kind(kind, scenario, plant_kind, out_dir, video, options):
    from dataclasses import fields

    from usv_mj.builder import as_scenario
    from usv_mj.core.errors import ArgumentTypeError

    where = _API_NAMES[kind]
    scenario = as_scenario(scenario, where)
    known = [f.name for f in fields(KINDS[kind])]
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise ArgumentTypeError(f"{where}: unknown option {unknown[0]!r}; the options are {', '.join(known)} "
                                "(and plant_kind, out_dir, video)")
    vessel = getattr(getattr(scenario, "vessel", None), "model", None)
    base = scenario.manoeuvre.options if (scenario.manoeuvre is not None and scenario.manoeuvre.kind == kind) \
        else manoeuvre_from_table({"kind": kind}, where, vessel).options   # the vessel's defaults
    opts = replace(base, **options)   # validated again: a bad value is one ScenarioError naming its key
    return run_manoeuvre(scenario, ManoeuvreSpec(kind, opts), plant_kind=plant_kind, out_dir=out_dir, video=video)


def turning_circle(scenario, *, plant_kind=None, out_dir=None, video=False, **options) -> dict:
    """The turning circle of ``scenario``'s vessel; ``options``: :class:`.options.TurningOptions`'s fields."""
    return _run_kind("turning", scenario, plant_kind, out_dir, video, options)


def zigzag(scenario, *, plant_kind=None, out_dir=None, video=False, **options) -> dict:
    """The zig-zag (10/10 by default; ``angle_deg=20`` for 20/20): :class:`.options.ZigzagOptions`."""
    return _run_kind("zigzag", scenario, plant_kind, out_dir, video, options)


def spiral(scenario, *, plant_kind=None, out_dir=None, video=False, **options) -> dict:
    """Dieudonné's spiral: :class:`.options.SpiralOptions`."""
    return _run_kind("spiral", scenario, plant_kind, out_dir, video, options)


def stopping(scenario, *, plant_kind=None, out_dir=None, video=False, **options) -> dict:
    """The stopping test: :class:`.options.StoppingOptions`."""
    return _run_kind("stopping", scenario, plant_kind, out_dir, video, options)
