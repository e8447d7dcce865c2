"""Encounter classification by COLREGs rules 13-17, and its lock over time (docs/encounters.md §2).

Two classifiers of one vessel pair, seen from own ship, both on the geometry of
:mod:`usv_mj.physics.encounters` (clockwise compass degrees, + = starboard):

- :func:`classify` (the one the rest of usv_mj uses): the Woerner-style entry criteria on the
  relative bearing beta and the contact angle alpha, as implemented by AutoVerification (Hagen /
  Minne, after Woerner et al. 2019, Auton. Robots 43(4):967-991, doi 10.1007/s10514-018-9765-y)
  and parametrised as the NTNU colav-sim evaluator (Hagen et al. 2023, Ocean Eng. 288:115991):
  a13 = 45 deg, a14 = 13 deg, a15 = 0, the stern-light sector |bearing| > 112.5 deg (research
  note §2.3 a). Checked in this order, the first match wins:

  ==========================  ===========================================================================
  own ship overtaken (R13)    |beta| > 112.5 and |alpha| < a13 and U_own < U_target   (stand-on, R17)
  own ship overtaking (R13)   |alpha| > 112.5 and |beta| < a13 and U_own > U_target   (give-way, R16)
  head-on (R14)               |beta| < a14 and |alpha| < a14                          (both give way)
  crossing, target starboard  -a15 < beta < 112.5 and -112.5 < alpha <= 0             (give-way, R15/16)
  crossing, target port       -112.5 < beta <= 0 and -a15 < alpha < 112.5             (stand-on, R15/17)
  otherwise                   no rule applies
  ==========================  ===========================================================================

  The list is symmetric: the situation of the pair seen from the target is the mirror
  (:func:`mirror`: give-way <-> stand-on, overtaking <-> overtaken, head-on <-> head-on), because
  swapping the vessels swaps beta and alpha. (With a15 > 0 the two crossing rows overlap near
  beta = alpha = 0 and the first wins, both vessels giving way; with a15 < 0, NTNU's -10 deg, a gap
  opens where no rule applies.) Speeds are over ground.

- :func:`tam_bucknall`: the relative-bearing x course-difference table of Tam & Bucknall (2010,
  J. Mar. Sci. Technol. 15:257-270), as implemented in NTNU ORCAS ``tam_bucknall_colregs.m``
  (research note §2.3 b), for comparison and tests. It ignores speeds, and its head-on region is
  much wider (course difference 180 +- 22.5 with the target anywhere forward of the beam).

**The lock** (:func:`update_situation`, :func:`colregs_step_into`): a pair's situation is decided
once, at entry, and held until both vessels are past and clear (AutoVerification's
``determine_situations``; the marinehdk colav-sim fork's ``colreg_fsm``): entry when the range is at
most the stage-2 range and TCPA > 0 (and DCPA within an optional gate); release when both are
passed (each sees the other more than 112.5 deg off its bow: |beta| > 112.5 and |alpha| > 112.5)
or the range exceeds 1.05 x the stage-2 range. Overtaking is released the same way, so it holds
"until finally past and clear" (Rule 13 d): the overtaken vessel sees the overtaker ahead until
the range opens.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numba import njit

from usv_mj.physics.encounters import (G_ALPHA, G_BETA, G_DCPA, G_RANGE, G_TCPA, N_GEOMETRY, ordered_pair,
                                       pair_geometry, vessels_terms_into, wrap360, write_pair)

# --- situations and roles -------------------------------------------------------------------------------
#: the situation of a pair as seen from own ship (int codes, stored in arrays)
NONE, HEAD_ON, CROSSING_GIVE_WAY, CROSSING_STAND_ON, OVERTAKING, OVERTAKEN = 0, 1, 2, 3, 4, 5
SITUATION_NAMES = ("none", "head_on", "crossing_give_way", "crossing_stand_on", "overtaking", "overtaken")
#: own ship's role in each situation
ROLE_NONE, GIVE_WAY, STAND_ON = 0, 1, 2
ROLE_NAMES = ("none", "give_way", "stand_on")
ROLE_OF = (ROLE_NONE, GIVE_WAY, GIVE_WAY, STAND_ON, GIVE_WAY, STAND_ON)
#: the COLREGs rules that apply to own ship in each situation
RULES_OF = ((), (14, 8), (15, 16, 8), (15, 17), (13, 16, 8), (13, 17))


@njit(cache=True)
def mirror(code):
    """The situation of the same pair seen from the other vessel."""
    if code == CROSSING_GIVE_WAY:
        return CROSSING_STAND_ON
    if code == CROSSING_STAND_ON:
        return CROSSING_GIVE_WAY
    if code == OVERTAKING:
        return OVERTAKEN
    if code == OVERTAKEN:
        return OVERTAKING
    return code


def situation_name(code: int) -> str:
    return SITUATION_NAMES[int(code)]


def role_of(code: int) -> str:
    """"give_way", "stand_on" or "none": own ship's role in situation ``code`` (head-on: give way)."""
    return ROLE_NAMES[ROLE_OF[int(code)]]


