"""A fleet's run log read back: the own ship's ``run.mcap`` and its companions, one per other vessel
(usv_mj.jobs.fleet), as a :class:`usv_mj.record.fleet.FleetRecord` (what ``usv-mj plot`` and
``usv-mj render`` redraw a fleet's figures and video from, with no simulation)."""

from __future__ import annotations

from usv_mj.record.fleet import FleetRecord, fleet_of_records


def is_fleet_log(log) -> bool:
    """The log (:func:`usv_mj.outputs.log.read_run`'s) is a fleet's: its main run names its vessel."""
    main = log.runs.get("main")
    return main is not None and bool(main.metadata.get("vessel_name")) and len(log.runs) > 1


def fleet_of_log(log) -> FleetRecord | None:
    """The :class:`FleetRecord` of a fleet's log (None for a single run's): each run keyed by its
    vessel's name, the own ship's run is "main"."""
    if not is_fleet_log(log):
        return None
    records = {}
    for run, record in log.runs.items():
        records[record.metadata.get("vessel_name") or run] = record
    own = log.runs["main"].metadata["vessel_name"]
    return fleet_of_records(records, own, {"vessels": list(records), "own_ship": own,
                                           "control_period_s": log.runs["main"].metadata.get("control_period_s")})
