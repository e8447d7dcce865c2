"""Velocity obstacles with COLREGs constraints (Kuwata et al. 2014) over the LOS path follower.

The second built-in collision-avoidance law (docs/encounters.md §5.1): ``[controller] kind = "vo"``.
As ``sbmpc`` (controllers/sbmpc.py, whose machinery it shares: :class:`AvoidanceOverLOS`, the
traffic, the COLREGs lock, the stand-on duty, the virtual reference that commands LOS, the
diagnostics and the clearance criterion) it steers the vessel's own reference with the LOS
controller of controllers/los.py and, every ``replan_period_s``, chooses a velocity; unlike it, it
predicts nothing beyond the velocities of the moment: one step in velocity space, no horizon, no
dynamics (research note §5).

Sources: Y. Kuwata, M. T. Wolf, D. Zarzhitsky and T. L. Huntsberger, "Safe maritime autonomous
navigation with COLREGS, using velocity obstacles", IEEE J. Oceanic Eng. 39(1), 2014, doi
10.1109/JOE.2013.2254214 (only the IROS 2011 version's abstract was readable); the constraint and
the costs as the public implementations write them (research note /work/notes/encounters-research.md
§5: AutoSea ``asv_ctrl_vo.cpp``, NTNU colav-sim ``kuwata_vo.py``). ENU throughout.

**The candidates**: the course chi_p + o, o in {0, -5, 5, -10, 10, ..., -120, 120} deg
(``heading_step_deg``, ``heading_span_deg``), at the speed f u_c, f in {1, 0.75, 0.5, 0.25, 0}
(``n_speeds``; u_c LOS's speed command). The preferred velocity v_pref is (o, f) = (0, 1): the course
chi_p = pi_p - atan(y_e / (lookahead_L L)), LOS's steering law towards the vessel's path with a
lookahead of 10 L *(here: the path follower's own lookahead, 1.5 L on the paper hull, points back at
the path so steeply once the vessel has given way that the least deviation from it is to slow down:
in test_fleet's head-on both vessels crept at a quarter speed, 22 deg off their paths)*.

**The velocity obstacle** of a vessel B (position p_B, velocity v_B, length L_B) for the own ship A:
the velocities v whose relative motion w = v - v_B brings the centres within r = d_safe + (L_A +
L_B)/2 (``d_safe_L`` own lengths hull to hull, as sbmpc's) within ``t_max_L`` L/U while closing:
with d = p_B - p_A, d.w > 0 and |d - w t*| < r at t* = clip(d.w / |w|^2, 0, t_max) (a truncated
cone; a pair already inside r may still open).

**The COLREGs constraint** (Kuwata; AutoSea's comment "COLREGs applicable if the following relation
holds"): towards a vessel whose locked situation (usv_mj.physics.colregs) makes the own ship give
way (head-on, crossing with it on starboard, overtaking it) and with which a collision is predicted
at v_pref (DCPA < r, 0 <= TCPA < t_max; *here v_pref, the sources the velocity of the moment: once
both have turned away no collision is predicted at it, the constraint lifts, and in the head-on a
turn to port came back among the cheapest*), a candidate violates the rules when
it does not move away, (p_A - p_B).w < 0, and passes on the wrong side, cross(p_A - p_B, w) < 0
(ENU: the target would pass on the own ship's starboard side; AutoSea's sign).

*The cone's horizon is t_max = 12 L/U* (40 s for the paper hull at 0.6 m/s), not the sources' 60 s
(30 L/U here): with 30 L/U a head-on target is in the cone from about 50 L, before the COLREGs lock
engages at stage 2 (25 L; usv_mj.physics.colregs); with no constraint yet both exits of the cone
cost alike, the choice flipped between -15 and +15 deg at every re-plan, the heading was 25 deg
off at 25 L, the lock read the head-on as a crossing from port (the own ship standing on) and the
own ship met its target 0.62 m apart (Imazu situation 1, calm water, docs/encounters.md §6). With
12 L/U a head-on enters the cone at about 24 L, after the lock.

**The cost** of a candidate (minimised; the first minimum in the order above, so a tie goes to the
smaller change, starboard first): |v - v_pref|^2 / U^2 (Q = I, as colav-sim) + w_vo for a candidate
in any vessel's VO + w_colregs for one that violates the constraint towards any vessel (colav-sim:
1000 and 100). Under the stand-on duty the choice is (0, 1). The choice is commanded as sbmpc's:
(0, f) on the vessel's own path at f u_c, (o != 0, f) as the course chi_p + o held (LOS on the
line through the vessel at that angle); (0, 1): LOS alone, the vessel's reference unchanged, so a
single run is ``los`` bit for bit.

Diagnostics: sbmpc's (``course_offset`` = o, relative to chi_p; ``speed_factor`` = f;
``avoidance_cost`` the chosen candidate's cost).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numba import njit

from usv_mj.controllers.los import LOSGains, path_errors
from usv_mj.controllers.sbmpc import AvoidanceOverLOS, OverLOSGains, guidance_speed
from usv_mj.core.errors import ScenarioError
from usv_mj.core.registry import CONTROLLERS
from usv_mj.physics.colregs import CROSSING_GIVE_WAY, HEAD_ON, OVERTAKING
from usv_mj.physics.encounters import tcpa_dcpa, world_velocity


@dataclass(frozen=True)
class VOGains(OverLOSGains):
    """The path follower's gains (every key of ``kind = "los"``; crab compensation off as sbmpc's),
    then the velocity obstacle's (module docstring). L: the own hull's length [m]; U: the
    reference's path speed [m/s]."""

    crab_compensation: bool = False       # LOS's, off here as in sbmpc (controllers/sbmpc.py, "The path follower")
    heading_span_deg: float = 120.0       # [deg] candidate courses up to this either side of LOS's (AutoSea +-120)
    heading_step_deg: float = 5.0         # [deg] their spacing (AutoSea about 2.4, colav-sim 2.5)
    n_speeds: int = 5                     # candidate speeds: 1, ..., 0 times LOS's speed command, evenly (>= 2)
    t_max_L: float = 12.0                 # [L/U] the cone's time horizon (module docstring; the sources 60 s: 30 L/U here)
    d_safe_L: float = 4.0                 # [L] the safety distance, hull to hull (sbmpc's)
    lookahead_L: float = 10.0             # [L] the lookahead of the preferred course chi_p (module docstring)
    w_vo: float = 1000.0                  # [-] cost of a candidate inside a velocity obstacle (colav-sim)
    w_colregs: float = 100.0              # [-] cost of one that breaks the COLREGs constraint (colav-sim)
    replan_period_s: float = 1.0          # [s] a velocity is chosen this often (Kuwata: 1 Hz)
    d_relevant_L: float = 50.0            # [L] vessels farther than this are ignored
    stand_on: bool = True                 # a stand-on vessel keeps course and speed (Rule 17 a i) while ...
    stand_on_range_L: float = 7.5         # [L] ... the target is farther than this (stage 3)

    def __post_init__(self) -> None:
        self.los_gains()
        own = [f.name for f in fields(VOGains) if f.name not in {g.name for g in fields(LOSGains)}]
        for name in own:
            v = getattr(self, name)
            if name == "stand_on":
                if not isinstance(v, bool):
                    raise ScenarioError(f"controller.stand_on must be true or false, got {v!r}")
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ScenarioError(f"controller.{name} must be a finite number >= 0, got {v!r}")
        for name in ("heading_step_deg", "t_max_L", "d_safe_L", "lookahead_L", "replan_period_s", "d_relevant_L"):
            if not getattr(self, name) > 0:
                raise ScenarioError(f"controller.{name} must be > 0, got {getattr(self, name)!r}")
        if not 0 < self.heading_span_deg <= 180 or self.heading_step_deg > self.heading_span_deg:
            raise ScenarioError(f"controller.heading_span_deg must be in (0, 180] and at least heading_step_deg, "
                                f"got {self.heading_span_deg!r} (step {self.heading_step_deg!r})")
        if not (isinstance(self.n_speeds, int) and self.n_speeds >= 2):
            raise ScenarioError(f"controller.n_speeds must be an integer >= 2, got {self.n_speeds!r}")

    def offsets(self) -> np.ndarray:
        """The candidate course offsets [rad]: 0, -step, +step, -2 step, ... (smaller first, starboard first)."""
        n = int(math.floor(self.heading_span_deg / self.heading_step_deg + 1e-9))
        out = [0.0]
        for k in range(1, n + 1):
            out += [-k * self.heading_step_deg, k * self.heading_step_deg]
        return np.radians(np.array(out, dtype=np.float64))

    def factors(self) -> np.ndarray:
        """The candidate speed factors: 1, ..., 0 evenly."""
        return np.linspace(1.0, 0.0, self.n_speeds)