# --- parameters -----------------------------------------------------------------------------------------
# the packed layout of ColregsParams.as_array() (the kernels' argument)
C_A13, C_A14, C_A15, C_STERN, C_STAGE2, C_STAGE3, C_STAGE4, C_RELEASE, C_DCPA_GATE = range(9)
N_COLREGS_PARAMS = 9


@dataclass(frozen=True)
class ColregsParams:
    """The sector boundaries and ranges of the classification and its lock (research note §2.3 a, §7).

    Ranges are multiples of a reference length [m] that the caller gives (the kernels' ``length``):
    for a pair, the larger of the two vessels' lengths, so that both vessels lock and release
    together (and the earlier of the two stage ranges applies).

    Attributes
    ----------
    a13_deg:
        Overtaking [deg]: the overtaken vessel lies within a13 of the overtaker's bow (|beta| < a13
        from the overtaker, |alpha| < a13 from the overtaken). 45 (AutoVerification
        ``alpha_critical_13``, NTNU colav-sim ``theta_critical_ot``; DNV trafficgen uses 67.5).
    a14_deg:
        Head-on half-width [deg]: |beta| < a14 and |alpha| < a14, so the headings are within 2 a14 of
        reciprocal. 13 (NTNU colav-sim ``theta_critical_ho``, the OE-2023 evaluator). It must stay below
        22.5 to keep Imazu's case 18/19 target at beta = 22.5, alpha = -22.5 a crossing
        (docs/encounters.md §2.2 has the alternatives: 5, 15, 22.5, 30).
    a15_deg:
        Crossing tolerance [deg]: the give-way crossing starts at beta > -a15 (and the stand-on one at
        alpha > -a15). 0 (AutoVerification ``alpha_critical_15``; NTNU -10, DNV 5).
    stern_deg:
        The stern-light sector's edge [deg]: 22.5 deg abaft the beam (Rule 13 b, Rule 21 d), so
        |bearing| > 112.5 is "coming up from astern" and, for the release, "passed".
    stage2_L, stage3_L, stage4_L:
        The COLREGs stage ranges [reference lengths]: 25, 7.5 and 4 (research note §7 item 4: stage 2
        = 0.5 R with the Imazu scale R = 50 L, stage 3 = 0.15 R, stage 4 "usually four ship lengths",
        AutoVerification ``r_colregs_4_max``). Entry locks at stage 2; the scores read stages 2-4.
    release_factor:
        A locked pair beyond release_factor x the stage-2 range is released [-]: 1.05 (the marinehdk
        colav-sim fork's ``exit_range_factor``): a hysteresis band, no flicker at the stage-2 edge.
    dcpa_gate_L:
        Entry also needs DCPA <= dcpa_gate_L x the reference length [reference lengths]: infinite by
        default (off: every approaching pair inside stage 2 is classified, as AutoVerification).
    """

    a13_deg: float = 45.0
    a14_deg: float = 13.0
    a15_deg: float = 0.0
    stern_deg: float = 112.5
    stage2_L: float = 25.0
    stage3_L: float = 7.5
    stage4_L: float = 4.0
    release_factor: float = 1.05
    dcpa_gate_L: float = math.inf

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or math.isnan(value):
                raise ValueError(f"ColregsParams.{f.name} must be a number, got {value!r}")
        if not 0.0 < self.a14_deg < 90.0 or not 0.0 < self.a13_deg < 90.0:
            raise ValueError(f"ColregsParams: a13_deg and a14_deg must be in (0, 90), got {self.a13_deg}, {self.a14_deg}")
        if not 90.0 <= self.stern_deg < 180.0:
            raise ValueError(f"ColregsParams.stern_deg must be in [90, 180), got {self.stern_deg}")
        if not self.stage2_L > self.stage3_L > self.stage4_L > 0.0:
            raise ValueError("ColregsParams: the stage ranges must satisfy stage2_L > stage3_L > stage4_L > 0, "
                             f"got {self.stage2_L}, {self.stage3_L}, {self.stage4_L}")
        if self.release_factor < 1.0:
            raise ValueError(f"ColregsParams.release_factor must be >= 1, got {self.release_factor}")
        if not self.dcpa_gate_L > 0.0:
            raise ValueError(f"ColregsParams.dcpa_gate_L must be > 0, got {self.dcpa_gate_L}")

    def as_array(self) -> np.ndarray:
        """The packed float64 vector of the kernels (indices ``C_*``)."""
        return np.array([self.a13_deg, self.a14_deg, self.a15_deg, self.stern_deg, self.stage2_L,
                         self.stage3_L, self.stage4_L, self.release_factor, self.dcpa_gate_L], dtype=np.float64)

    def stage_ranges_m(self, length_m: float) -> tuple[float, float, float]:
        """(stage 2, stage 3, stage 4) ranges [m] for the reference length ``length_m``."""
        return self.stage2_L * length_m, self.stage3_L * length_m, self.stage4_L * length_m


