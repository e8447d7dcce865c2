"""The benchmark's metrics of one episode, and their 95 % intervals over episodes (docs/metrics.md).

Every formula is here once; docs/metrics.md writes them out. Conventions (a :class:`RunRecord`):
rows are control steps t_k = k dt, the input of row k is held from t_k to t_{k+1} (the last row's
input is never applied).

- Errors: the cross-track error e_ct [m] is the path-normal offset from the reference point in the
  path frame of the reference velocity (x_d_dot, y_d_dot), :meth:`usv_mj.record.criteria.PathTolerance.errors`
  (> 0: left of the path); the heading error e_psi = wrap(psi - psi_d) [rad]
  (:func:`usv_mj.record.summary.pose_errors`). Their integrals IAE = int |e| dt, ISE = int e^2 dt use the
  trapezoid rule over the record (the state is continuous).
- Inputs: the force the actuators realize, f = (f_u [N], f_r [N m]) (what the plant receives; tau
  is the generalized force (f_u, 0, f_r)). Its integrals are exact sums of the zero-order hold:
  effort_u = sum_k |f_u,k| dt [N s], effort_r = sum_k |f_r,k| dt [N m s], energy =
  sum_k |f_u,k u_k + f_r,k r_k| dt [J] (tau . nu, the power at the row's velocity), k = 0..n-2.
- Activity: quantizer switches per second = (changes of the level index k_u, resp. k_r, between
  consecutive rows) / T; total variation TV_u = sum_k |f_u,k+1 - f_u,k| [N], TV_r [N m] over the
  applied inputs; T = t_last - t_0 [s].
- Saturation fraction: the share of applied rows with sat_u or sat_r set (an actuator limit cut
  the command).
- Settling: with a band b, the settling time is the first t_k after which every later |e| <= b:
  t_{j+1} for the last row j outside the band (0 when none is outside); an episode that ends outside
  the band never settled: its settling time is censored at its duration T (and ``settled`` is False).
  The maximum error after settling is max |e| over t >= ``settle_time_s``.
- The criterion the controller declares (:func:`usv_mj.record.criteria.criterion_of_record`, its
  ``evaluate``): ``passed`` True / False / None (not judged).
- Harbour: ``min_clearance_m`` and ``contacts`` from the obstacle log (``metadata["obstacles"]``,
  :class:`usv_mj.obstacles.sink.ObstacleLog`); None / 0 in open water.
- Goal (a task with a goal, e.g. a transit's last waypoint): ``goal_reached`` when the hull origin
  comes within ``goal_radius_m`` of it; ``time_to_goal_s`` the first such t_k (None when not reached).
- Encounters (a task of several vessels, the Imazu situations: :func:`encounter_metrics`, on the
  :class:`usv_mj.record.fleet.FleetRecord` and the own ship's run alone on its route, the
  "no-traffic run"): ``collision``, ``min_range_m``, ``domain_kept``, the COLREGs scores
  ``S_safety``, ``S13`` .. ``S17`` (the smallest over the targets), ``path_deviation_m``,
  ``time_loss_s``, and the own ship's inputs as above (its effort in its own channels).

Intervals over episodes: :func:`bootstrap_ci` (percentile bootstrap of the mean, a fixed seed) for
continuous metrics, :func:`wilson_ci` for rates (:data:`RATES`), and for a time to an event
(:data:`EVENTS`: settling, time to the goal) no mean at all: the fraction of episodes that reached
it, the median and the distribution-free interval of the median, the episodes that did not reach
it censored at their end (:func:`usv_mj.jobs.bench.stats.censored_median`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from usv_mj.core.errors import ScenarioError

Z95 = 1.959963984540054
"""The standard normal's 0.975 quantile."""


@dataclass(frozen=True)
class MetricSpec:
    """One metric of the leaderboard: its column, words, unit and which way is better."""

    column: str
    label: str
    unit: str
    better: str   # "lower" | "higher"
    rate: bool = False   # a 0/1 outcome: Wilson interval, shown as a share
    reached: str = ""    # a time to an event: the column that says whether it happened (else censored)


