"""The record of a run of several vessels: one :class:`RunRecord` per vessel on one time axis, and
the contacts between hulls.

Each vessel's record is an ordinary record (the core columns, then its own controller's diagnostic
block: :mod:`usv_mj.record.run_record`), so everything made from a record (summary, criteria,
figures, the log's topics) works on each vessel as on a single run. What belongs to the fleet:
the pairs of vessels (i < j, in the scenario's order), the contact force between each pair's hulls
per row [N] (MuJoCo's contact solver; 0 on the analytic plant, whose hulls do not touch), the
events of the encounter (a collision), and which vessel is the own ship.
"""

from __future__ import annotations

import numpy as np

from usv_mj.record.run_record import Event, RunRecord


def pairs_of(n: int) -> list[tuple[int, int]]:
    """The vessel pairs (i, j), i < j, in the order of a fleet's pair columns."""
    return [(i, j) for i in range(n) for j in range(i + 1, n)]


class FleetRecord:
    """A run of several vessels (module docstring).

    Attributes
    ----------
    names: the vessels' names, in the scenario's order. own: the own ship's name.
    records: {name: RunRecord}. pairs: :func:`pairs_of`. contacts: (rows, pairs) contact force [N].
    status, stop_reason, events, metadata, statics: the run's (as a RunRecord's).
    """

    def __init__(self, names, records: dict, own: str, capacity: int, metadata: dict | None = None):
        self.names = tuple(names)
        self.records = dict(records)
        self.own = own
        self.pairs = pairs_of(len(self.names))
        self.contacts = np.zeros((capacity, len(self.pairs)))
        self.events: list[Event] = []
        self.status = "running"
        self.stop_reason = ""
        self.metadata = dict(metadata or {})
        self.statics = None

    def __getitem__(self, name: str) -> RunRecord:
        return self.records[name]

    def __iter__(self):
        return iter(self.names)

    def __len__(self) -> int:
        return len(self.records[self.own])

    @property
    def n_rows(self) -> int:
        return self.records[self.own].n_rows

    @property
    def own_record(self) -> RunRecord:
        return self.records[self.own]

    def pair_name(self, p: int) -> str:
        i, j = self.pairs[p]
        return f"{self.names[i]}-{self.names[j]}"

    def contact_rows(self) -> np.ndarray:
        """(rows, pairs) contact forces of the rows written."""
        return self.contacts[:self.n_rows]

    def states(self) -> np.ndarray:
        """(rows, vessels, 6): every vessel's (x, y, psi, u, v, r) at every row."""
        cols = ("x", "y", "psi", "u", "v", "r")
        return np.stack([np.column_stack([self.records[n][c] for c in cols]) for n in self.names], axis=1)


def fleet_of_records(records: dict, own: str, metadata: dict | None = None) -> FleetRecord:
    """A :class:`FleetRecord` of vessels' records read back (a fleet's run log: each vessel a run of its
    own, usv_mj.jobs.fleet): the rows the records share, the contacts from their "vessel_contact"
    events (the force at each episode's first row: a log keeps the events, not the per-row forces)."""
    names = list(records)
    rows = min(r.n_rows for r in records.values())
    fleet = FleetRecord(names, records, own, max(rows, 1), metadata)
    t = records[own]["t"]
    seen = set()
    for name in names:
        for e in records[name].events:
            pair = tuple(e.values.get("pair", ())) if e.kind == "vessel_contact" else ()
            if len(pair) != 2 or (e.t, pair) in seen or not all(p in names for p in pair):
                continue
            seen.add((e.t, pair))
            if (e.t, pair) not in {(x.t, tuple(x.values.get("pair", ()))) for x in fleet.events}:
                fleet.events.append(e)
            i, j = sorted(names.index(p) for p in pair)
            k = int(np.argmin(np.abs(t[:rows] - e.t))) if rows else 0
            fleet.contacts[k, fleet.pairs.index((i, j))] = float(e.values.get("force_N", 1.0))
    statuses = {records[n].status for n in names}
    fleet.status = records[own].status if len(statuses) == 1 else sorted(statuses)[0]
    fleet.stop_reason = records[own].stop_reason
    return fleet