# --- the classifiers ------------------------------------------------------------------------------------


@njit(cache=True)
def classify(beta, alpha, speed_own, speed_target, cp):
    """The Woerner-style situation (module docstring) of a target at relative bearing ``beta`` with
    contact angle ``alpha`` [deg, (-180, 180], clockwise], speeds over ground [m/s], ``cp`` =
    :meth:`ColregsParams.as_array`. No range or TCPA gate (that is :func:`update_situation`'s)."""
    stern = cp[C_STERN]
    if abs(beta) > stern and abs(alpha) < cp[C_A13] and speed_own < speed_target:
        return OVERTAKEN
    if abs(alpha) > stern and abs(beta) < cp[C_A13] and speed_own > speed_target:
        return OVERTAKING
    if abs(beta) < cp[C_A14] and abs(alpha) < cp[C_A14]:
        return HEAD_ON
    if -cp[C_A15] < beta < stern and -stern < alpha <= 0.0:
        return CROSSING_GIVE_WAY
    if -stern < beta <= 0.0 and -cp[C_A15] < alpha < stern:
        return CROSSING_STAND_ON
    return NONE


#: Tam & Bucknall's table: rows = bearing region 1..6, columns = course-difference region 1..6
_TB = np.array([
    [OVERTAKING, CROSSING_STAND_ON, CROSSING_STAND_ON, HEAD_ON, CROSSING_GIVE_WAY, CROSSING_GIVE_WAY],
    [OVERTAKING, NONE, NONE, HEAD_ON, CROSSING_GIVE_WAY, CROSSING_GIVE_WAY],
    [OVERTAKEN, NONE, NONE, NONE, CROSSING_GIVE_WAY, CROSSING_GIVE_WAY],
    [OVERTAKEN, CROSSING_STAND_ON, NONE, NONE, NONE, CROSSING_GIVE_WAY],
    [OVERTAKEN, CROSSING_STAND_ON, CROSSING_STAND_ON, NONE, NONE, NONE],
    [OVERTAKING, CROSSING_STAND_ON, CROSSING_STAND_ON, HEAD_ON, NONE, NONE],
], dtype=np.int64)