@njit(cache=True)
def in_velocity_obstacle(dx, dy, wx, wy, r, t_max):
    """True when the relative velocity w = v - v_B [m/s] of a vessel at d = p_B - p_A [m] is closing
    (d.w > 0) and brings the centres within ``r`` [m] within ``t_max`` [s]."""
    dw = dx * wx + dy * wy
    if dw <= 0.0:
        return False
    t = min(dw / (wx * wx + wy * wy), t_max)
    return math.hypot(dx - wx * t, dy - wy * t) < r


@njit(cache=True)
def breaks_colregs(dx, dy, wx, wy):
    """Kuwata's constraint (AutoSea's signs, ENU): with d = p_B - p_A and w = v - v_B, the candidate
    does not move away, (p_A - p_B).w < 0, and passes B on the wrong side, cross(p_A - p_B, w) < 0."""
    ax, ay = -dx, -dy
    return ax * wx + ay * wy < 0.0 and ax * wy - ay * wx < 0.0


@njit(cache=True)
def vo_costs(ax, ay, vax, vay, chi_p, u_c, speed, offsets, factors, targets, radii, rules, t_max, w_vo, w_col,
             costs):
    """``costs[a, b]`` of the candidate course chi_p + offsets[a] at factors[b] u_c (module
    docstring); the own ship at (ax, ay) moving at (vax, vay) [m/s]; ``targets`` rows of (x, y, vx, vy);
    ``radii`` the cones' radii [m]; ``rules`` 1 where the own ship gives way by COLREGs; ``speed`` U
    [m/s] the scale of the velocity error; ``t_max`` [s]."""
    n = targets.shape[0]
    px, py = u_c * math.cos(chi_p), u_c * math.sin(chi_p)
    constrained = np.zeros(n, dtype=np.bool_)
    for i in range(n):   # the constraint applies where LOS alone (v_pref) would lead into a collision
        dx, dy = targets[i, 0] - ax, targets[i, 1] - ay
        t, d = tcpa_dcpa(dx, dy, targets[i, 2] - px, targets[i, 3] - py)
        constrained[i] = rules[i] > 0 and d < radii[i] and 0.0 <= t < t_max
    for a in range(offsets.shape[0]):
        c, s = math.cos(chi_p + offsets[a]), math.sin(chi_p + offsets[a])
        for b in range(factors.shape[0]):
            vx, vy = factors[b] * u_c * c, factors[b] * u_c * s
            cost = ((vx - px) ** 2 + (vy - py) ** 2) / (speed * speed)
            hit, broke = False, False
            for i in range(n):
                dx, dy = targets[i, 0] - ax, targets[i, 1] - ay
                wx, wy = vx - targets[i, 2], vy - targets[i, 3]
                hit = hit or in_velocity_obstacle(dx, dy, wx, wy, radii[i], t_max)
                broke = broke or (constrained[i] and breaks_colregs(dx, dy, wx, wy))
            costs[a, b] = cost + (w_vo if hit else 0.0) + (w_col if broke else 0.0)


