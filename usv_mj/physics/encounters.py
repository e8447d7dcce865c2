"""Encounter geometry of two vessels, written once (docs/encounters.md §1).

Range, true bearing, relative bearing, contact angle, course difference, TCPA and DCPA between two
vessels from usv_mj's own states, as ``numba.njit`` kernels (one pair, all ordered pairs of N
vessels, one pair over time) and the Python faces that call the same kernels.

Conventions
-----------
In: usv_mj's state ``(x, y, psi, u, v, r)`` of each vessel (README, Conventions): world x east,
y north [m]; heading psi [rad] counter-clockwise from east; body velocities u forward, v to port
[m/s] over ground (``eta_dot = J(psi) nu``: in a current nu is the velocity over ground, the water's
relative velocity is nu - nu_c, docs/sea.md §1); r is not used.

Out: metres, seconds and **compass degrees** (the field's language; keys end in ``_deg``):

- true bearing B of the target from own ship, clockwise from north, in [0, 360);
- relative bearing beta of the target from own ship's **bow**, clockwise, in (-180, 180],
  positive = starboard;
- contact angle alpha: the relative bearing of own ship seen from the target's **bow**, clockwise,
  in (-180, 180], positive = own ship on the target's starboard side;
- course difference C_T = chi_target - chi_own, clockwise, in [0, 360) (0: same course, 180:
  reciprocal courses);
- TCPA [s] (negative: the closest point of approach is past) and DCPA [m].

Heading or course over ground
-----------------------------
The COLREGs sectors are read from the **bow** (Rule 13's "abaft her beam", the lights' sectors):
beta and alpha use the headings psi. What moves the vessels apart or together is the velocity over
ground: TCPA, DCPA and the course difference use the world velocity ``v = R(psi) (u, v)``, whose
direction is the course over ground chi (:func:`course_over_ground_deg`); a vessel slower than
:data:`COURSE_MIN_SPEED` has no defined course and its heading stands for it. The two differ by the
drift angle (sway, current); in calm water on a straight run they are equal. (Sources differ here:
Woerner-style evaluators and TUD_RL read the sectors from the heading, PSBMPC's SB-MPC from the
velocity direction; research note §2.2.)

Formulas (research note §2.2; d = p_target - p_own, w = v_target - v_own):

    range  = |d|
    B      = atan2(d_x, d_y) mod 360                      (TUD_RL VesselFnc.bng_abs; NED codes atan2(dE, dN))
    beta   = wrap(B - chi_h,own),  chi_h = 90 - deg(psi)   (compass heading)
    alpha  = wrap(B + 180 - chi_h,target)                 (Woerner's alpha; DNV trafficgen; TUD_RL bng_TS)
    C_T    = (chi_target - chi_own) mod 360               (Xu et al. 2022 via TUD_RL head_inter)
    TCPA   = -(d . w) / |w|^2, 0 when |w|^2 <= W2_MIN     (Lenart 1983 via TUD_RL VesselFnc.tcpa)
    DCPA   = |d + w TCPA|                                 (Chun et al. 2021 via TUD_RL VesselFnc.cpa)

(Kuwata et al. 2011 print TCPA without the leading minus sign; the form above is the physical one:
positive while approaching.)
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

#: the columns of a pair's geometry (the last axis of :func:`pair_matrix` and :func:`pair_series`)
G_RANGE, G_BEARING, G_BETA, G_ALPHA, G_COURSE_DIFF, G_TCPA, G_DCPA = range(7)
N_GEOMETRY = 7
GEOMETRY_FIELDS = ("range_m", "true_bearing_deg", "relative_bearing_deg", "contact_angle_deg",
                   "course_difference_deg", "tcpa_s", "dcpa_m")

#: below this speed over ground [m/s] a vessel's course is its heading (no defined track)
COURSE_MIN_SPEED = 1e-3
#: |w|^2 [(m/s)^2] at or below which two vessels move together: TCPA = 0 by definition, DCPA = range
W2_MIN = 1e-12

# the state's columns (usv_mj.core.layouts.STATE_FIELDS)
_X, _Y, _PSI, _U, _V = 0, 1, 2, 3, 4


# --- angles -------------------------------------------------------------------------------------------


@njit(cache=True)
def wrap180(a):
    """An angle [deg] into (-180, 180] (180 stays 180, -180 becomes 180)."""
    w = 180.0 - ((180.0 - a) % 360.0)
    if w <= -180.0:   # (180 - a) % 360 rounded up to 360
        w += 360.0
    return w


@njit(cache=True)
def wrap360(a):
    """An angle [deg] into [0, 360)."""
    w = a % 360.0
    if w >= 360.0:    # a tiny negative a: 360 - eps rounds to 360
        w -= 360.0
    return w


@njit(cache=True)
def compass_deg(angle_enu):
    """A direction counter-clockwise from east [rad] as compass degrees clockwise from north, [0, 360)."""
    return wrap360(90.0 - math.degrees(angle_enu))


# --- one vessel ---------------------------------------------------------------------------------------


@njit(cache=True)
def world_velocity(psi, u, v):
    """The velocity over ground in the world frame [m/s]: (vx, vy) = R(psi) (u, v), v to port."""
    c, s = math.cos(psi), math.sin(psi)
    return u * c - v * s, u * s + v * c


@njit(cache=True)
def course_deg(psi, u, v):
    """Compass course over ground [deg, 0..360): the direction of :func:`world_velocity`; the
    compass heading when the speed is below :data:`COURSE_MIN_SPEED`."""
    vx, vy = world_velocity(psi, u, v)
    if vx * vx + vy * vy <= COURSE_MIN_SPEED * COURSE_MIN_SPEED:
        return compass_deg(psi)
    return wrap360(math.degrees(math.atan2(vx, vy)))


# --- two vessels --------------------------------------------------------------------------------------


@njit(cache=True)
def tcpa_dcpa(dx, dy, wx, wy):
    """(TCPA [s], DCPA [m]) of a relative position d = (dx, dy) [m] moving at the relative velocity
    w = (wx, wy) [m/s]: TCPA = -(d . w) / |w|^2 (0 when |w|^2 <= W2_MIN: the pair moves together and
    every time is the closest), DCPA = |d + w TCPA|."""
    w2 = wx * wx + wy * wy
    t = 0.0
    if w2 > W2_MIN:
        t = -(dx * wx + dy * wy) / w2
    return t, math.hypot(dx + wx * t, dy + wy * t)


@njit(cache=True)
def vessel_terms(state):
    """What a pair's geometry needs of one vessel, once per step: (compass heading [deg], compass
    course over ground [deg], vx, vy [m/s])."""
    psi, u, v = state[_PSI], state[_U], state[_V]
    vx, vy = world_velocity(psi, u, v)
    return compass_deg(psi), course_deg(psi, u, v), vx, vy


@njit(cache=True)
def pair_terms(dx, dy, heading_own, heading_target, course_own, course_target, wx, wy):
    """The 7-tuple of :func:`pair_geometry` from the relative position d = (dx, dy) [m], the two
    vessels' compass headings and courses [deg] (:func:`vessel_terms`) and the relative velocity
    w = v_target - v_own [m/s]."""
    bearing = wrap360(math.degrees(math.atan2(dx, dy)))
    beta = wrap180(bearing - heading_own)
    alpha = wrap180(bearing + 180.0 - heading_target)
    t, d = tcpa_dcpa(dx, dy, wx, wy)
    return math.hypot(dx, dy), bearing, beta, alpha, wrap360(course_target - course_own), t, d


@njit(cache=True)
def pair_geometry(own, target):
    """The geometry of ``target`` seen from ``own`` (each a state (x, y, psi, u, v, r)), a 7-tuple in
    the order of :data:`GEOMETRY_FIELDS`: range [m], true bearing [deg], relative bearing beta [deg],
    contact angle alpha [deg], course difference [deg], TCPA [s], DCPA [m] (module docstring)."""
    ho, co, vxo, vyo = vessel_terms(own)
    ht, ct, vxt, vyt = vessel_terms(target)
    return pair_terms(target[_X] - own[_X], target[_Y] - own[_Y], ho, ht, co, ct, vxt - vxo, vyt - vyo)


@njit(cache=True)
def vessels_terms_into(states, out):
    """:func:`vessel_terms` of every vessel (states (N, 6)) into ``out`` (N, 4)."""
    for i in range(states.shape[0]):
        h, c, vx, vy = vessel_terms(states[i])
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = h, c, vx, vy


@njit(cache=True)
def ordered_pair(states, terms, i, j):
    """:func:`pair_geometry` of vessel j seen from vessel i, from the step's :func:`vessels_terms_into`."""
    return pair_terms(states[j, _X] - states[i, _X], states[j, _Y] - states[i, _Y], terms[i, 0], terms[j, 0],
                      terms[i, 1], terms[j, 1], terms[j, 2] - terms[i, 2], terms[j, 3] - terms[i, 3])


