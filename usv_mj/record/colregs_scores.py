"""How a finished encounter is judged: safety and COLREGs scores per vessel pair (docs/encounters.md §3).

The scores of Woerner et al. (2019, Auton. Robots 43(4):967-991) in the form of Hagen et al. (2023,
"Safety and COLREG evaluation for marine collision avoidance algorithms", Ocean Eng. 288:115991:
"OE-2023"), as reconstructed publicly (the marinehdk colav-simulator fork's ``evaluation/scoring.py``,
formula ids oe2023-eq2..32; research note §3), with the weights and thresholds of the NTNU colav-sim
``config/evaluator.yaml`` and the radii of research note §7 item 4 scaled to the own ship's length L
(:class:`ScoreParams`). Everything is computed from the two vessels' states over time (x, y, psi,
u, v, r), so a record's columns or an MCAP log's state topics are enough.

Per pair (own ship i, target j; angles clockwise, + = starboard, from
:mod:`usv_mj.physics.encounters`):

- the **window**: from the entry of the pair's COLREGs situation (the lock of
  :mod:`usv_mj.physics.colregs`: stage-2 range and TCPA > 0) to the end; the **CPA** is the
  window's smallest range (the actual CPA of the tracks), with alpha_cpa and beta_cpa there;
- ``S_r`` range score, ``S_theta`` pose score, ``S_safety = (1 - S_r) S_theta + S_r`` (0 when S_r = 0);
- give-way (head-on, crossing with the target on starboard, overtaking): ``S16 = S_safety
  S_apparent (1 - P_delay)``, with ``S_apparent = 1 - g_chi P_na_course - g_u P_na_speed``;
- stand-on (crossing with the target on port, overtaken): ``S17 = S_safety (1 - P_stage2)
  (1 - P_stage3) (1 - P_port_turn)``;
- ``S13`` (overtaking: S16 - 0.3 P_ahead; overtaken: S17), ``S14`` (head-on: (1 - 0.4 P_nsb -
  0.6 P_sts)(1 - P_na_course)(1 - P_delay)), ``S15`` (give-way: S16 - 0.5 P_ahead; stand-on: S17);
  every score clipped to [0, 1]; a score that does not apply to the situation is None.

Course and speed are over ground (the track: :func:`usv_mj.physics.encounters.course_deg`), the
bearings at CPA from the bows. The stage ranges and the lock are :class:`usv_mj.physics.colregs.ColregsParams`'s
(the larger of the two lengths); the radii are the own ship's.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

import numpy as np

from usv_mj.physics.colregs import (CROSSING_GIVE_WAY, CROSSING_STAND_ON, GIVE_WAY, HEAD_ON, NONE, OVERTAKEN,
                                    OVERTAKING, ROLE_OF, SITUATION_NAMES, STAND_ON, ColregsParams, role_of,
                                    situation_series)
from usv_mj.physics.encounters import G_ALPHA, G_BETA, G_RANGE, courses_deg, pair_series, speeds

_SPEED_FLOOR = 1e-9   # a relative speed change of a vessel at rest: divide by this, not 0


@dataclass(frozen=True)
class ScoreParams:
    """Radii, weights and thresholds of the scores (names as NTNU colav-sim ``evaluator.yaml``).

    Attributes
    ----------
    r_col_L, r_nm_L, r_min_L, r_pref_L:
        Collision, near-miss, minimum acceptable and preferred passing distances, centre to centre
        [own-ship lengths]: 1, 2, 3, 5 (research note §7 item 4; all below Imazu's closest start,
        8.7 L at k_R = 50). colav-sim's are 30 / 50 / 100 / 190 m for an 8.45 m boat.
    gamma_min, gamma_nm, gamma_col:
        The drops of S_r over [R_min, R_pref), [R_nm, R_min), [R_col, R_nm) [-]: 0.2, 0.3, 0.5 (sum 1).
    gamma_alpha, gamma_beta:
        The pose score's weights on the contact angle and the relative bearing at CPA [-]: 0.25, 0.75.
    alpha_cut_deg, beta_cut_deg:
        Beyond these |angles| the pose term is full [deg]: 90, 90.
    delta_course_md_deg, delta_course_app_deg:
        A course change is detectable from 2 deg, readily apparent from 30 deg (Rule 8 b).
    delta_speed_md, delta_speed_reduction_app:
        A speed change relative to the speed at entry is detectable from 0.2, apparent from 0.5 [-].
    theta_sm_lim_deg:
        A head-on turn to starboard smaller than this is no starboard manoeuvre (P_nsb = 1) [deg]: 10.
    gamma_na_delta_chi, gamma_na_delta_u:
        S_apparent = 1 - gamma_na_delta_chi P_na_course - gamma_na_delta_u P_na_speed: 0.5, 0.5.
    gamma_so_delta_chi, gamma_so_delta_u_up, gamma_so_delta_u_down:
        A stand-on stage's action penalty: 0.5 course + 0.25 speed-up + 0.25 slow-down.
    gamma_ho_sts, gamma_ho_nsm:
        Head-on: starboard-to-starboard passing 0.6, no starboard manoeuvre 0.4.
    gamma_ahead_ot, gamma_ahead_cr:
        Passing ahead of the other: 0.3 when overtaking, 0.5 when giving way in a crossing.
    alpha_ahead_ot_absmax_deg:
        Overtaking: |alpha_cpa| below this is "passed ahead" [deg]: 45.
    alpha_ahead_cr_min_deg, alpha_ahead_cr_max_deg:
        Crossing: alpha_cpa in this open interval is "crossed ahead" [deg]: (-25, 165).
    apparent_either:
        False (OE-2023): S_apparent weighs both penalties, so a readily apparent turn with no speed
        change scores 0.5. True: either an apparent course or an apparent speed change is enough
        ("course and/or speed", Rule 8 b; AutoVerification's alg. 13): S_apparent = 1 - min(P_na_course,
        P_na_speed).
    """

    r_col_L: float = 1.0
    r_nm_L: float = 2.0
    r_min_L: float = 3.0
    r_pref_L: float = 5.0
    gamma_min: float = 0.2
    gamma_nm: float = 0.3
    gamma_col: float = 0.5
    gamma_alpha: float = 0.25
    gamma_beta: float = 0.75
    alpha_cut_deg: float = 90.0
    beta_cut_deg: float = 90.0
    delta_course_md_deg: float = 2.0
    delta_course_app_deg: float = 30.0
    delta_speed_md: float = 0.2
    delta_speed_reduction_app: float = 0.5
    theta_sm_lim_deg: float = 10.0
    gamma_na_delta_chi: float = 0.5
    gamma_na_delta_u: float = 0.5
    gamma_so_delta_chi: float = 0.5
    gamma_so_delta_u_up: float = 0.25
    gamma_so_delta_u_down: float = 0.25
    gamma_ho_sts: float = 0.6
    gamma_ho_nsm: float = 0.4
    gamma_ahead_ot: float = 0.3
    gamma_ahead_cr: float = 0.5
    alpha_ahead_ot_absmax_deg: float = 45.0
    alpha_ahead_cr_min_deg: float = -25.0
    alpha_ahead_cr_max_deg: float = 165.0
    apparent_either: bool = False

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "apparent_either":
                if not isinstance(value, bool):
                    raise ValueError(f"ScoreParams.apparent_either must be true or false, got {value!r}")
            elif isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"ScoreParams.{f.name} must be a finite number, got {value!r}")
        if not self.r_pref_L > self.r_min_L > self.r_nm_L > self.r_col_L >= 0.0:
            raise ValueError("ScoreParams: the radii must satisfy r_pref_L > r_min_L > r_nm_L > r_col_L >= 0, got "
                             f"{self.r_pref_L}, {self.r_min_L}, {self.r_nm_L}, {self.r_col_L}")
        if abs(self.gamma_min + self.gamma_nm + self.gamma_col - 1.0) > 1e-9:
            raise ValueError("ScoreParams: gamma_min + gamma_nm + gamma_col must be 1")
        if not self.delta_course_app_deg > self.delta_course_md_deg >= 0.0:
            raise ValueError("ScoreParams: delta_course_app_deg must exceed delta_course_md_deg >= 0")
        if not self.delta_speed_reduction_app > self.delta_speed_md >= 0.0:
            raise ValueError("ScoreParams: delta_speed_reduction_app must exceed delta_speed_md >= 0")
        if not self.delta_course_app_deg > self.theta_sm_lim_deg >= 0.0:
            raise ValueError("ScoreParams: theta_sm_lim_deg must be below delta_course_app_deg")

    def radii_m(self, length_m: float) -> tuple[float, float, float, float]:
        """(R_col, R_nm, R_min, R_pref) [m] for the own ship's length."""
        return (self.r_col_L * length_m, self.r_nm_L * length_m, self.r_min_L * length_m, self.r_pref_L * length_m)


