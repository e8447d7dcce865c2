"""The benchmark's metrics against closed forms on constructed records, and the intervals' widths
against their formulas (usv_mj.jobs.bench.metrics, docs/metrics.md)."""

import math

import numpy as np
import pytest

from usv_mj.jobs.bench.metrics import bootstrap_ci, episode_metrics, estimate, wilson_ci
from usv_mj.record.run_record import CORE_COLUMNS, RunRecord

DT = 0.01
T = 40.0
U = 0.5


def record(y=None, psi=None, *, f_u=0.0, f_r=0.0, u=U, r=0.0, k_u=None, sat_u=None, cross=1.0, obstacles=None):
    """A vessel following the reference x_d = U t, y_d = 0, psi_d = 0 along +x, with the given
    lateral offset y(t) and heading psi(t); the criterion: the path tolerance of ``cross`` m from 0 s."""
    t = np.arange(int(round(T / DT)) + 1) * DT
    n = len(t)
    cols = {name: np.zeros(n) for name in CORE_COLUMNS}
    cols["t"] = t
    cols["x"] = cols["x_d"] = U * t
    cols["x_d_dot"] = np.full(n, U)
    cols["u_d"] = np.full(n, U)
    cols["y"] = np.zeros(n) if y is None else y(t)
    cols["psi"] = np.zeros(n) if psi is None else psi(t)
    cols["u"] = np.full(n, u)
    cols["r"] = np.full(n, r)
    cols["f_u"] = np.broadcast_to(f_u(t) if callable(f_u) else f_u, (n,)).copy()
    cols["f_r"] = np.full(n, f_r)
    if k_u is not None:
        cols["k_u"] = k_u(t)
    if sat_u is not None:
        cols["sat_u"] = sat_u(t)
    meta = {"criterion": {"kind": "path_tolerance", "settle_time_s": 0.0, "cross_track_m": cross,
                          "along_track_m": None}}
    if obstacles is not None:
        meta["obstacles"] = obstacles
    return RunRecord.from_arrays(cols, metadata=meta, diagnostic_fields=())


def test_constant_error():
    c, h = 0.4, 0.05
    m = episode_metrics(record(lambda t: np.full_like(t, c), lambda t: np.full_like(t, h)), settle_time_s=10.0)
    assert m["iae_cross_track"] == pytest.approx(c * T, rel=1e-12)
    assert m["ise_cross_track"] == pytest.approx(c * c * T, rel=1e-12)
    assert m["iae_heading"] == pytest.approx(h * T, rel=1e-12)
    assert m["ise_heading"] == pytest.approx(h * h * T, rel=1e-12)
    assert m["max_cross_track_after_settle"] == pytest.approx(c)
    assert m["settling_time_cross_track"] == 0.0 and m["settled_cross_track"]
    assert m["passed"] is True                      # 0.4 m < 1 m throughout
    m = episode_metrics(record(lambda t: np.full_like(t, -1.5)), band_cross_track_m=1.0)
    assert m["passed"] is False
    assert m["iae_cross_track"] == pytest.approx(1.5 * T)
    assert m["settled_cross_track"] is False and m["settling_time_cross_track"] == pytest.approx(T)


def test_sinusoid():
    a, w = 0.8, 2 * math.pi / 8.0   # five whole periods in 40 s
    m = episode_metrics(record(lambda t: a * np.sin(w * t), lambda t: 0.1 * np.cos(w * t)))
    assert m["iae_cross_track"] == pytest.approx(2 * a / math.pi * T, rel=1e-4)   # mean |sin| = 2/pi
    assert m["ise_cross_track"] == pytest.approx(a * a * T / 2, rel=1e-6)        # mean sin^2 = 1/2
    assert m["iae_heading"] == pytest.approx(2 * 0.1 / math.pi * T, rel=1e-4)
    assert m["max_cross_track_after_settle"] == pytest.approx(a, rel=1e-4)
    # a sinusoid of amplitude 0.8 inside a 1 m band settles at once; in a 0.5 m band it settles after
    # its last excursion, at the phase 2 pi - asin(0.5 / 0.8) of the last period (32..40 s)
    assert m["settling_time_cross_track"] == 0.0
    m = episode_metrics(record(lambda t: a * np.sin(w * t)), band_cross_track_m=0.5)
    assert m["settled_cross_track"] is True
    assert m["settling_time_cross_track"] == pytest.approx(32.0 + (2 * math.pi - math.asin(0.5 / a)) / w, abs=DT)
    # a cosine ends at its crest, outside the band: never settled, censored at the duration
    m = episode_metrics(record(lambda t: a * np.cos(w * t)), band_cross_track_m=0.5)
    assert m["settled_cross_track"] is False and m["settling_time_cross_track"] == pytest.approx(T)


