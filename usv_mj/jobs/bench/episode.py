"""The benchmark's part of a sweep task: the metrics of an episode as row columns, on the worker.

:func:`usv_mj.jobs.sweep.runner.run_one` runs the episode (``simulate``, or a policy's episode function)
and adds what :func:`metrics_row` returns to its row: every metric of
:func:`usv_mj.jobs.bench.metrics.episode_metrics` as a column ``m.<name>`` (``m.iae_cross_track``, ...),
so the row carries the sweep's own columns (status, criterion, summary fields) beside them.
"""

from __future__ import annotations

PREFIX = "m."


def metrics_row(record, options: dict) -> dict:
    """``{"m.<metric>": value}`` of ``record`` with the task's metric options (``options["metrics"]``)."""
    from usv_mj.jobs.bench.metrics import episode_metrics

    return {PREFIX + k: v for k, v in episode_metrics(record, **(options.get("metrics") or {})).items()}
