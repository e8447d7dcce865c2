"""Scenario-based MPC collision avoidance (Johansen, Perez and Cristofaro 2016) over the LOS path follower.

A COLREGs-aware collision-avoidance law for any vessel of a scenario with ``[[vessels]]``
(docs/encounters.md, "Collision avoidance"): ``[controller] kind = "sbmpc"``. It steers the
vessel's own reference with the path follower of :mod:`usv_mj.controllers.los` (the LOS controller
itself, composed: its law, its gains, its kernel) and, every re-plan period, chooses one of a finite
set of *behaviours*, a course offset chi_ca and a factor P on the speed command, by simulating each
ahead against the other vessels and scoring it. "No avoidance", the baseline, is ``kind = "los"``
with the same gains: the path follower alone.

Sources: T. A. Johansen, T. Perez and A. Cristofaro, "Ship collision avoidance and COLREGS compliance
using simulation-based control behavior selection with predictive hazard assessment", IEEE T-ITS
17(12), 2016, doi 10.1109/TITS.2016.2551780 (the method; only its abstract was readable); the cost,
the COLREGs predicate mu and the defaults as the public implementations write them (research note
/work/notes/encounters-research.md §4: PSBMPC ``sbmpc.cpp``, ``mpc_cost_cpu.hpp``, AutoSea
``sb_mpc.cpp``); the transitional cost of Hagen et al., ICRA 2018, doi 10.1109/ICRA.2018.8463182
(§4.4). Conventions are usv_mj's (ENU, psi and courses counter-clockwise from east): a course offset
chi_ca > 0 turns to **port**, chi_ca < 0 to **starboard**. What is this module's own and not the
sources' is marked *(here)*.

**The behaviours** (§4.1): course offsets {-90, -75, ..., 90} deg (13) x speed factors {1, 0.5, 0}
(39), each held over the horizon. A behaviour is, for the path follower:

- (0, P): LOS on the vessel's own reference path, its speed command times P (LOS brings the
  vessel back to its path);
- (chi_ca != 0, P): LOS on the straight line through the vessel's position at the re-plan at the
  path angle + chi_ca: the course pi_p + chi_ca held *(here: Johansen adds chi_ca to the LOS course
  command, so that LOS keeps pulling the vessel back and it settles Delta tan(chi_ca) off its path,
  1.7 m for 30 deg with this hull's 3 m lookahead; the other vessels, predicting it at constant
  velocity, then expect it to keep drifting and each gives way less than it needs: in test_fleet's
  head-on the two passed 6.2 m apart instead of the 9.9 m aimed at. Holding the course is what the
  constant-velocity prediction of the others assumes.)*

LOS is commanded through a *virtual reference* it reads exactly as the behaviour asks: a point on
the line abeam of the vessel (on the path: at the true cross-track error, so LOS's own integral
state sees the path's), moving along the line at P x LOS's speed command. With the nominal behaviour
(0, 1) the vessel's own reference is passed unchanged: without other vessels (a single run, or none
within ``d_relevant_L``) the law **is** the LOS controller, bit for bit, and a single run compiles
with LOS's kernel.

**The prediction** of each behaviour from the re-plan time t0 over the horizon T = horizon_L L / U
(L the own hull's length, U the reference's path speed at t0) in steps of ``prediction_step_s``
(:func:`predict_own`): the own ship as a kinematic course/speed model driven by the path follower's
guidance on the behaviour's line (LOS step 2, plain: chi_c = angle - atan(y_e / Delta); on the path
the reference point moves on at its velocity at t0, a straight path) and its speed command (LOS step
5, P clip(U_p - u_at x_e / sqrt(x_e^2 + l_at^2), u_c_min, u_c_max), x_e along the reference path),
the course and the speed lagging their commands by first-order lags T_chi, T_U (exact
discretization); every other vessel within ``d_relevant_L`` own lengths at constant velocity over
ground (its state's R(psi) (u, v)).

**The cost** of behaviour k (§4.2), minimised over the 39 (:func:`plan_behaviours`):

    H(k) = max_i max_t [ C_i(t) R_i(t) + kappa mu_i(t) + kappa_TC mu_TC,i(t) ]
           + K_u (1 - P) + K_du |P - P_last| + K_chi,side chi_ca^2 + K_dchi,side wrap(chi_ca - chi_last)^2

- collision risk R_i(t) = (d_safe / d_i(t))^q / (t - t0)^p while d_i(t) <= d_safe and the pair is
  closing, else 0: d_i the **hull-to-hull** distance (centre distance minus (L_0 + L_i)/2, PSBMPC's),
  floored at d_safe / 20 (an overlap has a finite risk); p = 1, q = 4. *(Here: "and closing",
  (p_i - p_0).(v_i - v_0) < 0. Without it a pair already inside d_safe but opening keeps the risk of
  its first predicted instants, the same for every behaviour, and C's |dv|^2 then rewards the
  behaviour that matches the target's velocity: in a crossing from starboard the give-way ship,
  past astern, turned to follow the target at 5.5 m.)*
- collision cost C_i(t) = k_coll (|v_0(t) - v_i| / U)^2: PSBMPC's K_coll |dv|^2 with K_coll = 0.2 at
  about 2 m/s, made dimensionless with the research note's scaling K_coll = 0.2 (2 m/s / U)^2
  (§7 item 6), so k_coll = 0.8;
- mu_i(t) (§4.3, Johansen's predicate as PSBMPC and AutoSea compute it along the predicted tracks; v
  the velocities, L the unit line of sight from own ship to the target): CLOSE (centre distance <=
  d_close) and STARBOARD (the target to starboard of own course) and (HEAD_ON or (CROSSED and not
  OVERTAKEN)); HEAD_ON = |v_i| > eps and v_0.v_i < -cos(phi_HO)|v_0||v_i| and v_0.L > cos(phi_AH)|v_0|;
  CROSSED = v_0.v_i < cos(phi_CR)|v_0||v_i|; OVERTAKEN = v_0.v_i > cos(phi_OT)|v_0||v_i| and
  |v_0| < |v_i|;
- mu_TC,i(t) (§4.4): with the pair's flags at t0 (:func:`pair_flags`: S_0 target on starboard, O_0
  own ship overtaking, Q_0 own ship overtaken, H_0 head-on, X_0 crossing), while CLOSE the behaviour
  makes the target change sides as COLREGs forbid: O_0 and the side changed; Q_0 and own ship's
  side seen from the target changed; X_0 and S_0 and S(t) and chi_ca to port; H_0 and not S_0 and S(t);
- neither mu nor mu_TC counts once the pair is passed (one vessel more than 112.5 deg off the
  other's course and not being overtaken by it: PSBMPC's) and farther than d_safe *(here for mu_TC
  too: past, a target astern sits on one side or the other, which is no violation)*;
- the control cost (§4.2, PSBMPC's form), course terms in rad^2, port offsets and port changes
  weighted more (Rules 14/15: alter to starboard).

**The stand-on duty** *(here; not in Johansen's cost)*: while the own ship's locked COLREGs role
(:mod:`usv_mj.physics.colregs`, the lock of docs/encounters.md, advanced every control period) is
*stand-on* towards some vessel, all such vessels are farther than ``stand_on_range_L`` own lengths
(stage 3, where Rule 17 a ii lets it act) and it gives way to none, the behaviour is (0, 1): it keeps
its course and speed (Rule 17 a i). Without it two SB-MPC vessels in a crossing both turn at the
first re-plan: each predicts the other at constant velocity, and the stand-on one cannot know yet that
the give-way one will act.

**The path follower's gains** are LOS's (every key of ``kind = "los"``, :class:`SBMPCGains` extends
:class:`usv_mj.controllers.los.LOSGains`) with one default changed: ``crab_compensation = false``.
LOS's heading command chi_d - beta feeds the sway of a hard turn back into the heading: on the paper
hull a 75 deg course step at 0.6 m/s gives a 60 deg crab angle (v = 0.55 m/s at u = 0.31 m/s), the
heading overshoots by about 55 deg and swings +-30 deg for 10 s; an avoidance manoeuvre is such a
step.

**Parameters** (:class:`SBMPCGains`): defaults from the research note §7 item 6 (PSBMPC's milliAmpere
tuning, the only public one for a 5 m craft at about 2 m/s), distances in own-ship lengths L and the
horizon in L/U, so that the same numbers suit a 2 m USV and a 320 m tanker. Diagnostics: LOS's
(``cross_track_error``, ``along_track_error`` and ``path_angle`` of the vessel's own path, ``chi_d``
the course commanded), then the behaviour held, its cost and the nearest vessel's range, DCPA and TCPA
(:data:`AVOIDANCE_FIELDS`). Criterion: :class:`usv_mj.record.criteria.Clearance`, the nearest vessel
outside the own ship's safety domain (:data:`usv_mj.record.encounters.SAFETY_DOMAIN_L` own lengths,
centre to centre) at every step with a vessel in sight; a run without other vessels has no judged
step (not judged).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numba import njit

from usv_mj.controllers.base import REF_PSI, REF_R, REF_U, REF_X, REF_XDOT, REF_Y, REF_YDOT
from usv_mj.controllers.los import DIAGNOSTIC_FIELDS as LOS_FIELDS
from usv_mj.controllers.los import G_DELTA, G_L_AT, G_U_AT, G_U_MAX, G_U_MIN, LOSController, LOSGains, path_errors
from usv_mj.core.errors import ScenarioError
from usv_mj.core.registry import CONTROLLERS
from usv_mj.physics.colregs import GIVE_WAY, NONE, ROLE_OF, STAND_ON, ColregsParams, update_situation
from usv_mj.physics.encounters import G_ALPHA, G_BETA, G_DCPA, G_RANGE, G_TCPA, pair_geometry, world_velocity
from usv_mj.physics.ship import wrap_angle
from usv_mj.record.criteria import Clearance
from usv_mj.record.encounters import SAFETY_DOMAIN_L

#: the diagnostics: the path follower's, then the avoidance's
AVOIDANCE_FIELDS = (
    "course_offset",     # chi_ca of the behaviour held [rad], > 0 to port, < 0 to starboard
    "speed_factor",      # P of the behaviour held [-] (1 nominal, 0.5 half, 0 stop)
    "avoidance_cost",    # H of the behaviour held, at its re-plan [-] (NaN before the first plan)
    "nearest_range",     # range to the nearest other vessel, centre to centre [m] (NaN: none)
    "nearest_dcpa",      # its DCPA at constant velocities [m] (NaN: none)
    "nearest_tcpa",      # its TCPA [s], < 0 when the closest point is past (NaN: none)
)
DIAGNOSTIC_FIELDS = LOS_FIELDS + AVOIDANCE_FIELDS
N_LOS = len(LOS_FIELDS)
D_OFFSET, D_FACTOR, D_COST, D_RANGE, D_DCPA, D_TCPA = range(N_LOS, N_LOS + len(AVOIDANCE_FIELDS))

#: below this path speed [m/s] the horizon's speed scale U is this (a reference standing still)
SPEED_FLOOR = 0.05
#: at most this many prediction steps: a longer horizon is divided into this many
MAX_STEPS = 4000
#: the hull-to-hull distance in the risk is floored at d_safe / this (an overlap has a finite risk)
D_FLOOR_DIVISOR = 20.0
#: 22.5 deg abaft the beam: a vessel more than this off the other's course is passed (Rule 13)
PASSED_DEG = 112.5


class OverLOSGains(LOSGains):
    """The gains of an avoidance law over the LOS path follower (sbmpc, vo): LOS's fields first, then
    the law's own; the path follower's kernel reads only LOS's, packed by position."""

    def los_gains(self) -> LOSGains:
        """The path follower's gains (the LOS fields of this dataclass)."""
        return LOSGains(**{f.name: getattr(self, f.name) for f in fields(LOSGains)})

    def as_array(self) -> np.ndarray:
        """The path follower's gains packed (LOS's kernel reads them by position)."""
        return self.los_gains().as_array()