# --- the pieces (scalar formulas) -------------------------------------------------------------------------


def _unit(x: float) -> float:
    return float(min(1.0, max(0.0, x)))


def range_score(r_cpa: float, length_m: float, p: ScoreParams | None = None) -> float:
    """S_r (OE-2023 eq. 3): 1 from R_pref, then linear drops of gamma_min down to R_min, gamma_nm
    down to R_nm, gamma_col down to R_col, 0 inside R_col."""
    p = p or ScoreParams()
    r_col, r_nm, r_min, r_pref = p.radii_m(length_m)
    if r_cpa >= r_pref:
        return 1.0
    if r_cpa >= r_min:
        return 1.0 - p.gamma_min * (r_pref - r_cpa) / (r_pref - r_min)
    if r_cpa >= r_nm:
        return 1.0 - p.gamma_min - p.gamma_nm * (r_min - r_cpa) / (r_min - r_nm)
    if r_cpa >= r_col:
        return _unit(1.0 - p.gamma_min - p.gamma_nm - p.gamma_col * (r_nm - r_cpa) / (r_nm - r_col))
    return 0.0


def _pose_term(angle_deg: float, cut_deg: float) -> float:
    a = abs(float(angle_deg))
    if a >= cut_deg:
        return 1.0
    return (1.0 - math.cos(math.radians(a))) / (1.0 - math.cos(math.radians(cut_deg)))


