"""Vessels in traffic, stepped one decision at a time: the core of ``usv_mj/Encounter-v0`` and of the
PettingZoo environment (issue 35, item 6).

:func:`traffic_situation` turns a situation into a scenario with ``[[vessels]]``: an Imazu case
(1-22, :func:`usv_mj.scenario.imazu.imazu_situation`, scaled to the own vessel's length L and speed U:
R = k_R L, T = R / U) or a scenario (a file or a :class:`usv_mj.scenario.spec.Scenario`) with
``[[vessels]]``. :class:`Traffic` builds it once (:func:`usv_mj.builder.build_fleet`: each vessel's
controller, reference, quantizers and actuators; one fleet plant, MuJoCo or analytic) and steps it:
the vessels that are **agents** take an action, the others follow their own controllers, each
vessel's step composed as the fleet loop composes it (:mod:`usv_mj.loop.fleet`: the reference at t,
the controller (after its ``traffic`` method, when it has one) and the one control step
:class:`usv_mj.loop.step.ControlStep`; an agent's action takes the controller's place, through its
own control step with the action bounds of the Track task: clip, quantize (Eq. 3), actuators), then
one plant step for all (``plant.step_vessels``).

Per agent (a vessel index i):

- **Goal.** An Imazu case: the own ship's 2 R ahead (reached at 2 T on its straight course; the
  episode lasts 3 T), every target's as far beyond the collision point as it starts before it. A
  scenario: the vessel's reference position at 2/3 of the episode. Or the ``goals`` given.
- **Observation** (physical units, :data:`OWN_FIELDS` then :data:`TARGET_FIELDS` per slot): its
  surge, sway and yaw rate and the goal in its body frame; then ``max_targets`` slots of the other
  vessels nearest first (within ``sensor_range``; an empty slot is all zeros): a mask (1: a vessel is
  in the slot), the vessel's position and velocity over ground relative to the agent in the
  agent's body frame (x forward, y to port: R(psi)^T (p_j - p_i), R(psi)^T (v_j - v_i)), the range,
  the sine and cosine of the relative bearing (clockwise from the bow, + starboard:
  :mod:`usv_mj.physics.encounters`), DCPA and TCPA (the same module's kernels,
  :func:`usv_mj.physics.encounters.pair_matrix_into`). :meth:`Traffic.scales` divides them into the
  environments' scaled observation: lengths by R, speeds by U, times by T, the yaw rate by U / L.
- **Collision**: a contact force above :data:`usv_mj.loop.fleet.CONTACT_EVENT_N` between two hulls
  on MuJoCo (``plant.contacts()``); the hulls' collision footprints (the geoms MuJoCo collides, the
  analytic clearance's polygon: :func:`usv_mj.scene.hull.hull_footprint`) overlapping on the
  analytic plant (:func:`usv_mj.obstacles.footprint_kernels.convex_signed_distance` <= 0).
- **Reward** per decision: progress (d_before - d_after) / d_0 toward the goal (sums to about 1 from
  the start to the goal), minus ``domain_penalty`` [1/s] x the decision's duration x the depth
  (1 - range / D) of every other vessel inside the agent's safety domain D (a circle of
  :data:`usv_mj.record.encounters.SAFETY_DOMAIN_L` own lengths, centre to centre), plus
  ``goal_reward`` at the goal and minus ``collision_penalty`` at a collision.
- **End**: terminated on ``"collision"`` (the other vessel named), ``"goal"`` (within
  ``goal_radius`` of it), ``"diverged"`` (its state left the scenario's limits, the distance being to
  its goal, or a hydrodynamic callback failed); truncated at the time limit (``"time_limit"``).
  Within a decision (``action_repeat`` control periods) these are checked every control period
  and kept; the decision stops early once every agent has ended.

A vessel that is no agent, or an agent that has ended, keeps its step: the others its controller,
an ended agent a zero command through its control step (it drifts, still a hull in the sea).
Everything is deterministic: the situation is fixed, and only the draw among several situations
uses the environments' random generator. An Imazu case is built on the ``paper`` preset (its
scenario tables, the paper's disturbance of scale 1e-4 included: ``overrides={"disturbance":
{"scale": 0.0}}`` removes it); its targets keep course and speed by the LOS controller
(``controllers/los.py``, whose speed set-point stops at ``u_c_max`` = 1.5 m/s by default: a faster
``speed`` needs ``target_controller={"kind": "los", "u_c_max": ...}``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import shapely

from usv_mj.builder import build_fleet, make_actuators, make_quantizers
from usv_mj.envs.tasks import DEFAULT_FORCE, action_bounds
from usv_mj.loop.fleet import CONTACT_EVENT_N
from usv_mj.loop.simulate import make_reference
from usv_mj.loop.step import C_F_U, C_Q_U, C_TAU_U, ControlStep
from usv_mj.obstacles.footprint_kernels import convex_signed_distance
from usv_mj.physics.encounters import G_BETA, G_DCPA, G_RANGE, G_TCPA, N_GEOMETRY, pair_matrix_into
from usv_mj.physics.limits import within_limits
from usv_mj.plants.mujoco_callback import HydrodynamicCallbackError
from usv_mj.record.encounters import SAFETY_DOMAIN_L
from usv_mj.record.run_record import N_CORE
from usv_mj.scenario.imazu import IMAZU_CASES, K_R_DEFAULT, imazu_situation
from usv_mj.scenario.spec import Scenario, load_scenario, merge_tables
from usv_mj.scene.hull import hull_footprint, vessel_collision_geoms

#: an agent's own block of the observation (physical units: m/s, rad/s, m)
OWN_FIELDS = ("u", "v", "r", "goal_x", "goal_y")
#: one target slot of the observation (m, m/s, -, s)
TARGET_FIELDS = ("mask", "x", "y", "vx", "vy", "range", "sin_bearing", "cos_bearing", "dcpa", "tcpa")
N_OWN, N_TARGET = len(OWN_FIELDS), len(TARGET_FIELDS)
#: the scaled observation is clipped to +-OBS_BOUND (the mask, sine and cosine to their own [0, 1], [-1, 1])
OBS_BOUND = 10.0
#: the share of the episode at which a vessel's goal is its reference's position (Imazu: 2 T of 3 T)
GOAL_AT = 2.0 / 3.0
#: the Imazu episodes last this many T = R / U (the goal at 2 R is reached at 2 T on a straight course)
IMAZU_DURATION_T = 3.0
#: ``situation="imazu"``: every case, one drawn per episode
ALL_IMAZU = "imazu"
END_KINDS = ("collision", "goal", "diverged", "time_limit")
FOOTPRINT_RESOLUTION = 8


@dataclass(frozen=True)
class TrafficSituation:
    """A situation ready to build: the scenario with ``[[vessels]]`` and what the episode measures by.

    Attributes
    ----------
    name: "imazu-05", or the scenario's source.
    scenario: the scenario (each vessel's in ``scenario.vessels``; the own ship first for Imazu).
    goals: (N, 2) each vessel's goal [m].
    length_scale: R [m] (k_R own lengths); speed_scale: U [m/s]; time_scale: T = R / U [s].
    imazu: the :class:`usv_mj.scenario.imazu.ImazuSituation` (None for a scenario).
    """

    name: str
    scenario: Scenario
    goals: np.ndarray
    length_scale: float
    speed_scale: float
    time_scale: float
    imazu: object = None

    @property
    def names(self) -> tuple:
        return tuple(v.name for v in self.scenario.vessels)

    @property
    def own_index(self) -> int:
        return next(i for i, v in enumerate(self.scenario.vessels) if v.own_ship)


def _positive(where: str, name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value > 0):
        raise ValueError(f"{where}: {name} must be a finite number > 0, got {value!r}")
    return float(value)


def _controller_table(target_controller, where: str):
    if target_controller is None:
        return None
    if isinstance(target_controller, str):
        return {"kind": target_controller}
    if isinstance(target_controller, dict) and isinstance(target_controller.get("kind"), str):
        return dict(target_controller)
    raise ValueError(f"{where}: target_controller must be a controller kind (`usv-mj kinds controller`) or a "
                     f"table with its kind and gains, got {target_controller!r}")


def traffic_situation(situation, *, vessel: str | None = "otter", target_vessel: str | None = None,
                      speed: float = 1.0, k_R: float = K_R_DEFAULT, plant: str | None = None,
                      control_period: float | None = None, substeps: int | None = None,
                      duration: float | None = None, target_controller=None, goals=None, overrides=None,
                      where: str = "traffic") -> TrafficSituation:
    """The :class:`TrafficSituation` of ``situation``: an Imazu case (an int 1..22) placed for an own
    ``vessel`` (a vessel kind) at ``speed`` U [m/s] with R = ``k_R`` L, every target of
    ``target_vessel`` (default: the own's kind) keeping course and speed, or steered by
    ``target_controller`` (a controller kind or table) along its course; or a scenario with
    ``[[vessels]]`` (a :class:`Scenario` or a scenario file's path), whose vessels keep their own
    steering. ``plant`` ("mujoco" / "analytic"), ``control_period`` [s], ``substeps`` and
    ``duration`` [s] override the situation's (Imazu defaults: MuJoCo, 0.01 s, 10, 3 T);
    ``overrides``: scenario tables merged over the base (an Imazu case's: e.g. ``{"sea": ...}``);
    ``goals``: {vessel name: (x, y)} [m] instead of each reference's position at 2/3 of the episode."""
    if control_period is not None:
        control_period = _positive(where, "control_period", control_period)
    if duration is not None:
        duration = _positive(where, "duration", duration)
    if substeps is not None and (isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1):
        raise ValueError(f"{where}: substeps must be an integer >= 1, got {substeps!r}")
    if plant is not None and not isinstance(plant, str):
        raise ValueError(f"{where}: plant must be a plant kind ('mujoco' or 'analytic'), got {plant!r}")
    if overrides is not None and not isinstance(overrides, dict):
        raise ValueError(f"{where}: overrides must be a dict of scenario tables, got {overrides!r}")
    controller = _controller_table(target_controller, where)
    imazu = None
    if isinstance(situation, (int, np.integer)) and not isinstance(situation, bool):
        case = int(situation)
        if case not in IMAZU_CASES:
            raise ValueError(f"{where}: situation must be an Imazu case 1..22, a scenario with [[vessels]] or its "
                             f"file, got {situation!r}")
        speed = _positive(where, "speed", speed)
        k_R = _positive(where, "k_R", k_R)
        own_kind = vessel or "paper"
        merged = merge_tables({"control_period": control_period or 0.01, "vessel": {"kind": own_kind},
                               "plant": {"kind": plant or "mujoco", "substeps": substeps or 10}}, overrides or {})
        own_L = load_scenario(preset="paper", overrides=merged).vessel.model.dimensions.L
        imazu = imazu_situation(case, own_L, speed, k_R=k_R)
        tables = []
        for i, v in enumerate(imazu.vessels):
            entry = {"name": v.name, "own_ship": i == 0, "steer": "keep", "speed": v.speed,
                     "initial": {"eta": list(v.eta), "nu": list(v.nu)}}
            if i > 0:
                if target_vessel is not None:
                    entry["vessel"] = {"kind": target_vessel}
                if controller is not None:
                    entry["controller"] = controller
            tables.append(entry)
        merged["duration"] = duration or IMAZU_DURATION_T * imazu.T_cpa_s
        merged["vessels"] = tables
        scenario = load_scenario(preset="paper", overrides=merged)
        name = f"imazu-{case:02d}"
        R, U = imazu.R_m, speed
    else:
        if isinstance(situation, (str, Path)):
            scenario = load_scenario(situation)
        elif isinstance(situation, Scenario):
            scenario = situation
        else:
            raise ValueError(f"{where}: situation must be an Imazu case 1..22, a scenario with [[vessels]] or its "
                             f"file, got {situation!r}")
        if not scenario.vessels:
            raise ValueError(f"{where}: the scenario {scenario.source or '<scenario>'} has no [[vessels]] (a traffic "
                             f"situation needs the own ship and at least one other vessel)")
        if controller is not None or target_vessel is not None:
            raise ValueError(f"{where}: target_controller and target_vessel place an Imazu case's targets; a "
                             f"scenario's vessels take theirs from their [[vessels]] tables")
        over = dict(overrides or {})
        if plant is not None:
            over["plant"] = {**over.get("plant", {}), "kind": plant}
        if substeps is not None:
            over["plant"] = {**over.get("plant", {}), "substeps": substeps}
        if control_period is not None:
            over["control_period"] = control_period
        if duration is not None:
            over["duration"] = duration
        if over:
            scenario = scenario.with_overrides(over)
        own = next(v for v in scenario.vessels if v.own_ship)
        L = own.scenario.vessel.model.dimensions.L
        U = float(getattr(own.scenario.trajectory, "speed", 0.0) or 0.0)
        if not (math.isfinite(U) and U > 0):
            U = float(np.hypot(*own.scenario.initial.nu[:2])) or 1.0
        R = _positive(where, "k_R", k_R) * L
        name = scenario.source or "scenario"
    if len(scenario.vessels) < 2:
        raise ValueError(f"{where}: a traffic situation needs at least two vessels, {name} has "
                         f"{len(scenario.vessels)}")
    if imazu is not None:   # the own ship's goal 2 R ahead, every target's as far beyond the collision point
        cx, cy = imazu.collision_point
        fixed = {v.name: (2.0 * cx - v.eta[0], 2.0 * cy - v.eta[1]) for v in imazu.vessels}
        goals = {**fixed, **dict(goals or {})}
    return TrafficSituation(name, scenario, _goals(scenario, goals, where), R, U, R / U, imazu)


def _goals(scenario: Scenario, goals, where: str) -> np.ndarray:
    out = np.empty((len(scenario.vessels), 2))
    given = dict(goals or {})
    names = [v.name for v in scenario.vessels]
    unknown = sorted(set(given) - set(names))
    if unknown:
        raise ValueError(f"{where}: goals for unknown vessels {unknown}; the vessels: {', '.join(names)}")
    for i, v in enumerate(scenario.vessels):
        if v.name in given:
            g = np.asarray(given[v.name], dtype=float).reshape(-1)
            if g.shape != (2,) or not np.all(np.isfinite(g)):
                raise ValueError(f"{where}: goals[{v.name!r}] must be (x, y) [m], got {given[v.name]!r}")
            out[i] = g
        else:
            out[i] = make_reference(v.scenario, scenario.duration).evaluate(GOAL_AT * scenario.duration)[:2]
    return out


@dataclass
class StepResult:
    """What one decision did to each agent (index -> value)."""

    rewards: dict = field(default_factory=dict)
    ended: dict = field(default_factory=dict)        # index -> (kind, reason) of the agents that ended in it


class Traffic:
    """The vessels of a :class:`TrafficSituation`, built once and stepped one decision at a time
    (module docstring). ``agents``: the indices of the vessels that act; the others follow their
    controllers.

    Options: ``action_repeat`` (control periods per decision), ``quantize`` (Eq. 3 on the agents'
    actions), ``max_surge_force`` / ``max_yaw_moment`` (the action bounds of an unlimited channel,
    as the Track task's), ``max_targets`` (observation slots), ``sensor_range`` [m] (default 3 R),
    ``goal_radius`` [m] (default 2 own lengths), ``domain_penalty`` [1/s], ``goal_reward``,
    ``collision_penalty``.
    """

    def __init__(self, situation: TrafficSituation, agents, *, action_repeat: int = 10, quantize: bool = True,
                 max_surge_force: float = DEFAULT_FORCE, max_yaw_moment: float = DEFAULT_FORCE, max_targets: int = 3,
                 sensor_range: float | None = None, goal_radius: float | None = None, domain_penalty: float = 0.1,
                 goal_reward: float = 1.0, collision_penalty: float = 5.0, where: str = "traffic"):
        if isinstance(action_repeat, bool) or not isinstance(action_repeat, int) or action_repeat < 1:
            raise ValueError(f"{where}: action_repeat must be an integer >= 1, got {action_repeat!r}")
        if isinstance(max_targets, bool) or not isinstance(max_targets, int) or max_targets < 1:
            raise ValueError(f"{where}: max_targets must be an integer >= 1, got {max_targets!r}")
        for name, value in (("domain_penalty", domain_penalty), ("goal_reward", goal_reward),
                            ("collision_penalty", collision_penalty)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{where}: {name} must be a finite number >= 0, got {value!r}")
        self.situation = situation
        self.scenario = sc = situation.scenario
        self.names = situation.names
        self.n = n = len(self.names)
        self.agents = tuple(int(i) for i in agents)
        self.is_agent = np.zeros(n, dtype=bool)
        self.is_agent[list(self.agents)] = True
        self.action_repeat = action_repeat
        self.quantize = bool(quantize)
        self.max_targets = max_targets
        self.domain_penalty, self.goal_reward, self.collision_penalty = (float(domain_penalty), float(goal_reward),
                                                                         float(collision_penalty))
        self.dt = sc.control_period
        self.decision_period = self.dt * action_repeat
        self.n_steps = int(round(sc.duration / self.dt))   # control periods in an episode
        self.time_limit = self.n_steps * self.dt
        self.parts = build_fleet(sc)
        try:
            self.plant = self.parts.plant
            self.mujoco = hasattr(self.plant, "model")
            vessels = self.parts.vessels
            self.lengths = np.array([v.scenario.vessel.model.dimensions.L for v in vessels])
            own_L = self.lengths[situation.own_index]
            self.sensor_range = 3.0 * situation.length_scale if sensor_range is None else \
                _positive(where, "sensor_range", sensor_range)
            self.goal_radius = 2.0 * own_L if goal_radius is None else _positive(where, "goal_radius", goal_radius)
            self.domains = SAFETY_DOMAIN_L * self.lengths
            self.goals = situation.goals
            # each vessel's control step: a controller's as the fleet loop makes it (no bounds), an agent's
            # as the Track task's (clip to the action bounds, quantize, the vessel's actuators)
            self.bounds, self.steps = [], []
            for i, v in enumerate(vessels):
                if self.is_agent[i]:
                    lo, hi = action_bounds(v.scenario, max_surge_force, max_yaw_moment)
                    self.bounds.append((lo, hi))
                    step = ControlStep(make_quantizers(v.scenario), make_actuators(v.scenario),
                                       (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])))
                    step.quantize = self.quantize   # the option wins over [quantizer], as the Track task's
                    self.steps.append(step)
                else:
                    self.bounds.append(None)
                    self.steps.append(ControlStep(v.quantizers, v.actuators))
            self.seers = [getattr(v.controller, "traffic", None) for v in vessels]
            self.rows = np.zeros((n, N_CORE))
            self.pair_index = {}
            for i in range(n):
                for j in range(i + 1, n):
                    self.pair_index[(i, j)] = i * n - i * (i + 1) // 2 + (j - i - 1)
            self._footprints = [self._footprint(v.scenario) for v in vessels]
            self._reach = np.array([float(np.max(np.hypot(f[:, 0], f[:, 1]))) for f in self._footprints])
        except BaseException:
            self.parts.close()
            raise
        self.geometry = np.empty((n, n, N_GEOMETRY))
        self._scales = [self._make_scales(i) for i in range(n)]
        self._bounds_scaled = self._make_bounds()
        self.k = 0
        self.X = None

    @staticmethod
    def _footprint(scenario) -> np.ndarray:
        poly = shapely.orient_polygons(hull_footprint(FOOTPRINT_RESOLUTION,
                                                      vessel_collision_geoms(scenario.vessel.model.dimensions)))
        return np.ascontiguousarray(np.asarray(poly.exterior.coords)[:-1], dtype=np.float64)

    # --- episode ------------------------------------------------------------------------------------

    def reset(self) -> None:
        """Every vessel at its start, at t = 0; controllers, quantizers and actuators at rest."""
        for i, v in enumerate(self.parts.vessels):
            self.plant.reset_vessel(i, v.scenario.initial.eta, v.scenario.initial.nu, 0.0)
            v.controller.reset()
            self.steps[i].reset()
        self.rows[:] = 0.0
        self.k = 0
        self.X = np.array(self.plant.states)
        self.done = np.zeros(self.n, dtype=bool)   # an agent that ended
        self.end = {}                              # index -> (kind, reason)
        self.d0 = self.goal_distances()
        self._update_geometry()

    @property
    def t(self) -> float:
        return self.k * self.dt

    def goal_distances(self) -> np.ndarray:
        return np.hypot(self.X[:, 0] - self.goals[:, 0], self.X[:, 1] - self.goals[:, 1])

    def _update_geometry(self) -> None:
        pair_matrix_into(np.ascontiguousarray(self.X), self.geometry)

    # --- one decision -------------------------------------------------------------------------------

    def step(self, actions: dict) -> StepResult:
        """One decision: ``actions`` {agent index: (tau_u [N], tau_r [N m])} (an ended agent's, or a
        missing one's, is 0) held over ``action_repeat`` control periods (module docstring)."""
        live = [i for i in self.agents if not self.done[i]]
        d_before = self.goal_distances()
        depth = np.zeros(self.n)
        latched = {}
        periods = 0
        for _ in range(self.action_repeat):
            if self.k >= self.n_steps:
                break
            problem = self._advance(actions)
            periods += 1
            if problem is not None:   # the fleet cannot go on: every live agent ends with it
                for i in live:
                    latched.setdefault(i, ("diverged", problem))
                break
            self._update_geometry()
            rng = self.geometry[:, :, G_RANGE]
            for i in live:
                inside = np.clip(1.0 - rng[i] / self.domains[i], 0.0, None)
                inside[i] = 0.0
                depth[i] += float(np.nansum(inside)) * self.dt
            for i, kind, reason in self._ends(live):
                latched.setdefault(i, (kind, reason))
            if all(i in latched for i in live):
                break
        d_after = self.goal_distances()
        result = StepResult()
        truncate = self.k >= self.n_steps
        for i in live:
            r = (d_before[i] - d_after[i]) / self.d0[i] if self.d0[i] > 0 else 0.0
            r = (r if math.isfinite(r) else 0.0) - self.domain_penalty * depth[i]
            end = latched.get(i)
            if end is not None:
                if end[0] == "goal":
                    r += self.goal_reward
                elif end[0] == "collision":
                    r -= self.collision_penalty
            elif truncate:
                end = ("time_limit", f"the time limit of {self.time_limit:.6g} s")
            if end is not None:
                self.done[i] = True
                self.end[i] = end
                result.ended[i] = end
            result.rewards[i] = float(r)
        return result

    def _advance(self, actions: dict):
        """One control period of every vessel; a sentence when the fleet cannot go on, else None."""
        t = self.k * self.dt
        X, F, vessels = self.X, np.zeros((self.n, 2)), self.parts.vessels
        refs = {}
        for i, v in enumerate(vessels):
            if self.is_agent[i]:
                a = (0.0, 0.0) if self.done[i] else actions.get(i, (0.0, 0.0))
                F[i] = self.steps[i](float(a[0]), float(a[1]), X[i], self.rows[i])
                continue
            if self.seers[i] is not None:
                self.seers[i](t, X.copy(), i, self.lengths)
            ref = v.reference.evaluate(t)
            tau_u, tau_r, _ = v.controller(t, X[i].copy(), ref)
            lim = v.scenario.limits
            if not (abs(tau_u) < lim.max_force and abs(tau_r) < lim.max_force):
                return (f"vessel {v.name!r}: control force out of limits or not finite at t = {t:.3f} s: "
                        f"tau_u = {tau_u!r}, tau_r = {tau_r!r}")
            F[i] = self.steps[i](tau_u, tau_r, X[i], self.rows[i])
            refs[i] = ref
        try:
            self.plant.step_vessels(F)
        except HydrodynamicCallbackError as exc:
            self.k += 1
            return str(exc)
        self.k += 1
        self.X = X = np.array(self.plant.states)
        for i, ref in refs.items():   # each controlled vessel against its own limits (the fleet loop's check)
            lim = vessels[i].scenario.limits
            if not within_limits(X[i], X[i, 0] - ref[0], X[i, 1] - ref[1], lim.max_speed, lim.max_yaw_rate,
                                 lim.max_distance):
                return f"vessel {vessels[i].name!r}: the state left its limits at t = {self.t:.3f} s"
        return None

    def collisions(self) -> list:
        """The pairs (i, j), i < j, of hulls in collision now (module docstring)."""
        out = []
        if self.mujoco:
            c = self.plant.contacts()
            for (i, j), p in self.pair_index.items():
                if c[p] > CONTACT_EVENT_N:
                    out.append((i, j))
            return out
        rng = self.geometry[:, :, G_RANGE]
        for (i, j) in self.pair_index:
            if rng[i, j] <= self._reach[i] + self._reach[j] and self.hull_distance(i, j) <= 0.0:
                out.append((i, j))
        return out

    def hull_at(self, i: int) -> np.ndarray:
        """Vessel i's collision footprint at its pose now, (n, 2) world [m], counter-clockwise."""
        x, y, psi = self.X[i, :3]
        c, s = math.cos(psi), math.sin(psi)
        f = self._footprints[i]
        return np.column_stack((x + c * f[:, 0] - s * f[:, 1], y + s * f[:, 0] + c * f[:, 1]))

    def hull_distance(self, i: int, j: int) -> float:
        """Signed distance [m] between the two hulls' footprints now (negative: overlapping)."""
        return float(convex_signed_distance(self.hull_at(i), self.hull_at(j)))

    def _ends(self, live):
        out = []
        hits = self.collisions()
        for i in live:
            for a, b in hits:
                if i in (a, b):
                    other = self.names[b if i == a else a]
                    how = "hulls in contact (MuJoCo)" if self.mujoco else "hull footprints overlap"
                    out.append((i, "collision", f"{self.names[i]!r} collided with {other!r} at t = {self.t:.3f} s "
                                                f"({how})"))
                    break
            else:
                x = self.X[i]
                g = self.goals[i]
                lim = self.parts.vessels[i].scenario.limits
                if not within_limits(x, x[0] - g[0], x[1] - g[1], lim.max_speed, lim.max_yaw_rate, lim.max_distance):
                    out.append((i, "diverged", f"{self.names[i]!r}: the state left its limits at t = {self.t:.3f} s"))
                elif math.hypot(x[0] - g[0], x[1] - g[1]) < self.goal_radius:
                    out.append((i, "goal", f"{self.names[i]!r} reached its goal at t = {self.t:.3f} s"))
        return out

    # --- observations -------------------------------------------------------------------------------

    @property
    def obs_size(self) -> int:
        return N_OWN + self.max_targets * N_TARGET

    def observe(self, i: int) -> tuple[np.ndarray, tuple]:
        """Vessel i's observation in physical units (module docstring) and the names in its slots."""
        out = np.zeros(self.obs_size)
        X, G = self.X, self.geometry
        x = X[i]
        c, s = math.cos(x[2]), math.sin(x[2])
        gx, gy = self.goals[i, 0] - x[0], self.goals[i, 1] - x[1]
        out[:N_OWN] = (x[3], x[4], x[5], c * gx + s * gy, -s * gx + c * gy)
        rng = G[i, :, G_RANGE]
        others = [j for j in np.argsort(np.where(np.isnan(rng), np.inf, rng), kind="stable")
                  if j != i and rng[j] <= self.sensor_range][:self.max_targets]
        vi = (c * x[3] - s * x[4], s * x[3] + c * x[4])
        names = []
        for slot, j in enumerate(others):
            y = X[j]
            cj, sj = math.cos(y[2]), math.sin(y[2])
            dx, dy = y[0] - x[0], y[1] - x[1]
            wx, wy = cj * y[3] - sj * y[4] - vi[0], sj * y[3] + cj * y[4] - vi[1]
            beta = math.radians(G[i, j, G_BETA])
            k = N_OWN + slot * N_TARGET
            out[k:k + N_TARGET] = (1.0, c * dx + s * dy, -s * dx + c * dy, c * wx + s * wy, -s * wx + c * wy,
                                   G[i, j, G_RANGE], math.sin(beta), math.cos(beta), G[i, j, G_DCPA], G[i, j, G_TCPA])
            names.append(self.names[j])
        return out, tuple(names)

    def scales(self, i: int) -> np.ndarray:
        """What divides vessel i's physical observation into the scaled one (module docstring)."""
        return self._scales[i]

    def bounds_scaled(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) of the scaled observation (clipped to them)."""
        return self._bounds_scaled

    def _make_scales(self, i: int) -> np.ndarray:
        R, U, T = self.situation.length_scale, self.situation.speed_scale, self.situation.time_scale
        own = np.array([U, U, U / self.lengths[i], R, R])
        slot = np.array([1.0, R, R, U, U, R, 1.0, 1.0, R, T])
        return np.concatenate([own, np.tile(slot, self.max_targets)])

    def _make_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        slot_lo = np.array([0.0, -OBS_BOUND, -OBS_BOUND, -OBS_BOUND, -OBS_BOUND, 0.0, -1.0, -1.0, 0.0, -OBS_BOUND])
        slot_hi = np.array([1.0, OBS_BOUND, OBS_BOUND, OBS_BOUND, OBS_BOUND, OBS_BOUND, 1.0, 1.0, OBS_BOUND, OBS_BOUND])
        lo = np.concatenate([np.full(N_OWN, -OBS_BOUND), np.tile(slot_lo, self.max_targets)])
        hi = np.concatenate([np.full(N_OWN, OBS_BOUND), np.tile(slot_hi, self.max_targets)])
        return lo, hi

    def last_controls(self, i: int) -> dict:
        """Vessel i's last control step: the clipped action, the quantizer's command and the actuators'
        force [N, N m] (the record row's tau, Q(tau) and f columns)."""
        row = self.rows[i]
        return {"action": row[C_TAU_U:C_TAU_U + 2].copy(), "command": row[C_Q_U:C_Q_U + 2].copy(),
                "thrust": row[C_F_U:C_F_U + 2].copy()}

    def close(self) -> None:
        self.parts.close()


# --- what the Gymnasium and PettingZoo environments share -----------------------------------------------


def physical_action(action, low, high) -> tuple[float, float]:
    """The thrust (tau_u [N], tau_r [N m]) of a normalized action in [-1, 1] (clipped): a high for
    a >= 0, -a low below (each side scaled on its own, 0 is no thrust), as
    :meth:`usv_mj.envs.gymnasium_env.USVGymEnv.physical_action`."""
    a = np.clip(np.asarray(action, dtype=np.float64).reshape(2), -1.0, 1.0)
    f = np.where(a >= 0.0, a * high, -a * low)
    return float(f[0]), float(f[1])


def checked_action(action, where: str) -> np.ndarray:
    """``action`` as a finite float64 (2,) array, or a ValueError naming the place."""
    a = np.asarray(action, dtype=np.float64)
    if a.shape != (2,):
        raise ValueError(f"{where}: an action is (surge, yaw), shape (2,), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{where}: an action must be finite, got {a.tolist()}")
    return a


def scaled_observation(traffic: Traffic, i: int) -> tuple[np.ndarray, tuple]:
    """Vessel i's observation divided by :meth:`Traffic.scales` and clipped to
    :meth:`Traffic.bounds_scaled` (a non-finite value, from a diverged state, at its bound or 0), as
    float32; and the names in its target slots."""
    physical, names = traffic.observe(i)
    lo, hi = traffic.bounds_scaled()
    v = physical / traffic.scales(i)
    if not np.all(np.isfinite(v)):
        v = np.nan_to_num(v, nan=0.0, posinf=OBS_BOUND, neginf=-OBS_BOUND)
    return np.clip(v, lo, hi).astype(np.float32), names


def decode_observation(traffic: Traffic, i: int, observation) -> dict:
    """The physical observation of a scaled one (vessel i's scales): ``{"own": {field: value},
    "targets": (max_targets, len(TARGET_FIELDS)) array}`` (:data:`OWN_FIELDS`, :data:`TARGET_FIELDS`)."""
    v = np.asarray(observation, dtype=np.float64).reshape(-1) * traffic.scales(i)
    return {"own": dict(zip(OWN_FIELDS, v[:N_OWN].tolist())),
            "targets": v[N_OWN:].reshape(traffic.max_targets, N_TARGET)}


#: the options of :func:`traffic_situation` and of :class:`Traffic` the environments take
SITUATION_OPTIONS = ("vessel", "target_vessel", "speed", "k_R", "plant", "control_period", "substeps", "duration",
                     "target_controller", "goals", "overrides")
TRAFFIC_OPTIONS = ("action_repeat", "quantize", "max_surge_force", "max_yaw_moment", "max_targets", "sensor_range",
                   "goal_radius", "domain_penalty", "goal_reward", "collision_penalty")


def split_options(options: dict, where: str) -> tuple[dict, dict]:
    """(situation options, traffic options) of an environment's keyword options; ValueError on any other."""
    unknown = sorted(set(options) - set(SITUATION_OPTIONS) - set(TRAFFIC_OPTIONS))
    if unknown:
        raise ValueError(f"{where}: unknown options {unknown}; options: "
                         f"{', '.join(SITUATION_OPTIONS + TRAFFIC_OPTIONS)}")
    return ({k: options[k] for k in SITUATION_OPTIONS if k in options},
            {k: options[k] for k in TRAFFIC_OPTIONS if k in options})