@dataclass(frozen=True)
class SBMPCGains(OverLOSGains):
    """The path follower's gains (:class:`usv_mj.controllers.los.LOSGains`, every key of
    ``kind = "los"``), then the SB-MPC's (module docstring for the cost; research note §4.5 and §7
    item 6 for the defaults). L: the own hull's length [m]; U: the reference's path speed at the
    re-plan [m/s]."""

    crab_compensation: bool = False       # LOS's, off here (los: on): module docstring, "The path follower"
    # --- the behaviours (§4.1)
    max_offset_deg: float = 90.0          # [deg] the largest course offset either side, in (0, 180]
    offset_step_deg: float = 15.0         # [deg] their spacing: {-90, -75, ..., 0, ..., 75, 90}
    speed_factors: tuple = (1.0, 0.5, 0.0)  # [-] the factors on the speed command, each in [0, 1], 1 among them
    # --- the prediction
    horizon_L: float = 60.0               # [L/U] the horizon T = horizon_L L / U (120 s for 2 m at 1 m/s)
    prediction_step_s: float = 0.5        # [s] the prediction's step (PSBMPC 0.5 s)
    replan_period_s: float = 2.0          # [s] a behaviour is chosen this often and held between (2-5 s, §7)
    course_time_s: float = 1.0            # [s] T_chi, the course's first-order lag (PSBMPC 0.92 s)
    speed_time_s: float = 1.5             # [s] T_U, the speed's first-order lag (PSBMPC 1.44 s)
    # --- distances, in own lengths
    d_safe_L: float = 4.0                 # [L] the safety distance, hull to hull (PSBMPC's measure)
    d_close_L: float = 25.0               # [L] COLREGs apply within this centre distance (stage 2)
    d_relevant_L: float = 50.0            # [L] vessels farther than this at the re-plan are ignored (R = 50 L)
    # --- the cost (§4.2-4.4)
    p_time: float = 1.0                   # [-] p, the risk's time exponent
    q_distance: float = 4.0               # [-] q, the risk's distance exponent
    k_coll: float = 0.8                   # [-] collision cost k_coll (|dv|/U)^2 (PSBMPC's 0.2 s^2/m^2 at 2 m/s)
    kappa: float = 10.0                   # [-] the COLREGs violation mu's cost
    kappa_tc: float = 20.0                # [-] the transitional cost mu_TC's
    k_speed: float = 15.0                 # [-] K_u, per unit of speed reduction 1 - P
    k_speed_change: float = 6.0           # [-] K_du, per unit of |P - P_last|
    k_course_starboard: float = 1.3       # [1/rad^2] K_chi for a starboard offset
    k_course_port: float = 1.6            # [1/rad^2] K_chi for a port offset
    k_change_starboard: float = 0.9       # [1/rad^2] K_dchi for a change of offset to starboard
    k_change_port: float = 1.2            # [1/rad^2] K_dchi for a change to port
    phi_ah_deg: float = 68.5              # [deg] "ahead": the target within this of own course
    phi_ot_deg: float = 68.5              # [deg] overtaking: courses within this
    phi_ho_deg: float = 22.5              # [deg] head-on: courses within this of reciprocal
    phi_cr_deg: float = 68.5              # [deg] crossing: courses more than this apart
    head_on_min_speed_U: float = 0.125    # [U] a target slower than this is never head-on (PSBMPC 0.25 m/s at 2 m/s)
    # --- the stand-on duty (this module's: Rule 17)
    stand_on: bool = True                 # a stand-on vessel keeps course and speed (Rule 17 a i) while ...
    stand_on_range_L: float = 7.5         # [L] ... the target is farther than this (stage 3: Rule 17 a ii)

    def __post_init__(self) -> None:
        self.los_gains()   # the path follower's gains, validated as LOS validates them
        own = [f.name for f in fields(SBMPCGains) if f.name not in {g.name for g in fields(LOSGains)}]
        for name in own:
            if name == "speed_factors":
                continue
            if name == "stand_on":
                if not isinstance(self.stand_on, bool):
                    raise ScenarioError(f"controller.stand_on must be true or false, got {self.stand_on!r}")
                continue
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ScenarioError(f"controller.{name} must be a finite number >= 0, got {v!r}")
        for name in ("offset_step_deg", "horizon_L", "prediction_step_s", "replan_period_s", "course_time_s",
                     "speed_time_s", "d_safe_L", "d_close_L", "d_relevant_L", "q_distance"):
            if not getattr(self, name) > 0:
                raise ScenarioError(f"controller.{name} must be > 0, got {getattr(self, name)!r}")
        if not 0 < self.max_offset_deg <= 180:
            raise ScenarioError(f"controller.max_offset_deg must be in (0, 180], got {self.max_offset_deg!r}")
        if self.offset_step_deg > self.max_offset_deg:
            raise ScenarioError(f"controller.offset_step_deg ({self.offset_step_deg!r}) must not exceed "
                                f"controller.max_offset_deg ({self.max_offset_deg!r})")
        for name in ("phi_ah_deg", "phi_ot_deg", "phi_ho_deg", "phi_cr_deg"):
            if not 0 < getattr(self, name) < 180:
                raise ScenarioError(f"controller.{name} must be in (0, 180), got {getattr(self, name)!r}")
        f = self.speed_factors
        if not (isinstance(f, tuple) and f and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                   and 0.0 <= v <= 1.0 for v in f)):
            raise ScenarioError(f"controller.speed_factors must be a list of numbers in [0, 1], got {f!r}")
        if 1.0 not in f:
            raise ScenarioError(f"controller.speed_factors must hold 1 (the nominal speed), got {f!r}")

    def offsets(self) -> np.ndarray:
        """The course offsets [rad], from starboard to port: -max, ..., 0, ..., max."""
        n = int(math.floor(self.max_offset_deg / self.offset_step_deg + 1e-9))
        return np.radians(self.offset_step_deg * np.arange(-n, n + 1, dtype=np.float64))

    def factors(self) -> np.ndarray:
        """The speed factors, in the order given."""
        return np.array([float(v) for v in self.speed_factors], dtype=np.float64)

    def packed(self) -> np.ndarray:
        """The planner's parameters (indices ``K_*``), distances still in own lengths."""
        return np.array([
            self.horizon_L, self.prediction_step_s, self.course_time_s, self.speed_time_s,
            self.d_safe_L, self.d_close_L, self.p_time, self.q_distance, self.k_coll, self.kappa, self.kappa_tc,
            self.k_speed, self.k_speed_change, self.k_course_starboard, self.k_course_port,
            self.k_change_starboard, self.k_change_port,
            math.cos(math.radians(self.phi_ah_deg)), math.cos(math.radians(self.phi_ot_deg)),
            math.cos(math.radians(self.phi_ho_deg)), math.cos(math.radians(self.phi_cr_deg)),
            self.head_on_min_speed_U], dtype=np.float64)