@CONTROLLERS.register("vo", gains=VOGains)
class VOController(AvoidanceOverLOS):
    """Velocity obstacles with COLREGs constraints over the LOS path follower (module docstring)."""

    name = "vo"

    def kernel(self):
        return self._kernel()

    def _choose(self, state, reference, targets, codes, length, speed, duty):
        """The least-cost candidate (:func:`vo_costs`), or (0, 1) under the stand-on duty; the line
        held at chi_p + the offset."""
        g = self.gains
        pi_p, x_e, y_e = path_errors(state, reference)
        chi_p = pi_p - math.atan(y_e / (g.lookahead_L * length))
        u_c = guidance_speed(self._g, reference, x_e)
        vax, vay = world_velocity(state[2], state[3], state[4])
        radii = g.d_safe_L * length + 0.5 * (length + targets[:, 4])
        rules = np.array([c in (HEAD_ON, CROSSING_GIVE_WAY, OVERTAKING) for c in codes], dtype=np.float64)
        vo_costs(float(state[0]), float(state[1]), vax, vay, chi_p, u_c, speed, self._offsets, self._factors,
                 np.ascontiguousarray(targets[:, :4]), radii, rules, g.t_max_L * length / speed, g.w_vo,
                 g.w_colregs, self._costs)
        if duty:
            a, b = 0, 0    # offset 0, factor 1: the first of each
        else:
            k = int(np.argmin(self._costs))   # the first minimum, row-major: the order of the candidates
            a, b = divmod(k, self._costs.shape[1])
        return self._offsets[a], self._factors[b], chi_p + self._offsets[a], float(self._costs[a, b])