def pose_score(alpha_cpa_deg: float, beta_cpa_deg: float, p: ScoreParams | None = None) -> float:
    """S_theta (OE-2023 eqs. 4-6) = gamma_alpha c(alpha) + gamma_beta c(beta), c(x) = (1 - cos x) /
    (1 - cos x_cut) below the cut and 1 beyond: 0 bow to bow, 1 passing abeam or astern."""
    p = p or ScoreParams()
    return _unit(p.gamma_alpha * _pose_term(alpha_cpa_deg, p.alpha_cut_deg)
                 + p.gamma_beta * _pose_term(beta_cpa_deg, p.beta_cut_deg))


def safety_score(s_r: float, s_theta: float) -> float:
    """S_safety (OE-2023 eq. 2) = (1 - S_r) S_theta + S_r, and 0 when S_r = 0 (inside R_col): the
    pose cannot mask a collision (the formula alone would give S_theta there; the reconstruction's
    ``total_safety_score`` and research note §3.2 make it 0)."""
    if s_r <= 0.0:
        return 0.0
    return _unit((1.0 - s_r) * s_theta + s_r)


def non_apparent_penalty(x: float, detectable: float, apparent: float) -> float:
    """1 up to ``detectable``, 1 - q^2 between (q = (x - detectable) / (apparent - detectable)), 0
    from ``apparent`` on (|x|)."""
    x = abs(float(x))
    if x <= detectable:
        return 1.0
    if x >= apparent:
        return 0.0
    q = (x - detectable) / (apparent - detectable)
    return _unit(1.0 - q * q)


def action_penalty(x: float, detectable: float, apparent: float) -> float:
    """A stand-on vessel's action: 0 up to ``detectable``, linear to 1 at ``apparent`` (|x|)."""
    x = abs(float(x))
    if x <= detectable:
        return 0.0
    return _unit((x - detectable) / (apparent - detectable))


def starboard_to_starboard_penalty(alpha_cpa_deg: float, beta_cpa_deg: float) -> float:
    """P_sts (OE-2023 eq. 28, clockwise angles): 1 - ((sin a - 1)/2)^2 ((sin b - 1)/2)^2: 0 for a port
    to port passing (a = b = -90), 1 for starboard to starboard (a = b = +90)."""
    a = ((math.sin(math.radians(alpha_cpa_deg)) - 1.0) / 2.0) ** 2
    b = ((math.sin(math.radians(beta_cpa_deg)) - 1.0) / 2.0) ** 2
    return _unit(1.0 - a * b)