(K_HORIZON, K_DT, K_TCHI, K_TU, K_DSAFE, K_DCLOSE, K_P, K_Q, K_COLL, K_KAPPA, K_KAPPA_TC, K_U, K_DU,
 K_CHI_SB, K_CHI_P, K_DCHI_SB, K_DCHI_P, K_COS_AH, K_COS_OT, K_COS_HO, K_COS_CR, K_EPS_U) = range(22)
N_PACKED = 22

# the target table's columns (plan_behaviours' ``targets``)
T_X, T_Y, T_VX, T_VY, T_LEN, T_S0, T_O0, T_Q0, T_H0, T_X0, T_SB0 = range(11)
N_TARGET = 11


# --- the predicates (§4.3), on velocities in the world frame --------------------------------------


@njit(cache=True)
def _starboard(hx, hy, lx, ly):
    """True when the direction (lx, ly) lies to starboard (clockwise) of the direction (hx, hy)."""
    return hx * ly - hy * lx < 0.0


@njit(cache=True)
def _overtaken(vax, vay, vbx, vby, cos_ot):
    """A (velocity va) is being overtaken by B (vb): courses within phi_OT and A slower."""
    na, nb = math.hypot(vax, vay), math.hypot(vbx, vby)
    return vax * vbx + vay * vby > cos_ot * na * nb and na < nb