def test_step():
    # 2 m until 5 s, then 0.1 m: settles (band 1 m) at 5 s; max after a 10 s settling time is 0.1 m
    m = episode_metrics(record(lambda t: np.where(t < 5.0 - DT / 2, 2.0, 0.1)), settle_time_s=10.0)
    assert m["settling_time_cross_track"] == pytest.approx(5.0)
    assert m["settled_cross_track"] is True
    assert m["max_cross_track_after_settle"] == pytest.approx(0.1)
    # the trapezoid over the jump between 4.99 s and 5.00 s: (2 + 0.1) / 2 dt
    assert m["iae_cross_track"] == pytest.approx(2.0 * 4.99 + (2.0 + 0.1) / 2 * DT + 0.1 * (T - 5.0), rel=1e-12)


def test_inputs():
    F, Mr, rr = 30.0, 4.0, 0.02
    # surge force toggling between +F and -F every 2 s: 19 flips of 2F in 40 s
    m = episode_metrics(record(f_u=lambda t: np.where(np.floor(t / 2.0 + 1e-9) % 2 == 0, F, -F), f_r=Mr, r=rr,
                               k_u=lambda t: np.floor(t / 4.0 + 1e-9), sat_u=lambda t: (t < 10.0 - DT / 2) * 1.0))
    assert m["effort_u"] == pytest.approx(F * T, rel=1e-9)          # |f_u| = F held over every step
    assert m["effort_r"] == pytest.approx(Mr * T, rel=1e-9)
    # power f_u u + f_r r alternates F U + M r and -F U + M r: |.| averages F U
    assert m["energy"] == pytest.approx(F * U * T, rel=1e-9)
    assert m["total_variation_u"] == pytest.approx(19 * 2 * F)
    assert m["total_variation_r"] == 0.0
    assert m["switches_per_s_u"] == pytest.approx(9 / T)            # the level index changes at 4, 8, ..., 36 s
    assert m["saturation_fraction"] == pytest.approx(1000 / 4000)   # rows t < 10 s of the 4000 applied ones


def test_goal_and_clearance():
    m = episode_metrics(record(obstacles={"min_clearance_m": 1.25, "contacts": 0}), goal=(10.0, 0.0), goal_radius_m=2.0)
    assert m["goal_reached"] is True
    assert m["time_to_goal_s"] == pytest.approx(8.0 / U)            # x = U t reaches 10 - 2 m at 16 s
    assert m["min_clearance_m"] == 1.25 and m["contact"] is False
    m = episode_metrics(record(obstacles={"min_clearance_m": -0.1, "contacts": 2}), goal=(10.0, 5.0), goal_radius_m=2.0)
    assert m["goal_reached"] is False and m["time_to_goal_s"] is None and m["contact"] is True
    m = episode_metrics(record())
    assert m["goal_reached"] is None and m["contact"] is None and m["min_clearance_m"] is None


def test_wilson_against_the_published_values():
    # Wilson (1927) score interval, as tabulated by Newcombe (1998), Stat. Med. 17, 857, Table I
    assert wilson_ci(0, 10) == pytest.approx((0.0, 0.2775), abs=1e-4)
    assert wilson_ci(1, 29) == pytest.approx((0.0061, 0.1718), abs=1e-4)
    assert wilson_ci(81, 263) == pytest.approx((0.2553, 0.3662), abs=1e-4)
    e = estimate("passed", [True] * 8 + [False] * 2 + [None])
    assert (e.n, e.mean) == (10, 0.8)
    assert (e.lo, e.hi) == pytest.approx((0.4902, 0.9433), abs=1e-4)


def test_bootstrap_width_against_normal_theory():
    rng = np.random.default_rng(5)
    x = rng.normal(3.0, 2.0, 2000)
    lo, hi = bootstrap_ci(x)
    half = 1.959964 * x.std(ddof=1) / math.sqrt(len(x))
    assert hi - lo == pytest.approx(2 * half, rel=0.06)
    assert (lo + hi) / 2 == pytest.approx(x.mean(), abs=0.1 * half)
    assert bootstrap_ci(x) == (lo, hi)                               # a fixed seed
    assert bootstrap_ci([2.5]) == (2.5, 2.5)
    assert all(math.isnan(v) for v in bootstrap_ci([]))