METRICS = (
    MetricSpec("iae_cross_track", "IAE cross-track", "m s", "lower"),
    MetricSpec("ise_cross_track", "ISE cross-track", "m^2 s", "lower"),
    MetricSpec("iae_heading", "IAE heading", "rad s", "lower"),
    MetricSpec("ise_heading", "ISE heading", "rad^2 s", "lower"),
    MetricSpec("max_cross_track_after_settle", "max abs e_ct after settle", "m", "lower"),
    MetricSpec("max_heading_after_settle", "max abs e_psi after settle", "rad", "lower"),
    MetricSpec("settling_time_cross_track", "settling e_ct", "s", "lower", reached="settled_cross_track"),
    MetricSpec("settling_time_heading", "settling e_psi", "s", "lower", reached="settled_heading"),
    MetricSpec("effort_u", "effort surge", "N s", "lower"),
    MetricSpec("effort_r", "effort yaw", "N m s", "lower"),
    MetricSpec("energy", "energy", "J", "lower"),
    MetricSpec("switches_per_s_u", "switches/s surge", "1/s", "lower"),
    MetricSpec("switches_per_s_r", "switches/s yaw", "1/s", "lower"),
    MetricSpec("total_variation_u", "TV surge", "N", "lower"),
    MetricSpec("total_variation_r", "TV yaw", "N m", "lower"),
    MetricSpec("saturation_fraction", "saturated", "", "lower"),
    MetricSpec("passed", "criterion passed", "", "higher", rate=True),
    MetricSpec("min_clearance_m", "min clearance", "m", "higher"),
    MetricSpec("contact", "contact", "", "lower", rate=True),
    MetricSpec("goal_reached", "goal reached", "", "higher", rate=True),
    MetricSpec("time_to_goal_s", "time to goal", "s", "lower", reached="goal_reached"),
)
ENCOUNTER_METRICS = (
    MetricSpec("collision", "collision", "", "lower", rate=True),
    MetricSpec("min_range_m", "min range", "m", "higher"),
    MetricSpec("domain_kept", "safety domain kept", "", "higher", rate=True),
    MetricSpec("S_safety", "S_safety", "", "higher"),
    MetricSpec("S13", "S13 overtaking", "", "higher"),
    MetricSpec("S14", "S14 head-on", "", "higher"),
    MetricSpec("S15", "S15 crossing", "", "higher"),
    MetricSpec("S16", "S16 give-way", "", "higher"),
    MetricSpec("S17", "S17 stand-on", "", "higher"),
    MetricSpec("path_deviation_m", "path deviation", "m", "lower"),
    MetricSpec("time_loss_s", "time loss", "s", "lower"),
)
"""The metrics of an encounter task (:func:`encounter_metrics`): the same formulas for every
controller, the controller's own criterion not among them."""
METRICS = METRICS + ENCOUNTER_METRICS
BY_COLUMN = {m.column: m for m in METRICS}
RATES = tuple(m.column for m in METRICS if m.rate)
EVENTS = tuple(m.column for m in METRICS if m.reached)
"""The times to an event: censored where the event did not happen (usv_mj.jobs.bench.stats)."""


def worst_value(column: str):
    """The value an episode that is not ok (diverged or failed) counts with in the leaderboard:
    the worst the metric can take (+inf when lower is better, -inf when higher; a rate's bad
    outcome: ``passed`` and ``goal_reached`` False, ``contact`` True). Its own metrics are not used:
    they integrate only up to the divergence, so they would reward it (docs/metrics.md)."""
    spec = BY_COLUMN[column]
    if spec.rate:
        return spec.better == "lower"
    return math.inf if spec.better == "lower" else -math.inf