@njit(cache=True)
def _head_on(vax, vay, vbx, vby, lx, ly, cos_ho, cos_ah, eps):
    """Head-on: B moving (faster than eps), courses within phi_HO of reciprocal, B ahead of A within phi_AH."""
    na, nb = math.hypot(vax, vay), math.hypot(vbx, vby)
    return nb > eps and vax * vbx + vay * vby < -cos_ho * na * nb and vax * lx + vay * ly > cos_ah * na


@njit(cache=True)
def _crossed(vax, vay, vbx, vby, cos_cr):
    """Crossing: courses more than phi_CR apart."""
    return vax * vbx + vay * vby < cos_cr * math.hypot(vax, vay) * math.hypot(vbx, vby)


@njit(cache=True)
def _passed(vax, vay, vbx, vby, lx, ly, cos_ot):
    """One vessel more than 112.5 deg off the other's course (abaft the beam sector) and not being
    overtaken by it (PSBMPC's "passed"); (lx, ly) the unit line of sight A -> B."""
    c = math.cos(math.radians(PASSED_DEG))
    a_passed = vax * lx + vay * ly < c * math.hypot(vax, vay) and not _overtaken(vax, vay, vbx, vby, cos_ot)
    b_passed = -(vbx * lx + vby * ly) < c * math.hypot(vbx, vby) and not _overtaken(vbx, vby, vax, vay, cos_ot)
    return a_passed or b_passed