@njit(cache=True)
def _tb_bearing_region(b):
    if b >= 337.5 or b < 22.5:
        return 0
    if b < 90.0:
        return 1
    if b < 112.5:
        return 2
    if b < 247.5:
        return 3
    if b < 270.0:
        return 4
    return 5


@njit(cache=True)
def _tb_course_region(h):
    if h >= 292.5 or h < 67.5:
        return 0
    if h < 90.0:
        return 1
    if h < 157.5:
        return 2
    if h < 202.5:
        return 3
    if h < 270.0:
        return 4
    return 5


@njit(cache=True)
def tam_bucknall(beta, course_difference):
    """Tam & Bucknall's situation (module docstring) from the relative bearing [deg] and the course
    difference chi_target - chi_own [deg], both clockwise (any range; read in [0, 360)).

    Bearing regions: [337.5, 22.5), [22.5, 90), [90, 112.5), [112.5, 247.5), [247.5, 270),
    [270, 337.5); course-difference regions: [292.5, 67.5), [67.5, 90), [90, 157.5),
    [157.5, 202.5), [202.5, 270), [270, 292.5)."""
    return _TB[_tb_bearing_region(wrap360(beta)), _tb_course_region(wrap360(course_difference))]


# --- the lock ---------------------------------------------------------------------------------------------


@njit(cache=True)
def update_situation(situation, rng, beta, alpha, tcpa, dcpa, speed_own, speed_target, length, cp):
    """One step of a pair's locked situation (module docstring), seen from own ship: the new code.

    A locked pair (``situation`` != NONE) is released to NONE when both are passed (|beta| and |alpha|
    beyond the stern edge) or the range exceeds release_factor x stage 2; otherwise it keeps its
    code. A free pair locks :func:`classify`'s code when rng <= stage 2, TCPA > 0 and DCPA within the
    gate. ``length`` [m] is the reference length of the ranges (ColregsParams)."""
    stage2 = cp[C_STAGE2] * length
    if situation != NONE:
        if (abs(beta) > cp[C_STERN] and abs(alpha) > cp[C_STERN]) or rng > cp[C_RELEASE] * stage2:
            return NONE
        return situation
    if rng <= stage2 and tcpa > 0.0 and dcpa <= cp[C_DCPA_GATE] * length:
        return classify(beta, alpha, speed_own, speed_target, cp)
    return NONE


@njit(cache=True)
def colregs_step_into(states, lengths, cp, situation, geometry):
    """One step of every pair of N vessels: ``geometry`` (N, N, N_GEOMETRY) gets every ordered pair's
    geometry (:func:`usv_mj.physics.encounters.pair_geometry`, diagonal NaN) and ``situation`` (N, N)
    integer codes, ``[i, j]`` = the situation of j seen from i, is advanced by
    :func:`update_situation` for each pair i < j with the reference length max(L_i, L_j) and
    mirrored into ``[j, i]``. ``states`` (N, 6), ``lengths`` (N,) [m]."""
    n = states.shape[0]
    terms = np.empty((n, 4))
    vessels_terms_into(states, terms)
    for i in range(n):
        for k in range(N_GEOMETRY):
            geometry[i, i, k] = np.nan
        situation[i, i] = NONE
    for i in range(n):
        speed_i = math.hypot(terms[i, 2], terms[i, 3])
        for j in range(i + 1, n):
            g = ordered_pair(states, terms, i, j)
            h = ordered_pair(states, terms, j, i)
            write_pair(geometry, i, j, g)
            write_pair(geometry, j, i, h)
            speed_j = math.hypot(terms[j, 2], terms[j, 3])
            code = update_situation(situation[i, j], g[G_RANGE], g[G_BETA], g[G_ALPHA], g[G_TCPA], g[G_DCPA],
                                    speed_i, speed_j, max(lengths[i], lengths[j]), cp)
            situation[i, j] = code
            situation[j, i] = mirror(code)