@njit(cache=True)
def write_pair(out, i, j, g):
    """``out[i, j, :]`` = the 7-tuple ``g`` (element by element: a slice per pair costs more than
    the geometry)."""
    out[i, j, G_RANGE], out[i, j, G_BEARING], out[i, j, G_BETA], out[i, j, G_ALPHA] = g[0], g[1], g[2], g[3]
    out[i, j, G_COURSE_DIFF], out[i, j, G_TCPA], out[i, j, G_DCPA] = g[4], g[5], g[6]


@njit(cache=True)
def pair_matrix_into(states, out):
    """Every ordered pair of N vessels: ``out[i, j]`` (an (N, N, N_GEOMETRY) array) is vessel j seen
    from vessel i; the diagonal is NaN. ``states`` is (N, 6)."""
    n = states.shape[0]
    terms = np.empty((n, 4))
    vessels_terms_into(states, terms)
    for i in range(n):
        for k in range(N_GEOMETRY):
            out[i, i, k] = np.nan
        for j in range(n):
            if j != i:
                write_pair(out, i, j, ordered_pair(states, terms, i, j))


@njit(cache=True)
def pair_series_into(own, target, out):
    """One pair over time: ``out[k]`` (a (T, N_GEOMETRY) array) is ``target[k]`` seen from ``own[k]``
    (both (T, 6))."""
    for k in range(own.shape[0]):
        g = pair_geometry(own[k], target[k])
        out[k, G_RANGE], out[k, G_BEARING], out[k, G_BETA], out[k, G_ALPHA] = g[0], g[1], g[2], g[3]
        out[k, G_COURSE_DIFF], out[k, G_TCPA], out[k, G_DCPA] = g[4], g[5], g[6]