@njit(cache=True)
def pair_flags(ax, ay, vax, vay, hax, hay, bx, by, vbx, vby, hbx, hby, k):
    """The transitional flags of a pair at the re-plan (§4.4), seen from A: (S_0 B on A's starboard,
    O_0 A overtaking B, Q_0 A overtaken by B, H_0 head-on, X_0 crossing, SB_0 A on B's starboard);
    (hax, hay), (hbx, hby): the vessels' unit courses (the heading when slow)."""
    d = math.hypot(bx - ax, by - ay)
    lx, ly = ((bx - ax) / d, (by - ay) / d) if d > 0.0 else (hax, hay)
    s0 = _starboard(hax, hay, lx, ly)
    sb0 = _starboard(hbx, hby, -lx, -ly)
    q0 = _overtaken(vax, vay, vbx, vby, k[K_COS_OT])
    o0 = _overtaken(vbx, vby, vax, vay, k[K_COS_OT])
    h0 = _head_on(vax, vay, vbx, vby, lx, ly, k[K_COS_HO], k[K_COS_AH], 0.0)
    x0 = _crossed(vax, vay, vbx, vby, k[K_COS_CR]) and not (h0 or o0 or q0)
    return s0, o0, q0, h0, x0, sb0


# --- the planner -----------------------------------------------------------------------------------


@njit(cache=True)
def horizon_steps(length, speed, k):
    """(m, dt): the prediction's number of steps and step [s] for the horizon horizon_L L / U."""
    horizon = k[K_HORIZON] * length / speed
    dt = k[K_DT]
    m = int(math.ceil(horizon / dt - 1e-9))
    if m > MAX_STEPS:
        m = MAX_STEPS
        dt = horizon / m
    return max(m, 1), dt


@njit(cache=True)
def predict_own(own, ref, chi_ca, p_fac, los_g, k, dt, out):
    """The own ship's predicted track under behaviour (chi_ca [rad], p_fac) (module docstring):
    ``out[j]`` = (x, y, vx, vy) [m, m/s] at t0 + (j + 1) dt, for j < len(out). ``own`` = (x, y, chi,
    U) at t0 (course over ground [rad], speed [m/s]); ``ref`` the reference vector at t0; ``los_g``
    the LOS gains packed; ``k`` :meth:`SBMPCGains.packed`.

    The guidance of each step, at the step's start: along the reference path (the reference point
    moving on at its velocity at t0) the along-track error x_e gives the speed command
    P clip(U_p - u_at x_e / sqrt(x_e^2 + l_at^2), u_c_min, u_c_max); the course command is LOS's on
    the behaviour's line: the reference path itself for chi_ca = 0, else the line through the own
    ship's position at t0 at the path angle + chi_ca (a course held). Then the course and the speed
    lag their commands (first order, exact discretization) and the position moves on."""
    a_chi = 1.0 - math.exp(-dt / k[K_TCHI])
    a_u = 1.0 - math.exp(-dt / k[K_TU])
    vdx, vdy = ref[REF_XDOT], ref[REF_YDOT]
    u_p = math.sqrt(vdx * vdx + vdy * vdy)
    pi_p = math.atan2(vdy, vdx) if vdx * vdx + vdy * vdy > 1e-12 else ref[REF_PSI]
    cp, sp = math.cos(pi_p), math.sin(pi_p)
    pi_v = pi_p + chi_ca
    cv, sv = math.cos(pi_v), math.sin(pi_v)
    delta, u_at, l_at = los_g[G_DELTA], los_g[G_U_AT], los_g[G_L_AT]
    u_min, u_max = los_g[G_U_MIN], los_g[G_U_MAX]
    x, y, chi, u = own[0], own[1], own[2], own[3]
    x0, y0 = x, y
    for j in range(out.shape[0]):
        tau = j * dt
        ex, ey = x - (ref[REF_X] + vdx * tau), y - (ref[REF_Y] + vdy * tau)
        x_e = cp * ex + sp * ey
        if chi_ca == 0.0:
            y_line = -sp * ex + cp * ey
        else:
            y_line = -sv * (x - x0) + cv * (y - y0)
        chi_c = pi_v - math.atan(y_line / delta)
        u_c = u_p - u_at * x_e / math.sqrt(x_e * x_e + l_at * l_at)
        u_c = p_fac * min(max(u_c, u_min), u_max)
        chi = chi + a_chi * wrap_angle(chi_c - chi)
        u = u + a_u * (u_c - u)
        vx, vy = u * math.cos(chi), u * math.sin(chi)
        x += dt * vx
        y += dt * vy
        out[j, 0], out[j, 1], out[j, 2], out[j, 3] = x, y, vx, vy