@njit(cache=True)
def situation_series_into(states, lengths, cp, out):
    """The lock over a whole run: ``out[k]`` (T, N, N) is the situation matrix after step k of
    ``states`` (T, N, 6), starting free."""
    t, n = states.shape[0], states.shape[1]
    sit = np.zeros((n, n), dtype=np.int64)
    geo = np.empty((n, n, N_GEOMETRY))
    for k in range(t):
        colregs_step_into(states[k], lengths, cp, sit, geo)
        out[k] = sit


# --- Python faces -----------------------------------------------------------------------------------------


def classify_pair(own, target, params: ColregsParams | None = None) -> int:
    """The Woerner-style situation of ``target`` seen from ``own`` (states (x, y, psi, u, v[, r])),
    with no range or TCPA gate."""
    o = np.asarray(own, dtype=np.float64)
    t = np.asarray(target, dtype=np.float64)
    g = pair_geometry(o, t)
    return int(classify(g[G_BETA], g[G_ALPHA], math.hypot(o[3], o[4]), math.hypot(t[3], t[4]),
                        (params or ColregsParams()).as_array()))


def classify_pair_tam_bucknall(own, target) -> int:
    """Tam & Bucknall's situation of ``target`` seen from ``own``."""
    g = pair_geometry(np.asarray(own, dtype=np.float64), np.asarray(target, dtype=np.float64))
    return int(tam_bucknall(g[G_BETA], g[4]))


class ColregsTracker:
    """The lock of every pair of N vessels, one step at a time (the multi-vessel loop's face).

    ``step(states)`` advances it with the states (N, 6) of this step and returns the situation matrix
    (N, N) (``[i, j]``: j seen from i); ``geometry`` holds the step's (N, N, N_GEOMETRY) geometry.
    """

    def __init__(self, lengths, params: ColregsParams | None = None):
        self.lengths = np.ascontiguousarray(lengths, dtype=np.float64)
        if self.lengths.ndim != 1 or not np.all(self.lengths > 0.0):
            raise ValueError(f"ColregsTracker: lengths must be positive, one per vessel, got {lengths!r}")
        self.params = params or ColregsParams()
        self.cp = self.params.as_array()
        n = self.lengths.shape[0]
        self.situation = np.zeros((n, n), dtype=np.int64)
        self.geometry = np.full((n, n, N_GEOMETRY), np.nan)

    def reset(self):
        self.situation[:] = NONE

    def step(self, states) -> np.ndarray:
        colregs_step_into(np.ascontiguousarray(states, dtype=np.float64), self.lengths, self.cp,
                          self.situation, self.geometry)
        return self.situation


def situation_series(states, lengths, params: ColregsParams | None = None) -> np.ndarray:
    """(T, N, N) situation codes over a run's states (T, N, 6) (the lock from a free start)."""
    s = np.ascontiguousarray(states, dtype=np.float64)
    if s.ndim != 3 or s.shape[2] < 5:
        raise ValueError(f"states must be (T, N, 6), got shape {s.shape}")
    lengths = np.ascontiguousarray(lengths, dtype=np.float64)
    if lengths.shape != (s.shape[1],):
        raise ValueError(f"lengths must be one per vessel ({s.shape[1]}), got shape {lengths.shape}")
    out = np.empty((s.shape[0], s.shape[1], s.shape[1]), dtype=np.int64)
    situation_series_into(s, lengths, (params or ColregsParams()).as_array(), out)
    return out
