"""Rows of a record kept for drawing: every extreme, a bounded number of points, chunk by chunk.

A figure of a ten-hour run at 1 kHz cannot draw 36 million points, and a plain stride (every n-th
row) drops the spikes between the kept rows. :func:`decimate` splits the rows into ``buckets``
equal ranges (about one per pixel column) and keeps, in each, the row of the minimum and the row of
the maximum of every drawn series, plus the first and the last row: a line through the kept
points covers, in every bucket, the full range of every series (the min/max envelope), so no
extreme is lost. The columns are read with :meth:`usv_mj.record.run_record.RunRecord.column_chunks`, so the
memory needed is a few chunks whatever the run's length.
"""

from __future__ import annotations

import math

import numpy as np

from usv_mj.record.store import CHUNK_ROWS

#: min/max buckets of a drawn series (two points each): about the pixel columns of a figure
BUCKETS = 4000


def decimate(record, names, derive=None, buckets: int = BUCKETS) -> dict:
    """The kept rows of the columns ``names`` (name -> values at those rows, ascending).

    ``derive(chunks) -> dict`` maps a dict of column chunks to the series to draw (e.g. a pose
    error from x and x_d; default: the columns themselves); the extremes of every derived series
    but ``t`` are kept. A record of at most 2 x ``buckets`` rows is returned whole.
    """
    names = tuple(names)
    n = len(record)
    b = max(1, math.ceil(n / max(1, int(buckets))))   # rows per bucket
    per_chunk = b * max(1, CHUNK_ROWS // b)           # chunks hold whole buckets
    parts: dict = {}
    lo = 0
    for chunks in zip(*(record.column_chunks(c, per_chunk) for c in names)):
        got = dict(zip(names, chunks))
        series = derive(got) if derive is not None else got
        m = len(next(iter(series.values())))
        if b == 1 or n <= 2 * buckets:
            keep = np.arange(m)
        else:
            keep = _extremes([v for k, v in series.items() if k != "t"], b, m)
            if lo == 0:
                keep = np.union1d(keep, [0])
            if lo + m == n:
                keep = np.union1d(keep, [m - 1])
        for k, v in series.items():
            parts.setdefault(k, []).append(np.asarray(v)[keep])
        lo += m
    return {k: np.concatenate(v) for k, v in parts.items()} if parts else \
        {k: np.empty(0) for k in (derive({c: np.empty(0) for c in names}) if derive else names)}


def _extremes(series, b: int, m: int) -> np.ndarray:
    """Indices (ascending, unique) of the min and max of each series in each bucket of ``b`` rows."""
    full = (m // b) * b
    found = []
    for v in series:
        v = np.asarray(v)
        if full:
            blocks = v[:full].reshape(-1, b)
            start = np.arange(0, full, b)
            found += [start + np.argmin(blocks, axis=1), start + np.argmax(blocks, axis=1)]
        if full < m:
            tail = v[full:]
            found += [np.array([full + np.argmin(tail), full + np.argmax(tail)])]
    return np.unique(np.concatenate(found)) if found else np.arange(0)