@njit(cache=True)
def behaviour_hazard(track, targets, length, speed, chi_ca, k, dt):
    """max_i max_t [C R + kappa mu + kappa_TC mu_TC] (module docstring) of the own ship's predicted
    ``track`` (:func:`predict_own`) against ``targets`` (rows of (x, y, vx, vy, length, the flags of
    :func:`pair_flags` as 0/1) at t0, moving at constant velocity)."""
    d_safe = k[K_DSAFE] * length
    d_close = k[K_DCLOSE] * length
    d_floor = d_safe / D_FLOOR_DIVISOR
    eps = k[K_EPS_U] * speed
    kc = k[K_COLL] / (speed * speed)
    worst = 0.0
    for j in range(track.shape[0]):
        tau = (j + 1) * dt
        x, y, vax, vay = track[j, 0], track[j, 1], track[j, 2], track[j, 3]
        na = math.hypot(vax, vay)
        hax, hay = (vax / na, vay / na) if na > 0.0 else (1.0, 0.0)
        for i in range(targets.shape[0]):
            vbx, vby = targets[i, T_VX], targets[i, T_VY]
            dx = targets[i, T_X] + vbx * tau - x
            dy = targets[i, T_Y] + vby * tau - y
            d = math.hypot(dx, dy)
            cost = 0.0
            dh = max(d - 0.5 * (length + targets[i, T_LEN]), d_floor)
            if dh <= d_safe and dx * (vbx - vax) + dy * (vby - vay) < 0.0:   # near and closing
                rv2 = (vax - vbx) ** 2 + (vay - vby) ** 2
                cost = kc * rv2 * (d_safe / dh) ** k[K_Q] / tau ** k[K_P]
            if 0.0 < d <= d_close:
                lx, ly = dx / d, dy / d
                if dh > d_safe and _passed(vax, vay, vbx, vby, lx, ly, k[K_COS_OT]):
                    if cost > worst:   # passed and clear: no rule applies any more
                        worst = cost
                    continue
                s_t = _starboard(hax, hay, lx, ly)
                if s_t:
                    if (_head_on(vax, vay, vbx, vby, lx, ly, k[K_COS_HO], k[K_COS_AH], eps)
                            or (_crossed(vax, vay, vbx, vby, k[K_COS_CR])
                                and not _overtaken(vax, vay, vbx, vby, k[K_COS_OT]))):
                        cost += k[K_KAPPA]
                # the transitional cost: the target changes sides as COLREGs forbid
                s0 = targets[i, T_S0] > 0.5
                tc = targets[i, T_O0] > 0.5 and s_t != s0
                if targets[i, T_Q0] > 0.5:
                    nb = math.hypot(vbx, vby)
                    if nb > 0.0 and _starboard(vbx / nb, vby / nb, -lx, -ly) != (targets[i, T_SB0] > 0.5):
                        tc = True
                x_tc = targets[i, T_X0] > 0.5 and s0 and s_t and chi_ca > 0.0
                if x_tc or (targets[i, T_H0] > 0.5 and not s0 and s_t):
                    tc = True
                if tc:
                    cost += k[K_KAPPA_TC]
            if cost > worst:
                worst = cost
    return worst


@njit(cache=True)
def control_cost(chi_ca, p_fac, last_chi, last_p, k):
    """K_u (1 - P) + K_du |P - P_last| + K_chi,side chi_ca^2 + K_dchi,side wrap(chi_ca - chi_last)^2;
    port offsets and changes (> 0) with the port weights."""
    dchi = wrap_angle(chi_ca - last_chi)
    h = (k[K_U] * (1.0 - p_fac) + k[K_DU] * abs(p_fac - last_p)
         + (k[K_CHI_P] if chi_ca > 0.0 else k[K_CHI_SB]) * chi_ca * chi_ca
         + (k[K_DCHI_P] if dchi > 0.0 else k[K_DCHI_SB]) * dchi * dchi)
    return h


@njit(cache=True)
def plan_behaviours(own, ref, targets, length, speed, los_g, k, offsets, factors, last_chi, last_p, costs):
    """Score every behaviour (module docstring): ``costs[a, b]`` = H of offset ``offsets[a]`` [rad]
    and factor ``factors[b]``; ``length`` L [m] and ``speed`` U [m/s] the scales; ``last_chi`` [rad],
    ``last_p`` the behaviour held. The rest as
    :func:`predict_own` and :func:`behaviour_hazard`."""
    m, dt = horizon_steps(length, speed, k)
    track = np.empty((m, 4))
    for a in range(offsets.shape[0]):
        for b in range(factors.shape[0]):
            predict_own(own, ref, offsets[a], factors[b], los_g, k, dt, track)
            costs[a, b] = (behaviour_hazard(track, targets, length, speed, offsets[a], k, dt)
                           + control_cost(offsets[a], factors[b], last_chi, last_p, k))


@njit(cache=True)
def best_behaviour(costs):
    """(a, b, H): the first minimum of ``costs`` in row-major order."""
    best_a, best_b, best = 0, 0, costs[0, 0]
    for a in range(costs.shape[0]):
        for b in range(costs.shape[1]):
            if costs[a, b] < best:
                best_a, best_b, best = a, b, costs[a, b]
    return best_a, best_b, best


def guidance_speed(g: np.ndarray, ref: np.ndarray, x_e: float) -> float:
    """The LOS speed command of controllers/los.py step 5: clip(U_p - u_at x_e/sqrt(x_e^2 + l_at^2),
    u_c_min, u_c_max) [m/s] (``g``: LOSGains.as_array())."""
    u_p = math.sqrt(ref[REF_XDOT] ** 2 + ref[REF_YDOT] ** 2)
    u_c = u_p - g[G_U_AT] * x_e / math.sqrt(x_e * x_e + g[G_L_AT] ** 2)
    return min(max(u_c, g[G_U_MIN]), g[G_U_MAX])


