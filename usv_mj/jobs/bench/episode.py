"""The benchmark's part of a sweep task: an episode's run and its metrics as row columns, on the worker.

:func:`usv_mj.jobs.sweep.runner.run_one` runs the episode (``simulate``, or the suite's episode
function: a policy's, :mod:`usv_mj.jobs.bench.policy`, or :func:`fleet_episode` for a task of
several vessels) and adds what :func:`metrics_row` returns to its row: every metric of
:func:`usv_mj.jobs.bench.metrics.episode_metrics` (or, for an encounter,
:func:`usv_mj.jobs.bench.metrics.encounter_metrics`) as a column ``m.<name>`` (``m.iae_cross_track``,
``m.min_range_m``, ...), so the row carries the sweep's own columns (status, criterion, summary
fields) beside them.
"""

from __future__ import annotations

PREFIX = "m."
#: where an encounter episode's metrics travel from :func:`fleet_episode` to :func:`metrics_row`
ENCOUNTER_KEY = "bench_encounter_metrics"


def fleet_episode(scenario, options: dict):
    """An episode of several vessels (a scenario with ``[[vessels]]``: an Imazu situation): the fleet
    through :func:`usv_mj.loop.simulate.simulate` (which runs a fleet as it runs a single hull), then
    the own ship alone on its route (its own scenario, the same controller, sea and duration: the
    no-traffic run the time loss is measured against). Returns the own ship's record, as a single
    episode's, with the encounter's metrics (:func:`usv_mj.jobs.bench.metrics.encounter_metrics`,
    ``options["encounter"]["situations"]``: {vessel index: situation}) in its metadata."""
    from usv_mj.jobs.bench.metrics import encounter_metrics
    from usv_mj.loop.simulate import simulate

    fleet = simulate(scenario)
    own = fleet.own_record
    alone = None
    if fleet.status == "completed":
        alone = simulate(next(v.scenario for v in scenario.vessels if v.own_ship))
    situations = {int(k): v for k, v in ((options.get("encounter") or {}).get("situations") or {}).items()}
    own.metadata[ENCOUNTER_KEY] = encounter_metrics(fleet, alone, situations)
    return own


def metrics_row(record, options: dict) -> dict:
    """``{"m.<metric>": value}`` of ``record`` with the task's metric options (``options["metrics"]``);
    an encounter episode's (:func:`fleet_episode`) are its encounter metrics."""
    from usv_mj.jobs.bench.metrics import episode_metrics

    if ENCOUNTER_KEY in record.metadata:
        return {PREFIX + k: v for k, v in record.metadata[ENCOUNTER_KEY].items()}
    return {PREFIX + k: v for k, v in episode_metrics(record, **(options.get("metrics") or {})).items()}