# --- Python faces (the same kernels) ----------------------------------------------------------------


class PairGeometry(NamedTuple):
    """The geometry of a target seen from own ship (module docstring for each quantity)."""

    range_m: float
    true_bearing_deg: float
    relative_bearing_deg: float
    contact_angle_deg: float
    course_difference_deg: float
    tcpa_s: float
    dcpa_m: float


def _state(x) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 1 or a.shape[0] < 5:
        raise ValueError(f"a vessel's state is (x, y, psi, u, v[, r]), got shape {a.shape}")
    return a


def encounter(own, target) -> PairGeometry:
    """Every quantity of :data:`GEOMETRY_FIELDS` of ``target`` seen from ``own`` (states
    (x, y, psi, u, v[, r]) in usv_mj's frame)."""
    return PairGeometry(*(float(v) for v in pair_geometry(_state(own), _state(target))))


def range_m(own, target) -> float:
    """Distance between the two vessels' reference points [m]."""
    return encounter(own, target).range_m


def true_bearing_deg(own, target) -> float:
    """True bearing of ``target`` from ``own``, compass degrees clockwise from north, [0, 360)."""
    return encounter(own, target).true_bearing_deg


def relative_bearing_deg(own, target) -> float:
    """beta: bearing of ``target`` from ``own``'s bow, clockwise, (-180, 180], + = starboard."""
    return encounter(own, target).relative_bearing_deg