def virtual_reference(state, ref, line, factor: float, g: np.ndarray) -> tuple[np.ndarray, float, float, float]:
    """(ref', pi_p, x_e, y_e): the reference vector LOS reads to steer a behaviour (module
    docstring), and the true path's angle and along- and cross-track errors (the diagnostics).
    ``line`` = (x_a, y_a, angle) of the course held (None: the reference path). The point of ref' is
    the vessel's foot on the line (x_e' = 0; on the path: abeam at the true cross-track error), it
    moves along the line at ``factor`` x LOS's speed command; r_d is kept on the path, 0 on a line."""
    pi_p, x_e, y_e = path_errors(state, ref)
    out = np.array(ref, dtype=np.float64, copy=True)
    if line is None:
        angle = pi_p
        c, s = math.cos(angle), math.sin(angle)
        out[REF_X], out[REF_Y] = state[0] + y_e * s, state[1] - y_e * c
    else:
        xa, ya, angle = line
        c, s = math.cos(angle), math.sin(angle)
        along = (state[0] - xa) * c + (state[1] - ya) * s
        out[REF_X], out[REF_Y] = xa + along * c, ya + along * s
        out[REF_R] = 0.0
    speed = factor * guidance_speed(g, ref, x_e)
    out[REF_PSI] = angle
    out[REF_XDOT], out[REF_YDOT] = speed * c, speed * s
    if out.shape[0] > REF_U:
        out[REF_U] = speed
    return out, pi_p, x_e, y_e


class AvoidanceOverLOS:
    """What an avoidance law over the LOS path follower shares (``sbmpc`` here, ``vo`` in
    controllers/vo.py): the traffic (usv_mj/loop/fleet.py's contract) with the COLREGs lock per
    vessel and the nearest vessel's range/DCPA/TCPA, a re-plan every ``gains.replan_period_s``, the
    stand-on duty (module docstring), the chosen behaviour commanded to LOS through the virtual
    reference, the diagnostics and the criterion. A law defines ``name``, ``_choose`` and its own
    ``kernel`` (``return self._kernel()``: usv_mj.core.kernels runs a kernel
    only for the class that defines it). Its gains extend LOSGains with ``replan_period_s``,
    ``d_relevant_L``, ``stand_on`` and ``stand_on_range_L``."""

    diagnostic_fields = DIAGNOSTIC_FIELDS

    @classmethod
    def from_scenario(cls, gains, scenario):
        """The controller for ``scenario``: its path follower as ``kind = "los"`` builds it (the
        vessel's nominal ship, its control period) and the hull's length L."""
        follower = LOSController.from_scenario(gains.los_gains(), scenario)
        return cls(gains, follower, float(scenario.vessel.model.dimensions.L))

    def __init__(self, gains, follower: LOSController, length: float):
        if not (math.isfinite(length) and length > 0):
            raise ScenarioError(f"controller {self.name}: the hull's length must be > 0 m, got {length!r}")
        self._offsets = gains.offsets()     # the law's candidate course offsets [rad] and speed factors
        self._factors = gains.factors()
        self._costs = np.zeros((self._offsets.size, self._factors.size))
        self.gains = gains
        self.follower = follower
        self.length = float(length)
        self.dt = follower.dt
        #: judged by keeping clear: the nearest vessel outside the safety domain (SAFETY_DOMAIN_L L)
        self.criterion = Clearance(min_range_m=SAFETY_DOMAIN_L * self.length)
        self._g = gains.as_array()
        self._cp = ColregsParams().as_array()
        self._replan_every = max(1, int(round(gains.replan_period_s / self.dt)))
        self._diag = np.zeros(len(DIAGNOSTIC_FIELDS))
        self.reset()

    def reset(self) -> None:
        self.follower.reset()
        self._diag[:] = 0.0
        self._diag[D_FACTOR] = 1.0
        self._diag[D_COST:D_TCPA + 1] = math.nan
        self._chi, self._p = 0.0, 1.0
        self._line = None
        self._states = None
        self._index = 0
        self._lengths = None
        self._situation = None
        self._calls = 0
        self._plan_now = False

    def _kernel(self):
        """The path follower's kernel on this controller's diagnostics vector (a single run has no
        traffic: the law is LOS's, and the avoidance's fields keep their reset values)."""
        k = self.follower.kernel()
        return type(k)(k.fn, k.args[:-1] + (self._diag,), k.sync, k.fail)

    # --- the traffic (usv_mj/loop/fleet.py's contract) ---------------------------------------------

    def traffic(self, t, states, index, lengths) -> None:
        """Every vessel's state (rows (x, y, psi, u, v, r)), this vessel's row and every hull's length
        [m], each control period before ``__call__``: the COLREGs lock per vessel is advanced, the
        nearest vessel's range/DCPA/TCPA taken, and a re-plan is due every ``replan_period_s``."""
        states = np.asarray(states, dtype=np.float64)
        n = states.shape[0]
        if self._situation is None or self._situation.shape[0] != n:
            self._situation = np.zeros(n, dtype=np.int64)
        self._states, self._index = states, int(index)
        self._lengths = np.asarray(lengths, dtype=np.float64)
        own = states[index]
        u_own = math.hypot(own[3], own[4])
        best = math.inf
        self._diag[D_RANGE:D_TCPA + 1] = math.nan
        for j in range(n):
            if j == index:
                continue
            g = pair_geometry(own, states[j])
            ref_len = max(self._lengths[index], self._lengths[j])
            self._situation[j] = update_situation(self._situation[j], g[G_RANGE], g[G_BETA], g[G_ALPHA], g[G_TCPA],
                                                  g[G_DCPA], u_own, math.hypot(states[j, 3], states[j, 4]),
                                                  ref_len, self._cp)
            if g[G_RANGE] < best:
                best = g[G_RANGE]
                self._diag[D_RANGE], self._diag[D_DCPA], self._diag[D_TCPA] = g[G_RANGE], g[G_DCPA], g[G_TCPA]
        self._plan_now = self._calls % self._replan_every == 0
        self._calls += 1

    def roles(self) -> dict:
        """{vessel row: "give_way" | "stand_on"} of the locked situations (the others have none)."""
        if self._situation is None:
            return {}
        names = {GIVE_WAY: "give_way", STAND_ON: "stand_on"}
        return {j: names[ROLE_OF[c]] for j, c in enumerate(self._situation) if c != NONE and ROLE_OF[c] in names}

    def _plan(self, state, reference) -> None:
        """Choose the behaviour from the traffic of this control period: the vessels within
        ``d_relevant_L`` (none: the nominal behaviour), the stand-on duty, then ``_choose``."""
        states, index, lengths = self._states, self._index, self._lengths
        length = float(lengths[index]) if lengths is not None else self.length
        relevant = self.gains.d_relevant_L * length
        stand_range = self.gains.stand_on_range_L * length
        rows, codes, stand_on, near, give_way = [], [], False, False, False
        for j in range(states.shape[0]):
            if j == index:
                continue
            b = states[j]
            d = math.hypot(b[0] - state[0], b[1] - state[1])
            role = ROLE_OF[self._situation[j]]
            give_way |= role == GIVE_WAY
            stand_on |= role == STAND_ON
            near |= role == STAND_ON and d <= stand_range
            if d > relevant:
                continue
            vbx, vby = world_velocity(b[2], b[3], b[4])
            rows.append((b[0], b[1], vbx, vby, float(lengths[j]), b[2]))
            codes.append(int(self._situation[j]))
        if not rows:   # nobody near: the nominal behaviour
            self._chi, self._p = 0.0, 1.0
            self._diag[D_COST] = math.nan
            return
        speed = max(math.hypot(reference[REF_XDOT], reference[REF_YDOT]), SPEED_FLOOR)
        duty = bool(self.gains.stand_on and stand_on and not (near or give_way))   # Rule 17 a i
        chi, p, angle, h = self._choose(state, np.asarray(reference, dtype=np.float64), np.array(rows), codes,
                                        length, speed, duty)
        self._line = (float(state[0]), float(state[1]), float(angle))
        self._chi, self._p = float(chi), float(p)
        self._diag[D_COST] = h

    def _choose(self, state, reference, targets, codes, length, speed, duty):
        """(offset [rad], speed factor, the held line's angle [rad], cost) of the law's choice;
        ``targets`` rows of (x, y, vx, vy, length, psi) of the vessels in sight, ``codes`` their
        locked situations (usv_mj.physics.colregs), ``duty``: the stand-on duty holds."""
        raise NotImplementedError

    def __call__(self, t, state, reference):
        if self._states is not None and self._plan_now:
            self._plan(state, reference)
            self._plan_now = False
        diag = self._diag
        if self._chi == 0.0 and self._p == 1.0:   # the nominal behaviour: LOS on the vessel's own reference
            tau_u, tau_r, d = self.follower(t, state, reference)
            diag[:N_LOS] = d
        else:
            line = self._line if self._chi != 0.0 else None
            ref, pi_p, x_e, y_e = virtual_reference(state, reference, line, self._p, self._g)
            tau_u, tau_r, d = self.follower(t, state, ref)
            diag[:N_LOS] = d
            diag[0], diag[1], diag[2] = y_e, x_e, pi_p   # the reference path's errors and angle (chi_d: the command)
        diag[D_OFFSET], diag[D_FACTOR] = self._chi, self._p
        return tau_u, tau_r, diag