def non_starboard_penalty(starboard_change_deg: float, p: ScoreParams | None = None) -> float:
    """P_nsb (OE-2023 eqs. 29-30): 1 below theta_sm_lim, 0 above the apparent course change, 1 - q^2
    between (q over [theta_sm_lim, delta_course_app])."""
    p = p or ScoreParams()
    x = float(starboard_change_deg)
    if x < p.theta_sm_lim_deg:
        return 1.0
    if x > p.delta_course_app_deg:
        return 0.0
    q = (x - p.theta_sm_lim_deg) / (p.delta_course_app_deg - p.theta_sm_lim_deg)
    return _unit(1.0 - q * q)


def _wrap180(a):
    w = 180.0 - np.mod(180.0 - np.asarray(a, dtype=float), 360.0)
    return np.where(w <= -180.0, w + 360.0, w)


# --- one pair ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PairScores:
    """The scores of own ship against one target (module docstring); None where a score does not
    apply. Angles [deg] clockwise, + = starboard; ranges [m]; times [s]; indices into the series."""

    situation: str
    role: str
    entry_index: int | None
    cpa_index: int
    t_cpa_s: float
    r_cpa_m: float
    alpha_cpa_deg: float
    beta_cpa_deg: float
    S_r: float
    S_theta: float
    S_safety: float
    S_apparent: float | None
    P_delay: float | None
    P_na_course: float | None
    P_na_speed: float | None
    P_nsb: float | None
    P_sts: float | None
    P_stage2: float | None
    P_stage3: float | None
    P_port_turn: float | None
    P_ahead: float | None
    S13: float | None
    S14: float | None
    S15: float | None
    S16: float | None
    S17: float | None

    def to_dict(self) -> dict:
        return asdict(self)


#: the scores that :func:`min_over_targets` reduces
SCORE_NAMES = ("S_r", "S_theta", "S_safety", "S13", "S14", "S15", "S16", "S17")


def _situation_code(situation) -> int:
    if isinstance(situation, str):
        if situation not in SITUATION_NAMES:
            raise ValueError(f"score_pair: situation must be one of {', '.join(SITUATION_NAMES)}, got {situation!r}")
        return SITUATION_NAMES.index(situation)
    code = int(situation)
    if not 0 <= code < len(SITUATION_NAMES):
        raise ValueError(f"score_pair: situation code must be 0..{len(SITUATION_NAMES) - 1}, got {situation!r}")
    return code


def _stand_on_penalty(chi, u, idx, p: ScoreParams) -> float:
    """The action penalty of one stand-on stage: its samples ``idx`` against the first one."""
    if idx.size == 0:
        return 0.0
    k = idx[0]
    course = float(np.max(np.abs(_wrap180(chi[idx] - chi[k]))))
    u0 = max(float(u[k]), _SPEED_FLOOR)
    up = max(0.0, float(np.max(u[idx] - u[k]))) / u0
    down = max(0.0, float(np.max(u[k] - u[idx]))) / u0
    return _unit(p.gamma_so_delta_chi * action_penalty(course, p.delta_course_md_deg, p.delta_course_app_deg)
                 + p.gamma_so_delta_u_up * action_penalty(up, p.delta_speed_md, p.delta_speed_reduction_app)
                 + p.gamma_so_delta_u_down * action_penalty(down, p.delta_speed_md, p.delta_speed_reduction_app))