def _finite(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def errors(record) -> dict:
    """``cross_track`` [m] (the path frame of the reference velocity, PathTolerance's) and
    ``heading`` = wrap(psi - psi_d) [rad] at every row."""
    from usv_mj.record.criteria import PathTolerance
    from usv_mj.record.summary import pose_errors

    return {"cross_track": PathTolerance().errors(record)["cross"], "heading": pose_errors(record)["psi"]}


def integral_abs(t: np.ndarray, e: np.ndarray) -> float:
    """IAE = int |e| dt (trapezoid rule)."""
    return float(np.trapezoid(np.abs(e), t)) if len(t) > 1 else 0.0


def integral_sq(t: np.ndarray, e: np.ndarray) -> float:
    """ISE = int e^2 dt (trapezoid rule)."""
    return float(np.trapezoid(e * e, t)) if len(t) > 1 else 0.0


def settling_time(t: np.ndarray, e: np.ndarray, band: float) -> tuple[float, bool]:
    """(the first t_k after which |e| <= band at every later row, settled); an error that ends
    outside the band (or is not finite there): (T = t_last - t_0, False), censored at the duration."""
    outside = ~(np.abs(e) <= band)
    if not outside.any():
        return 0.0, True
    last = int(np.flatnonzero(outside)[-1])
    if last == len(t) - 1:
        return float(t[-1] - t[0]), False
    return float(t[last + 1] - t[0]), True


def max_after(t: np.ndarray, e: np.ndarray, t0: float) -> float | None:
    """max |e| over t >= t0 (None: no row there or not finite)."""
    after = t >= t0
    return _finite(np.max(np.abs(e[after]))) if after.any() else None


def input_metrics(record) -> dict:
    """Effort, energy, switches per second, total variation and the saturation fraction (module
    docstring) over the applied rows k = 0..n-2."""
    t = np.asarray(record["t"])
    n = len(t)
    out = {k: None for k in ("effort_u", "effort_r", "energy", "switches_per_s_u", "switches_per_s_r",
                             "total_variation_u", "total_variation_r", "saturation_fraction")}
    if n < 2:
        return out
    dt = np.diff(t)
    fu, fr = record["f_u"][:-1], record["f_r"][:-1]
    u, r = record["u"][:-1], record["r"][:-1]
    duration = float(t[-1] - t[0])
    out["effort_u"] = _finite(np.sum(np.abs(fu) * dt))
    out["effort_r"] = _finite(np.sum(np.abs(fr) * dt))
    out["energy"] = _finite(np.sum(np.abs(fu * u + fr * r) * dt))
    for ch, f in (("u", fu), ("r", fr)):
        k = record[f"k_{ch}"][:-1]
        out[f"switches_per_s_{ch}"] = _finite(np.count_nonzero(np.diff(k)) / duration) if np.isfinite(k).all() else None
        out[f"total_variation_{ch}"] = _finite(np.sum(np.abs(np.diff(f))))
    sat = (record["sat_u"][:-1] > 0.5) | (record["sat_r"][:-1] > 0.5)
    out["saturation_fraction"] = float(np.mean(sat))
    return out


def goal_metrics(record, goal, radius_m: float) -> dict:
    """``goal_reached`` (the hull origin within ``radius_m`` [m] of ``goal`` (x, y) [m] at some row)
    and ``time_to_goal_s`` (the first such t_k - t_0; None when not reached); both None without a goal."""
    if goal is None:
        return {"goal_reached": None, "time_to_goal_s": None}
    t = np.asarray(record["t"])
    d = np.hypot(record["x"] - goal[0], record["y"] - goal[1])
    inside = d <= radius_m
    if not inside.any():
        return {"goal_reached": False, "time_to_goal_s": None}
    return {"goal_reached": True, "time_to_goal_s": float(t[int(np.argmax(inside))] - t[0])}


# --- encounters: the own ship among other vessels (the Imazu tasks) ----------------------------------

#: the scores of usv_mj.record.colregs_scores an encounter episode reports (the smallest over the targets)
SCORES = ("S_safety", "S13", "S14", "S15", "S16", "S17")


def own_ranges(fleet) -> tuple[list, np.ndarray]:
    """(the other vessels' indices j, (rows, j) centre-to-centre ranges [m] from the own ship)."""
    xy = fleet.states()[:fleet.n_rows, :, :2]
    own = fleet.names.index(fleet.own)
    others = [j for j in range(len(fleet.names)) if j != own]
    return others, np.hypot(*(xy[:, others, :] - xy[:, own:own + 1, :]).transpose(2, 0, 1))


def collided(fleet) -> bool:
    """The own ship touched another hull: on MuJoCo a contact force above
    :data:`usv_mj.loop.fleet.CONTACT_EVENT_N` between their hulls at some row; on the analytic plant
    (no contact model, the hulls pass through each other) a centre range below (L_own + L_j) / 2 at
    some row, L the hull lengths."""
    from usv_mj.loop.fleet import CONTACT_EVENT_N
    from usv_mj.record.encounters import hulls_overlap

    own = fleet.names.index(fleet.own)
    if fleet.metadata.get("plant") == "mujoco":
        pairs = [p for p, (i, j) in enumerate(fleet.pairs) if own in (i, j)]
        return bool((fleet.contact_rows()[:, pairs] > CONTACT_EVENT_N).any())
    others, ranges = own_ranges(fleet)
    return any(hulls_overlap(fleet, own, j, ranges[:, k]).any() for k, j in enumerate(others))


def encounter_metrics(fleet, alone=None, situations: dict | None = None) -> dict:
    """The metrics of an encounter episode (Imazu 1987; the scores of Woerner et al. 2019 as Hagen
    et al. 2023 write them, :mod:`usv_mj.record.colregs_scores`), from the fleet's record ``fleet``
    and ``alone``, the own ship's record of its run with no other vessel (the same scenario, route,
    controller and sea: the "no-traffic run"; None: no time loss):

    - ``collision``: :func:`collided`;
    - ``min_range_m``: the smallest centre-to-centre range from the own ship to any other vessel [m];
    - ``domain_kept``: ``min_range_m`` >= the own ship's safety domain, SAFETY_DOMAIN_L L_own
      (:data:`usv_mj.record.encounters.SAFETY_DOMAIN_L`, 3 own lengths);
    - ``S_safety``, ``S13`` .. ``S17``: :func:`usv_mj.record.colregs_scores.score_encounters` of the
      own ship against every other vessel with the scenario's ``situations`` ({vessel index:
      situation}, e.g. an Imazu case's), the smallest over the targets (None where none applies);
    - ``path_deviation_m``: max |e_ct| over the episode, the own ship's cross-track error from its
      planned route (its reference, :func:`errors`; for a straight route the distance from the line) [m];
    - ``time_loss_s``: (s_alone - s) / U at the episode's last row, s the own ship's along-track
      position on its route (the along-track error from the reference point, which both runs share)
      and U the route's speed there: the time at the planned speed the avoidance cost, against the
      same controller with no traffic (so the controller's own lag in a sea is not counted) [s];
      None when the runs did not end at the same row;
    - the own ship's inputs (:func:`input_metrics`): its effort in its own channels (the record's
      applied f_u, f_r).

    JSON-ready (None, no NaN)."""
    from usv_mj.record.colregs_scores import score_encounters
    from usv_mj.record.criteria import PathTolerance
    from usv_mj.record.encounters import SAFETY_DOMAIN_L, lengths_of

    own = fleet.own_record
    n = fleet.n_rows
    lengths = lengths_of(fleet)
    out: dict = {"collision": collided(fleet)}
    _, ranges = own_ranges(fleet)
    out["min_range_m"] = _finite(ranges.min()) if ranges.size else None
    out["domain_kept"] = None if out["min_range_m"] is None else \
        bool(out["min_range_m"] >= SAFETY_DOMAIN_L * lengths[fleet.own])
    t = np.asarray(own["t"])[:n]
    scores = score_encounters(t, fleet.states()[:n], [lengths[name] for name in fleet.names],
                              own=fleet.names.index(fleet.own), situations=situations).minimum
    out.update({k: (None if scores.get(k) is None else _finite(scores[k])) for k in SCORES})
    path = PathTolerance().errors(own)
    out["path_deviation_m"] = _finite(np.max(np.abs(path["cross"]))) if n else None
    out["time_loss_s"] = None
    if alone is not None and n and alone.n_rows == n and alone.value("t", -1) == own.value("t", -1):
        speed = math.hypot(own.value("x_d_dot", -1), own.value("y_d_dot", -1))
        if speed > 0:
            along_alone = PathTolerance().errors(alone)["along"][-1]
            out["time_loss_s"] = _finite((along_alone - path["along"][-1]) / speed)
    out.update(input_metrics(own))
    return out


@dataclass(frozen=True)
class MetricOptions:
    """A task's options of :func:`episode_metrics` (a suite's task keys of the same names)."""

    settle_time_s: float = 20.0                     # s: the maximum errors are taken over t >= this
    band_cross_track_m: float = 1.0                 # m: the settling band of the cross-track error
    band_heading_rad: float = math.radians(10.0)    # rad: the settling band of the heading error
    goal: tuple | None = None                       # (x m, y m): the task's goal; None: no goal
    goal_radius_m: float = 2.0                      # m: the goal is reached within this distance

    def __post_init__(self):
        for name in ("settle_time_s", "band_cross_track_m", "band_heading_rad", "goal_radius_m"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ScenarioError(f"bench metrics: {name} = {v!r} must be a finite number >= 0")
        g = self.goal
        if g is not None and not (len(g) == 2 and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                      and math.isfinite(v) for v in g)):
            raise ScenarioError(f"bench metrics: goal = {g!r} must be (x, y) in m")


def episode_metrics(record, *, settle_time_s: float = 20.0, band_cross_track_m: float = 1.0,
                    band_heading_rad: float = math.radians(10.0), goal=None, goal_radius_m: float = 2.0) -> dict:
    """Every metric of :data:`METRICS` of one episode (module docstring), plus ``settled_cross_track``
    and ``settled_heading`` (False: the settling time is censored); JSON-ready (None, no NaN).
    The options: :class:`MetricOptions` (validated there)."""
    from usv_mj.record.criteria import criterion_of_record, judge

    MetricOptions(settle_time_s, band_cross_track_m, band_heading_rad, None if goal is None else tuple(goal),
                  goal_radius_m)
    t = np.asarray(record["t"])
    e = errors(record)
    out: dict = {}
    for name, err in e.items():
        out[f"iae_{name}"] = _finite(integral_abs(t, err))
        out[f"ise_{name}"] = _finite(integral_sq(t, err))
        out[f"max_{name}_after_settle"] = max_after(t, err, settle_time_s)
        band = band_cross_track_m if name == "cross_track" else band_heading_rad
        ts, settled = settling_time(t, err, band) if len(t) else (None, False)
        out[f"settling_time_{name}"], out[f"settled_{name}"] = ts, settled
    out.update(input_metrics(record))
    out["passed"] = judge(criterion_of_record(record), record)["passed"]
    obstacles = record.metadata.get("obstacles") or {}
    out["min_clearance_m"] = obstacles.get("min_clearance_m")
    out["contact"] = (int(obstacles.get("contacts") or 0) > 0) if obstacles else None
    out.update(goal_metrics(record, goal, goal_radius_m))
    return out


# --- intervals over episodes -----------------------------------------------------------------------


def wilson_ci(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson's score interval of a rate: (p + z^2/2n -+ z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n),
    p = successes / n; (nan, nan) for n = 0."""
    if n <= 0:
        return math.nan, math.nan
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_SEED = 20260


def bootstrap_ci(values, resamples: int = BOOTSTRAP_RESAMPLES, seed: int = BOOTSTRAP_SEED,
                 level: float = 0.95) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean: the (1-level)/2 and (1+level)/2 quantiles of the
    means of ``resamples`` resamples with replacement, drawn by ``np.random.default_rng(seed)``
    (the same values give the same interval on any machine); (v, v) for one value, (nan, nan) for none."""
    x = np.asarray([v for v in values if v is not None], float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return math.nan, math.nan
    if x.size == 1:
        return float(x[0]), float(x[0])
    rng = np.random.default_rng(seed)
    means = x[rng.integers(0, x.size, (resamples, x.size))].mean(axis=1)
    lo, hi = np.quantile(means, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


@dataclass(frozen=True)
class Estimate:
    """A metric over episodes: ``mean`` (for a rate: the share; for a time to an event: the median,
    inf when not reached by the median episode), its 95 % interval, ``n`` episodes; ``reached``: for
    a time to an event, how many of them reached it (None otherwise)."""

    mean: float
    lo: float
    hi: float
    n: int
    reached: int | None = None


def estimate_event(times, reached) -> Estimate:
    """A time to an event over episodes (:data:`EVENTS`): the median with its distribution-free 95 %
    interval, the episodes that did not reach it censored at their end
    (:func:`usv_mj.jobs.bench.stats.censored_median`); ``reached`` of ``n``. An episode with
    ``reached`` None (not measured: no goal) is left out."""
    from usv_mj.jobs.bench.stats import censored_median

    pairs = [(t, bool(r)) for t, r in zip(times, reached) if r is not None]
    if not pairs:
        return Estimate(math.nan, math.nan, math.nan, 0)
    m = censored_median([t if t is not None else math.inf for t, _ in pairs], [r for _, r in pairs])
    return Estimate(m["median"], m["lo"], m["hi"], m["n"], m["reached"])


def estimate(column: str, values) -> Estimate:
    """The mean of ``values`` (None: not measured, left out) and its interval: Wilson for the rates
    of :data:`RATES` (True counts), the percentile bootstrap otherwise. A value of +-inf (the worst
    value of an episode not ok, :func:`worst_value`) makes the mean and both ends of its interval
    that infinity."""
    present = [v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))]
    n = len(present)
    if n == 0:
        return Estimate(math.nan, math.nan, math.nan, 0)
    if column in RATES:
        k = sum(bool(v) for v in present)
        lo, hi = wilson_ci(k, n)
        return Estimate(k / n, lo, hi, n)
    x = np.asarray(present, float)
    if not np.isfinite(x).all():
        m = float(np.mean(x))
        return Estimate(m, m, m, n)
    lo, hi = bootstrap_ci(x)
    return Estimate(float(np.mean(x)), lo, hi, n)