def contact_angle_deg(own, target) -> float:
    """alpha: bearing of ``own`` from ``target``'s bow, clockwise, (-180, 180], + = own ship on the
    target's starboard side."""
    return encounter(own, target).contact_angle_deg


def course_difference_deg(own, target) -> float:
    """C_T = course of ``target`` - course of ``own`` (over ground), clockwise, [0, 360)."""
    return encounter(own, target).course_difference_deg


def cpa(own, target) -> tuple[float, float]:
    """(TCPA [s], DCPA [m]) for both vessels keeping their present velocity over ground."""
    g = encounter(own, target)
    return g.tcpa_s, g.dcpa_m


def velocity_over_ground(state) -> tuple[float, float]:
    """(vx, vy) [m/s]: the vessel's velocity over ground in the world frame."""
    s = _state(state)
    return tuple(float(v) for v in world_velocity(s[_PSI], s[_U], s[_V]))


def speed_over_ground(state) -> float:
    """|v| [m/s], the speed over ground."""
    return float(math.hypot(*velocity_over_ground(state)))


def course_over_ground_deg(state) -> float:
    """Compass course over ground [deg, 0..360) (the heading below :data:`COURSE_MIN_SPEED`)."""
    s = _state(state)
    return float(course_deg(s[_PSI], s[_U], s[_V]))


def heading_deg(state) -> float:
    """Compass heading [deg, 0..360): the bow's direction."""
    return float(compass_deg(float(_state(state)[_PSI])))


def pair_matrix(states) -> np.ndarray:
    """(N, N, N_GEOMETRY): ``[i, j]`` is vessel j seen from vessel i (columns ``G_*``); ``states``
    (N, 6). The diagonal is NaN."""
    s = np.ascontiguousarray(states, dtype=np.float64)
    if s.ndim != 2 or s.shape[1] < 5:
        raise ValueError(f"states must be (N, 6), got shape {s.shape}")
    out = np.empty((s.shape[0], s.shape[0], N_GEOMETRY))
    pair_matrix_into(s, out)
    return out


def pair_series(own, target) -> np.ndarray:
    """(T, N_GEOMETRY): ``target[k]`` seen from ``own[k]`` (both (T, 6), e.g. a record's state columns)."""
    o = np.ascontiguousarray(own, dtype=np.float64)
    t = np.ascontiguousarray(target, dtype=np.float64)
    if o.ndim != 2 or o.shape != t.shape or o.shape[1] < 5:
        raise ValueError(f"own and target must be (T, 6) alike, got {o.shape} and {t.shape}")
    out = np.empty((o.shape[0], N_GEOMETRY))
    pair_series_into(o, t, out)
    return out


@njit(cache=True)
def courses_into(states, out):
    """``out[k]`` = :func:`course_deg` of ``states[k]`` (one vessel over time, (T, 6))."""
    for k in range(states.shape[0]):
        out[k] = course_deg(states[k, _PSI], states[k, _U], states[k, _V])


def courses_deg(states) -> np.ndarray:
    """(T,) compass courses over ground [deg] of one vessel's states (T, 6)."""
    s = np.ascontiguousarray(states, dtype=np.float64)
    out = np.empty(s.shape[0])
    courses_into(s, out)
    return out


def speeds(states) -> np.ndarray:
    """(T,) speeds over ground [m/s] of one vessel's states (T, 6) (|R(psi)(u, v)| = hypot(u, v))."""
    s = np.asarray(states, dtype=np.float64)
    return np.hypot(s[:, _U], s[:, _V])