def score_pair(t, own, target, own_length_m: float, *, target_length_m: float | None = None,
               params: ScoreParams | None = None, colregs: ColregsParams | None = None,
               situation=None, entry_index: int = 0) -> PairScores:
    """The scores of ``own`` against ``target`` over a finished run.

    ``t`` (T,) [s]; ``own``, ``target`` (T, 6) states (x, y, psi, u, v, r) at those times;
    ``own_length_m`` scales the radii; the stage ranges use max(own, target) length
    (``target_length_m`` defaults to the own ship's). ``situation`` (a code or a name of
    :data:`usv_mj.physics.colregs.SITUATION_NAMES`) overrides the lock, the window then starting at
    ``entry_index`` (the first sample by default): a situation the scenario defines (Imazu's, from
    the start), so that a manoeuvre made before the stage-2 range counts as the early action it is.
    Without it the situation is the first one the lock of :mod:`usv_mj.physics.colregs` enters over
    the run, the window starting there (a vessel that altered course before the stage-2 range may
    enter none); a pair that never enters one gets only S_r, S_theta and S_safety (over the whole run).
    """
    p = params or ScoreParams()
    cp = colregs or ColregsParams()
    t = np.asarray(t, dtype=float)
    own = np.ascontiguousarray(own, dtype=np.float64)
    target = np.ascontiguousarray(target, dtype=np.float64)
    if own.ndim != 2 or own.shape != target.shape or own.shape[0] != t.shape[0] or own.shape[0] == 0:
        raise ValueError(f"score_pair: t (T,), own and target (T, 6) must agree, got {t.shape}, {own.shape}, "
                         f"{target.shape}")
    if not own_length_m > 0.0:
        raise ValueError(f"score_pair: own_length_m must be positive, got {own_length_m!r}")
    ref_len = max(float(own_length_m), float(target_length_m or own_length_m))
    geo = pair_series(own, target)
    rng = geo[:, G_RANGE]
    stage2, stage3, stage4 = cp.stage_ranges_m(ref_len)

    if situation is None:
        sit = situation_series(np.stack([own, target], axis=1), [ref_len, ref_len], cp)[:, 0, 1]
        entered = np.flatnonzero(sit != NONE)
        code = int(sit[entered[0]]) if entered.size else NONE
        k0 = int(entered[0]) if entered.size else None
    else:
        code = _situation_code(situation)
        if isinstance(entry_index, bool) or not isinstance(entry_index, (int, np.integer)) \
                or not 0 <= entry_index < t.shape[0]:
            raise ValueError(f"score_pair: entry_index must be a sample index 0..{t.shape[0] - 1}, got {entry_index!r}")
        k0 = int(entry_index)
    start = 0 if k0 is None else k0
    k_cpa = start + int(np.argmin(rng[start:]))
    r_cpa, alpha, beta = float(rng[k_cpa]), float(geo[k_cpa, G_ALPHA]), float(geo[k_cpa, G_BETA])
    s_r = range_score(r_cpa, own_length_m, p)
    s_theta = pose_score(alpha, beta, p)
    s_safety = safety_score(s_r, s_theta)
    base = dict(situation=SITUATION_NAMES[code], role=role_of(code), entry_index=k0, cpa_index=k_cpa,
                t_cpa_s=float(t[k_cpa]), r_cpa_m=r_cpa, alpha_cpa_deg=alpha, beta_cpa_deg=beta,
                S_r=s_r, S_theta=s_theta, S_safety=s_safety)
    none = dict.fromkeys(("S_apparent", "P_delay", "P_na_course", "P_na_speed", "P_nsb", "P_sts", "P_stage2",
                          "P_stage3", "P_port_turn", "P_ahead", "S13", "S14", "S15", "S16", "S17"))
    if code == NONE or k0 is None:
        return PairScores(**base, **none)

    # own ship's track from entry to CPA: course change (clockwise, + starboard) and speed
    win = np.arange(k0, k_cpa + 1)
    chi = courses_deg(own)
    u = speeds(own)
    dchi = _wrap180(chi[win] - chi[k0])
    u0 = max(float(u[k0]), _SPEED_FLOOR)
    course_change = float(np.max(np.abs(dchi)))
    starboard_change = max(0.0, float(np.max(dchi)))
    speed_reduction = max(0.0, float(np.max(u0 - u[win]))) / u0
    out = dict(none)
    role = ROLE_OF[code]
    if role == GIVE_WAY:
        p_course = non_apparent_penalty(course_change, p.delta_course_md_deg, p.delta_course_app_deg)
        p_speed = non_apparent_penalty(speed_reduction, p.delta_speed_md, p.delta_speed_reduction_app)
        if p.apparent_either:
            s_apparent = _unit(1.0 - min(p_course, p_speed))
        else:
            s_apparent = _unit(1.0 - p.gamma_na_delta_chi * p_course - p.gamma_na_delta_u * p_speed)
        # the manoeuvre starts at the first detectable course or speed change (none: at CPA)
        moved = (np.abs(dchi) >= p.delta_course_md_deg) | (np.abs(u[win] - u0) / u0 >= p.delta_speed_md)
        k_man = int(win[np.argmax(moved)]) if moved.any() else k_cpa
        r_man, r_entry = float(rng[k_man]), max(float(rng[k0]), _SPEED_FLOOR)
        p_delay = 0.0 if r_man > stage3 else _unit((r_entry - r_man) / r_entry)
        s16 = _unit(s_safety * s_apparent * (1.0 - p_delay))
        out.update(S_apparent=s_apparent, P_delay=p_delay, P_na_course=p_course, P_na_speed=p_speed, S16=s16)
        if code == HEAD_ON:
            p_nsb = non_starboard_penalty(starboard_change, p)
            p_sts = starboard_to_starboard_penalty(alpha, beta)
            out.update(P_nsb=p_nsb, P_sts=p_sts, S14=_unit((1.0 - p.gamma_ho_nsm * p_nsb - p.gamma_ho_sts * p_sts)
                                                           * (1.0 - p_course) * (1.0 - p_delay)))
        elif code == OVERTAKING:
            p_ahead = float(abs(alpha) < p.alpha_ahead_ot_absmax_deg)
            out.update(P_ahead=p_ahead, S13=_unit(s16 - p.gamma_ahead_ot * p_ahead))
        elif code == CROSSING_GIVE_WAY:
            p_ahead = float(p.alpha_ahead_cr_min_deg < alpha < p.alpha_ahead_cr_max_deg)
            out.update(P_ahead=p_ahead, S15=_unit(s16 - p.gamma_ahead_cr * p_ahead))
    elif role == STAND_ON:
        r_win = rng[win]
        in2 = win[(r_win <= stage2) & (r_win > stage3)]
        in3 = win[(r_win <= stage3) & (r_win > stage4)]
        in4 = win[r_win <= stage4]
        p2, p3 = _stand_on_penalty(chi, u, in2, p), _stand_on_penalty(chi, u, in3, p)
        p_pt = 0.0
        # Rule 17 c: no turn to port for a vessel on own port side (judged in stage 4)
        if in4.size and geo[in4[0], G_BETA] < 0.0:
            port_change = max(0.0, -float(np.min(_wrap180(chi[in4] - chi[in4[0]]))))
            p_pt = float(port_change >= p.delta_course_md_deg)
        s17 = _unit(s_safety * (1.0 - p2) * (1.0 - p3) * (1.0 - p_pt))
        out.update(P_stage2=p2, P_stage3=p3, P_port_turn=p_pt, S17=s17)
        if code == OVERTAKEN:
            out.update(S13=s17)
        elif code == CROSSING_STAND_ON:
            out.update(S15=s17)
    return PairScores(**base, **out)


