"""The encounter measures of a run of several vessels, from its records alone (a run, or its log).

For every pair of vessels (i < j), at every row: the geometry of :mod:`usv_mj.physics.encounters`
(range, bearings, contact angle, course difference, TCPA, DCPA of vessel j seen from vessel i), and
the pair's summary: the closest approach (its range, time and the DCPA/TCPA predicted just before),
the hull-to-hull clearance against the own ship's safety domain, and the contact episodes.

The safety domain (docs/encounters.md): a circle about the own ship of ``SAFETY_DOMAIN_L`` own-ship
lengths (the research note's R_min = 3 L of Hagen et al. 2023's evaluation, scaled to the hull).
"""

from __future__ import annotations

import math

import numpy as np

from usv_mj.physics.encounters import GEOMETRY_FIELDS, N_GEOMETRY, pair_series_into
from usv_mj.record.fleet import FleetRecord

#: the own ship's safety domain radius, in own-ship lengths (centre to centre)
SAFETY_DOMAIN_L = 3.0


def pair_series(record: FleetRecord, i: int, j: int) -> np.ndarray:
    """(rows, N_GEOMETRY): vessel j seen from vessel i at every row (:data:`GEOMETRY_FIELDS`)."""
    states = record.states()
    out = np.empty((states.shape[0], N_GEOMETRY))
    pair_series_into(np.ascontiguousarray(states[:, i]), np.ascontiguousarray(states[:, j]), out)
    return out


def lengths_of(record: FleetRecord) -> dict:
    """Each vessel's hull length L [m] (its record's ``metadata["length_m"]``; None when unknown)."""
    return {name: record.records[name].metadata.get("length_m") for name in record.names}


def hulls_overlap(record: FleetRecord, i: int, j: int, ranges) -> np.ndarray:
    """Per row, whether vessels i and j overlap where the plant has no contact model (the analytic
    plant: the hulls pass through each other): the centre range ``ranges`` [m] below (L_i + L_j) / 2,
    L the hull lengths. All False on the MuJoCo plant (its contacts are the record's contact force)
    or when a length is unknown."""
    lengths = lengths_of(record)
    li, lj = lengths.get(record.names[i]), lengths.get(record.names[j])
    if record.metadata.get("plant") == "mujoco" or li is None or lj is None:
        return np.zeros(len(ranges), dtype=bool)
    return np.asarray(ranges) < (li + lj) / 2.0


def encounter_summary(record: FleetRecord) -> dict:
    """Per pair (``"own-target"``): the closest approach (``min_range_m``, ``t_min_range_s``), the
    DCPA and TCPA one second before it, the contact episodes (``contacts``: their start times and
    largest force [N]), and whether the own ship's safety domain (:data:`SAFETY_DOMAIN_L` own lengths)
    was entered, and on the analytic plant when the hulls overlapped (:func:`hulls_overlap`); and the run's
    ``collision`` (any contact or overlap), ``min_range_m`` over the own ship's pairs."""
    t = record.own_record["t"]
    dt = float(t[1] - t[0]) if len(t) > 1 else 0.0
    lengths = lengths_of(record)
    own_l = lengths.get(record.own)
    domain = None if own_l is None else SAFETY_DOMAIN_L * own_l
    contacts = record.contact_rows()
    pairs = {}
    for p, (i, j) in enumerate(record.pairs):
        g = pair_series(record, i, j)
        rng = g[:, GEOMETRY_FIELDS.index("range_m")]
        finite = np.isfinite(rng)
        k = int(np.argmin(np.where(finite, rng, np.inf))) if finite.any() else 0
        before = max(0, k - (int(round(1.0 / dt)) if dt > 0 else 0))
        on = contacts[:, p] > 1e-6
        edges = np.diff(np.concatenate(([False], on, [False])).astype(np.int8))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)   # each contact: rows [start, end)
        entry = {"vessels": [record.names[i], record.names[j]],
                 "min_range_m": float(rng[k]), "t_min_range_s": float(t[k]) if len(t) else 0.0,
                 "dcpa_before_m": float(g[before, GEOMETRY_FIELDS.index("dcpa_m")]),
                 "tcpa_before_s": float(g[before, GEOMETRY_FIELDS.index("tcpa_s")]),
                 "contacts": [{"t_s": float(t[s]), "max_force_N": float(contacts[s:e, p].max())}
                              for s, e in zip(starts[:20], ends[:20])],
                 "n_contacts": int(len(starts)),
                 "in_contact_s": float(on.sum() * dt)}
        overlap = hulls_overlap(record, i, j, np.where(finite, rng, np.inf))
        if overlap.any():   # the analytic plant: the hulls passed through each other
            entry["hulls_overlap_from_s"] = float(t[int(np.argmax(overlap))])
            entry["hulls_overlap_s"] = float(overlap.sum() * dt)
        if record.own in entry["vessels"] and domain is not None:
            entry["safety_domain_m"] = domain
            entry["safety_domain_entered"] = bool(rng[k] < domain)
        pairs[record.pair_name(p)] = entry
    own_pairs = [e for e in pairs.values() if record.own in e["vessels"]]
    return {"own_ship": record.own, "safety_domain_m": domain, "safety_domain_L": SAFETY_DOMAIN_L,
            "collision": any(e["contacts"] or "hulls_overlap_from_s" in e for e in pairs.values()),
            "min_range_m": min((e["min_range_m"] for e in own_pairs), default=math.nan),
            "pairs": pairs}
