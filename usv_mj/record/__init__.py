"""Record: a run's rows (in memory or streamed to disk), its summary and the criteria it is judged by.

Plain data: nothing here builds or runs a part. ``from usv_mj.record import RunRecord`` is the
public door; the record itself is :mod:`usv_mj.record.run_record`.
"""

from usv_mj.record.run_record import COL, COLUMNS, CORE_COLUMNS, Event, RunRecord  # noqa: F401

__all__ = ["RunRecord", "Event", "COL", "COLUMNS", "CORE_COLUMNS"]