# --- every target -----------------------------------------------------------------------------------------


def min_over_targets(pairs) -> dict:
    """``{score: the smallest value over the pairs where it applies (None where none does)}`` for
    :data:`SCORE_NAMES`."""
    out = {}
    for name in SCORE_NAMES:
        values = [getattr(s, name) for s in pairs if getattr(s, name) is not None]
        out[name] = min(values) if values else None
    return out


@dataclass(frozen=True)
class EncounterScores:
    """Own ship against every other vessel: ``pairs[j]`` the scores against vessel j, ``minimum``
    the smallest of each score over the targets (:func:`min_over_targets`)."""

    own: int
    pairs: dict
    minimum: dict

    def to_dict(self) -> dict:
        return {"own": self.own, "pairs": {str(j): s.to_dict() for j, s in self.pairs.items()},
                "minimum": dict(self.minimum)}


def score_encounters(t, states, lengths, *, own: int = 0, params: ScoreParams | None = None,
                     colregs: ColregsParams | None = None, situations: dict | None = None) -> EncounterScores:
    """The scores of vessel ``own`` against every other vessel of a run: ``states`` (T, N, 6),
    ``lengths`` (N,) [m] (:func:`score_pair` per pair; the pairs are locked independently).
    ``situations`` (optional): ``{j: situation}`` for the pairs whose situation the scenario defines
    (windows from the first sample), e.g. an Imazu case's."""
    states = np.asarray(states, dtype=np.float64)
    lengths = np.asarray(lengths, dtype=np.float64)
    if states.ndim != 3 or lengths.shape != (states.shape[1],):
        raise ValueError(f"score_encounters: states (T, N, 6) and lengths (N,) must agree, got {states.shape}, "
                         f"{lengths.shape}")
    if not 0 <= own < states.shape[1]:
        raise ValueError(f"score_encounters: own must be a vessel index 0..{states.shape[1] - 1}, got {own}")
    pairs = {j: score_pair(t, states[:, own], states[:, j], float(lengths[own]), target_length_m=float(lengths[j]),
                           params=params, colregs=colregs, situation=(situations or {}).get(j))
             for j in range(states.shape[1]) if j != own}
    return EncounterScores(own, pairs, min_over_targets(pairs.values()))