@CONTROLLERS.register("sbmpc", gains=SBMPCGains)
class SBMPCController(AvoidanceOverLOS):
    """Scenario-based MPC collision avoidance over the LOS path follower (module docstring)."""

    name = "sbmpc"

    def __init__(self, gains: SBMPCGains, follower: LOSController, length: float):
        self._k = gains.packed()
        super().__init__(gains, follower, length)

    def kernel(self):
        return self._kernel()

    def _choose(self, state, reference, targets, codes, length, speed, duty):
        """Every behaviour scored (:func:`plan_behaviours`), the least cost chosen, or (0, 1) under
        the stand-on duty; the line held at the path angle + the offset."""
        vx, vy = world_velocity(state[2], state[3], state[4])
        u0 = math.hypot(vx, vy)
        chi0 = math.atan2(vy, vx) if u0 > 1e-3 else float(state[2])
        hax, hay = math.cos(chi0), math.sin(chi0)
        rows = []
        for bx, by, vbx, vby, lb, psib in targets:
            nb = math.hypot(vbx, vby)
            hbx, hby = (vbx / nb, vby / nb) if nb > 1e-3 else (math.cos(psib), math.sin(psib))
            flags = pair_flags(state[0], state[1], vx, vy, hax, hay, bx, by, vbx, vby, hbx, hby, self._k)
            rows.append((bx, by, vbx, vby, lb) + tuple(float(f) for f in flags))
        plan_behaviours(np.array([state[0], state[1], chi0, u0]), reference, np.array(rows, dtype=np.float64),
                        length, speed, self._g, self._k, self._offsets, self._factors, self._chi, self._p,
                        self._costs)
        if duty:
            a, b = int(np.flatnonzero(self._offsets == 0.0)[0]), int(np.flatnonzero(self._factors == 1.0)[0])
            h = float(self._costs[a, b])
        else:
            a, b, h = best_behaviour(self._costs)
        pi_p = path_errors(state, reference)[0]
        return self._offsets[a], self._factors[b], pi_p + self._offsets[a], h
