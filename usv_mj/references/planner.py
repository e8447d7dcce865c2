"""Guidance that keeps clear: a visibility-graph path around inflated obstacles, smoothed into a
unicycle reference with bounded r_d and r_d_dot, and re-timed around moving obstacles.

The safety property (why the inflation is what it is)
-----------------------------------------------------
The PPC law keeps the tracking errors of the controlled point inside the funnel: |e1| < rho(t) and
|e2| < rho(t) (Eqs. 8-10), where e = p_bar - p_bar_d, p_bar = p + eps h(psi), p_bar_d = p_d + eps
h(psi_d), h(a) = (cos a, sin a) and eps = m23/m22 (docs/model.md §3, Do & Pan's offset). Each axis is
bounded separately, so |p_bar - p_bar_d| < sqrt(2) rho(t). Every point q of the hull is within the
hull radius R of the body origin p (:data:`usv_mj.scene.hull.HULL_RADIUS`). Hence

    |q - p_d(t)| <= |q - p| + |p - p_bar| + |p_bar - p_bar_d| + |p_bar_d - p_d|
                 <  R + |eps| + sqrt(2) rho(t) + |eps|  =: G(t)

so the hull lies inside the disc of radius G(t) about the reference point, and

    clearance(hull, O) > dist(p_d(t), O) - G(t).

The planner makes dist(p_d(t), O_i(t)) >= G(t) + margin for every obstacle and every t of the run
(checked on the final reference with shapely, not assumed), so **while the tracking errors stay
inside the funnel, the hull keeps at least ``margin`` from every obstacle**. It is a property of
the reference and the funnel; it says nothing once the funnel is left (a funnel violation is an
event of the run, and the clearance log shows what happened then). With the paper's funnel
(rho_inf = 2 m, rho_0 = 18 m) G is at least 3.9 m and 26.6 m at t = 0: narrow gaps close and the
reference must stay far from everything early on; a harbour scenario sets a tighter funnel.

Planning (static obstacles): each obstacle is grown by its inflation (G at the time the reference
passes it + margin + an allowance for the smoothing), the grown shapes are merged (shapely), a
visibility graph over their vertices plus start and goal is searched with networkx (A*, Euclidean
heuristic; only the vertices and tangent segments a shortest path can use, :func:`visibility_path`), and the polyline is smoothed by a virtual boat (pure pursuit with look-ahead L, the
curvature rate-limited) into a path tabulated in arc length: x(s), y(s), psi(s), kappa(s), with
|kappa| <= max_yaw_rate / u and |dkappa/ds| <= max_yaw_accel / u^2. The reference runs it at speed
u: r_d = kappa u, psi_d = psi(s), x_d_dot = u cos psi_d (docs/model.md §4's unicycle-like model, v_d = 0).
Where the verification finds an obstacle closer than G(t) + margin, that obstacle's inflation is
raised by the deficit and the path is planned again (at most ``MAX_ITERATIONS`` times).

Moving obstacles (:class:`Guidance`): every ``check_period`` the predicted clearance
dist(p_d(tau), O_j(tau)) - G(tau) over the next ``horizon`` seconds is computed for each moving
obstacle (constant velocity); when it drops under the margin, the reference is **re-timed**: it
slows down (|u_d_dot| <= max_accel), holds a lower speed for a while, and speeds up again; the
candidate that loses the least progress while keeping the predicted clearance above the margin
(moving and static obstacles) is taken, and a ``replan`` event (``mode = "timing"``) is logged.
The path itself does not change, so r_d and r_d_dot stay bounded (r_d_dot = kappa' u^2 + kappa
u_dot). When no re-timing helps (a boat coming along the path), the path is shifted sideways
around the conflict point, starboard first, with growing offsets, smoothed by the same virtual
boat from the current heading and curvature (r_d stays continuous), and accepted when the
predicted clearance over the horizon holds (``mode = "path"``). When nothing helps, a
``guidance_conflict`` event is logged and the reference is left as it is.
"""

from __future__ import annotations

import bisect
import dataclasses
import math
from dataclasses import dataclass, field

import networkx as nx
import numpy as np
import shapely

from usv_mj.controllers.performance_funnel import PerformanceFunnel
from usv_mj.record.run_record import Event
from usv_mj.scenario.spec import ScenarioError
from usv_mj.physics.ship import wrap_angle

from usv_mj.scene.hull import HULL_RADIUS
from usv_mj.references.guided import (GuidedReference, PathTable, SpeedProfile, guided_kernel, guided_pose,  # noqa: F401 (re-exported)
                     retimed_pieces)
from usv_mj.scenario.obstacles import GuidanceSpec, ObstacleSpec

SQRT2 = math.sqrt(2.0)
MAX_ITERATIONS = 12
PATH_DS = 0.02          # m, arc-length step of the tabulated path
VERIFY_DT = 0.1         # s, time step of the clearance verification


class PlanningError(ScenarioError):
    """No path, or the start/goal lies inside an inflated obstacle; the message says which. A
    :class:`usv_mj.scenario.spec.ScenarioError`: the scenario (funnel, margin, obstacles) asks for the
    impossible, and the CLI reports it as such (exit code 2)."""


class InsideObstacle(PlanningError):
    """The start or the goal (``label``, ``point``) lies inside an inflated obstacle
    (:func:`plan_reference` names which)."""

    def __init__(self, label: str, point):
        self.label, self.point = label, (float(point[0]), float(point[1]))
        super().__init__(f"the {label} point ({self.point[0]:.2f}, {self.point[1]:.2f}) m lies inside an inflated "
                         f"obstacle")


@dataclass(frozen=True)
class SafetyEnvelope:
    """G(t) = hull_radius + 2 |eps| + sqrt(2) rho(t) (module docstring) and the margin.

    Attributes
    ----------
    funnel: the position funnel rho_1 = rho_2 (Eq. 9) [m].
    eps: m23/m22 [m] (docs/model.md §3).
    hull_radius: [m].
    margin: required clearance on top [m].
    """

    funnel: PerformanceFunnel
    eps: float
    hull_radius: float = HULL_RADIUS
    margin: float = 0.3

    def guaranteed_radius(self, t):
        """G(t) [m]: the hull is inside the disc of this radius about p_d(t) while |e1|, |e2| < rho(t)."""
        return self.hull_radius + 2.0 * abs(self.eps) + SQRT2 * self.funnel(t)

    def required(self, t):
        """G(t) + margin [m]: the distance the reference keeps from every obstacle."""
        return self.guaranteed_radius(t) + self.margin

    @classmethod
    def from_scenario(cls, scenario, margin: float) -> "SafetyEnvelope":
        f = scenario.funnel
        from usv_mj.scene.hull import vessel_hull_radius

        radius = vessel_hull_radius(scenario.vessel.model.dimensions)   # the vessel's (the paper's: HULL_RADIUS)
        return cls(PerformanceFunnel(f.rho_xy[0], f.rho_xy[1], f.rate), scenario.ship.eps, radius, margin)


# --- the path: arc-length table from a virtual boat --------------------------------------------


def smooth_polyline(points, psi0: float, kappa_max: float, dkappa_max: float, lookahead: float,
                    extend: float, ds: float = PATH_DS, kappa0: float = 0.0) -> PathTable:
    """The virtual boat: pure pursuit of the polyline ``points`` (look-ahead ``lookahead`` [m]) from
    points[0] with heading ``psi0``; curvature kappa_cmd = 2 sin(alpha)/L clipped to ``kappa_max``
    [1/m], followed with |dkappa/ds| <= ``dkappa_max`` [1/m^2]. The polyline is extended by
    ``extend`` [m] straight past its last point; the table stops at that end. ``kappa0``: initial
    curvature (a path that continues another one keeps r_d continuous)."""
    pts = np.asarray(points, dtype=float)
    last = pts[-1] - pts[-2]
    pts = np.vstack([pts, pts[-1] + extend * last / np.linalg.norm(last)])
    seg = np.diff(pts, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    keep = seg_len > 1e-9
    pts = np.vstack([pts[0], pts[1:][keep]])
    seg = np.diff(pts, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    cum = np.concatenate(([0.0], np.cumsum(seg_len)))
    total = cum[-1]

    def point_at(sp):
        sp = min(max(sp, 0.0), total)
        j = min(bisect.bisect_right(cum, sp) - 1, len(seg) - 1)
        return pts[j] + (sp - cum[j]) / seg_len[j] * seg[j]

    n_max = int(math.ceil(1.5 * total / ds)) + 10
    xs, ys, ps, ks = (np.empty(n_max) for _ in range(4))
    x, y, psi, kappa = pts[0, 0], pts[0, 1], psi0, float(kappa0)
    j = 0          # current segment
    s_proj = 0.0   # arc length of the projection on the polyline
    k = 0
    dk = dkappa_max * ds
    while k < n_max:
        xs[k], ys[k], ps[k], ks[k] = x, y, psi, kappa
        # projection onto the polyline (monotone: look at the current and next segments)
        best = None
        for jj in range(j, min(j + 3, len(seg))):
            a = pts[jj]
            w = min(max(((x - a[0]) * seg[jj, 0] + (y - a[1]) * seg[jj, 1]) / seg_len[jj] ** 2, 0.0), 1.0)
            q = a + w * seg[jj]
            dist2 = (x - q[0]) ** 2 + (y - q[1]) ** 2
            if best is None or dist2 < best[0] - 1e-12:
                best = (dist2, jj, cum[jj] + w * seg_len[jj])
        _, j, s_proj = best
        if s_proj >= total - lookahead - 1e-9:
            break
        target = point_at(s_proj + lookahead)
        alpha = math.atan2(target[1] - y, target[0] - x) - psi
        alpha = float(wrap_angle(alpha))
        dist_t = math.hypot(target[0] - x, target[1] - y)
        k_cmd = 2.0 * math.sin(alpha) / max(dist_t, 1e-6)
        k_cmd = min(max(k_cmd, -kappa_max), kappa_max)
        k_new = kappa + min(max(k_cmd - kappa, -dk), dk)
        # kappa linear over the step, psi its exact integral, x and y by Simpson's rule
        psi_mid = psi + 0.5 * ds * kappa + 0.125 * ds * (k_new - kappa)
        psi_new = psi + 0.5 * ds * (kappa + k_new)
        x += ds / 6.0 * (math.cos(psi) + 4.0 * math.cos(psi_mid) + math.cos(psi_new))
        y += ds / 6.0 * (math.sin(psi) + 4.0 * math.sin(psi_mid) + math.sin(psi_new))
        psi, kappa = psi_new, k_new
        k += 1
    return PathTable(xs[:k].copy(), ys[:k].copy(), ps[:k].copy(), ks[:k].copy(), ds)


# --- static planning ----------------------------------------------------------------------------


@dataclass
class Plan:
    """The result of :func:`plan_reference`.

    Attributes
    ----------
    reference: the :class:`GuidedReference`.
    polyline: the visibility-graph path [m], shape (n, 2).
    inflation: per obstacle [m]: the distance used to grow it for the search (static ones).
    slack: per static obstacle, min over t of dist(p_d(t), O_i) - (G(t) + margin) [m] (>= 0: verified).
    slack_time: the time [s] of that minimum.
    iterations: number of plan/verify rounds.
    envelope: the :class:`SafetyEnvelope`.
    safety_radius: per obstacle [m], G + margin at the time the reference passes closest (the
        "inflated safety boundary" to draw; NaN for moving obstacles).
    """

    reference: GuidedReference
    polyline: np.ndarray
    inflation: np.ndarray
    slack: np.ndarray
    slack_time: np.ndarray
    iterations: int
    envelope: SafetyEnvelope
    obstacles: tuple = ()
    events: list = field(default_factory=list)
    safety_radius: np.ndarray | None = None

    @property
    def verified(self) -> bool:
        return bool(np.all(self.slack >= -1e-9))

    def fresh(self) -> "Plan":
        """The same plan with a reference of its own, as planned (a run's :class:`Guidance` re-times
        and detours the reference it is given; the path tables are shared, never changed)."""
        t0, s0, path = self.reference.segments[0]
        speed = self.reference.profile.pieces[0][2]
        return dataclasses.replace(self, reference=GuidedReference(path, SpeedProfile(speed)), events=list(self.events))


QUAD_SEGS = 3  # vertices per quarter circle of the grown shapes (visibility-graph size vs. corner cutting)


def _grown(obstacle: ObstacleSpec, inflation: float):
    """The obstacle grown by ``inflation`` [m] as a polygon that contains the exact grown shape
    (circles: a circumscribed polygon; boxes: rounded corners with circumscribed arcs)."""
    n = 4 * QUAD_SEGS
    grow = 1.0 / math.cos(math.pi / n)
    if obstacle.kind == "circle":
        return shapely.Point(*obstacle.center).buffer((obstacle.radius + inflation) * grow, quad_segs=QUAD_SEGS)
    return obstacle.shape(0.0).buffer(inflation * grow, quad_segs=QUAD_SEGS, join_style="round")


def _merged_obstacles(obstacles, inflation):
    grown = [_grown(o, r) for o, r in zip(obstacles, inflation)]
    union = shapely.union_all(grown)
    polys = list(union.geoms) if hasattr(union, "geoms") else [union]
    return [shapely.Polygon(p.exterior) for p in polys if not p.is_empty]


#: candidate edges per bulk STRtree query: one query is a call into GEOS that Python cannot
#: interrupt, so it is kept short (a Ctrl-C while a harbour is planned is honoured at once)
QUERY_CHUNK = 512


def _tangent_at(nodes, before, after, i, j):
    """Whether the segment nodes[i] -> nodes[j] is locally tangent at nodes[i] to its polygon: the
    polygon's neighbours of vertex i, ``before[i]`` and ``after[i]``, lie on one side of the line
    (or on it). A shortest path around polygons only runs along such segments (the reduced
    visibility graph: a segment that cuts the corner at a vertex enters the polygon there, and one
    at a reflex vertex is never taut). Start and goal (before = -1) are tangent to anything."""
    d = nodes[j] - nodes[i]
    free = before[i] < 0
    b, a = nodes[np.maximum(before[i], 0)] - nodes[i], nodes[np.maximum(after[i], 0)] - nodes[i]
    cb = d[:, 0] * b[:, 1] - d[:, 1] * b[:, 0]
    ca = d[:, 0] * a[:, 1] - d[:, 1] * a[:, 0]
    scale = 1e-12 * (np.abs(d).sum(axis=1) + 1.0) ** 2
    return free | (cb * ca >= -scale)


def _visible_edges(nodes, before, after, keep, tree):
    """The edges (i, j, length) of the reduced visibility graph on the nodes ``keep`` (indices):
    pairs tangent at both ends (:func:`_tangent_at`) whose segment meets no part in ``tree``,
    asked in bulk, :data:`QUERY_CHUNK` segments per STRtree query."""
    edges = []
    for row, i in enumerate(keep[:-1]):
        j = keep[row + 1:]
        ii = np.full(len(j), i)
        ok = _tangent_at(nodes, before, after, ii, j) & _tangent_at(nodes, before, after, j, ii)
        if ok.any():
            edges.append(np.c_[ii[ok], j[ok]])
    if not edges:
        return np.zeros((0, 2), np.int64), np.zeros(0)
    edges = np.vstack(edges)
    blocked = np.zeros(len(edges), dtype=bool)
    if tree is not None:
        for lo in range(0, len(edges), QUERY_CHUNK):
            e = edges[lo:lo + QUERY_CHUNK]
            hit, _ = tree.query(shapely.linestrings(np.stack([nodes[e[:, 0]], nodes[e[:, 1]]], axis=1)),
                                predicate="intersects")
            blocked[lo + np.unique(hit)] = True
    edges = edges[~blocked]
    return edges, np.linalg.norm(nodes[edges[:, 0]] - nodes[edges[:, 1]], axis=1)


def visibility_path(start, goal, polygons) -> np.ndarray:
    """Shortest polyline start -> goal around ``polygons`` (visibility graph, networkx A*).

    The graph holds only the nodes that can lie on a path no longer than a bound L, those with
    |start - v| + |v - goal| <= L (an ellipse about the start and the goal), and only the edges
    tangent to their polygons at both ends (:func:`_tangent_at`), each tested against the
    obstacles near it (one STRtree query per chunk of edges). L starts at 1.25 |goal - start|; a
    path found no longer than L is the shortest of all (every vertex of the shortest path lies in
    the ellipse of its own length); otherwise L grows to the length found (or doubles when none
    is found) and the search runs again. The work follows the obstacles near the straight line,
    not all of them."""
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    blocked_area = shapely.union_all([p.buffer(-1e-6) for p in polygons]) if polygons else shapely.Polygon()
    for label, pt in (("start", start), ("goal", goal)):
        if blocked_area.contains(shapely.Point(*pt)):
            raise InsideObstacle(label, pt)
    nodes, before, after = [start, goal], [-1, -1], [-1, -1]
    for p in shapely.orient_polygons(polygons) if polygons else ():
        ring = np.asarray(p.exterior.coords)[:-1]
        first, m = len(nodes), len(ring)
        nodes.extend(ring)
        local = np.arange(m)
        before.extend(first + (local - 1) % m)
        after.extend(first + (local + 1) % m)
    nodes, before, after = np.array(nodes), np.array(before), np.array(after)
    parts = list(blocked_area.geoms) if hasattr(blocked_area, "geoms") else [blocked_area]
    parts = [p for p in parts if not p.is_empty]
    tree = shapely.STRtree(parts) if parts else None
    detour = np.linalg.norm(nodes - start, axis=1) + np.linalg.norm(nodes - goal, axis=1)
    bound = 1.25 * detour[0]
    while True:
        keep = np.flatnonzero(detour <= bound + 1e-9)
        edges, lengths = _visible_edges(nodes, before, after, keep, tree)
        graph = nx.Graph()
        graph.add_nodes_from(keep.tolist())
        graph.add_weighted_edges_from(zip(edges[:, 0].tolist(), edges[:, 1].tolist(), lengths.tolist()))
        try:
            route = nx.astar_path(graph, 0, 1, heuristic=lambda a, b: float(np.linalg.norm(nodes[a] - nodes[b])),
                                  weight="weight")
        except nx.NetworkXNoPath:
            if len(keep) == len(nodes):
                raise PlanningError("no path from the start to the goal keeps the required clearance: the gaps "
                                    "between the inflated obstacles are closed (tighten the funnel, lower the "
                                    "margin or move the obstacles)") from None
            bound *= 2.0
            continue
        length = float(np.sum(np.linalg.norm(np.diff(nodes[route], axis=0), axis=1)))
        if length <= bound + 1e-9:
            return nodes[route]
        bound = length


def _inside_which(exc: InsideObstacle, obstacles, static, inflation) -> PlanningError:
    """``exc`` with the obstacle named: its index in ``[[obstacles]]``, its name and its inflation."""
    point = shapely.Point(*exc.point)
    for i, r in zip(static, inflation):
        if _grown(obstacles[i], r).buffer(-1e-6).contains(point):
            o = obstacles[i]
            name = f"obstacles[{i}]" + (f" ({o.name})" if getattr(o, "name", "") else "")
            return PlanningError(f"the {exc.label} point ({exc.point[0]:.2f}, {exc.point[1]:.2f}) m lies inside an "
                                 f"inflated obstacle, {name}, grown by {r:.2f} m (the hull's radius, the funnel's "
                                 f"bound and guidance.margin: docs/obstacles.md); move the {exc.label} or the obstacle")
    return exc   # inside the union only (two inflated obstacles overlap there)


def obstacle_distances(obstacles, positions: np.ndarray, times: np.ndarray | None = None) -> np.ndarray:
    """dist(p_k, O_i(t_k)) [m], exact for circles (|p - c(t)| - r) and boxes (shapely), shape (K, n)."""
    positions = np.asarray(positions, dtype=float)
    out = np.empty((len(positions), len(obstacles)))
    times = np.zeros(len(positions)) if times is None else np.asarray(times, dtype=float)
    pts = None
    for i, o in enumerate(obstacles):
        cx = o.center[0] + o.velocity[0] * times
        cy = o.center[1] + o.velocity[1] * times
        if o.kind == "circle":
            out[:, i] = np.hypot(positions[:, 0] - cx, positions[:, 1] - cy) - o.radius
        else:
            rel = positions - np.c_[cx - o.center[0], cy - o.center[1]]  # move the point, not the box
            if pts is None or o.moving:
                pts = shapely.points(rel)
            out[:, i] = shapely.distance(o.shape(0.0), pts)
            if o.moving:
                pts = None
    return out


def plan_reference(start, goal, obstacles, envelope: SafetyEnvelope, guidance: GuidanceSpec, speed: float,
                   duration: float, psi0: float | None = None) -> Plan:
    """Plan a reference from ``start`` to ``goal`` [m] around the static ``obstacles`` (module
    docstring), run at ``speed`` [m/s] from t = 0 and verified over [0, ``duration``] s.

    Moving obstacles are ignored here (see :class:`Guidance`). Raises :class:`PlanningError`.
    """
    obstacles = tuple(obstacles)
    static = [i for i, o in enumerate(obstacles) if not o.moving]
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    if psi0 is None:
        psi0 = math.atan2(goal[1] - start[1], goal[0] - start[0])
    kappa_max = guidance.max_yaw_rate / speed
    dkappa_max = guidance.max_yaw_accel / speed**2
    times = np.arange(0.0, duration + 1e-9, VERIFY_DT)
    required = envelope.required(times)
    # first guess: G at the earliest time the reference can reach the obstacle (rho decreases)
    d0 = obstacle_distances([obstacles[i] for i in static], start[None, :])[0] if static else np.zeros(0)
    inflation = np.array([envelope.required(max(d - 0.0, 0.0) / speed) + guidance.allowance_m for d in d0])
    extend = speed * duration + 10.0
    for iteration in range(1, MAX_ITERATIONS + 1):
        polygons = _merged_obstacles([obstacles[i] for i in static], inflation) if static else []
        try:
            polyline = visibility_path(start, goal, polygons)
        except InsideObstacle as exc:   # which obstacle, and by how much it is inflated
            raise _inside_which(exc, obstacles, static, inflation) from None
        path = smooth_polyline(polyline, psi0, kappa_max, dkappa_max, guidance.lookahead_m, extend)
        reference = GuidedReference(path, SpeedProfile(speed))
        pos = reference.positions(times)
        dist = obstacle_distances([obstacles[i] for i in static], pos)
        slack_t = dist - required[:, None]
        slack = slack_t.min(axis=0) if static else np.zeros(0)
        slack_time = times[np.argmin(slack_t, axis=0)] if static else np.zeros(0)
        if np.all(slack >= 0):
            break
        bad = slack < 0
        inflation[bad] += -slack[bad] + 0.05
    full_inflation = np.full(len(obstacles), np.nan)
    full_inflation[static] = inflation
    full_slack = np.full(len(obstacles), np.nan)
    full_slack[static] = slack
    full_time = np.full(len(obstacles), np.nan)
    full_time[static] = slack_time
    safety = np.full(len(obstacles), np.nan)
    if static:
        safety[static] = envelope.required(times[np.argmin(dist, axis=0)])
    return Plan(reference, polyline, full_inflation, full_slack[static], full_time[static], iteration, envelope,
                obstacles, safety_radius=safety)


# --- moving obstacles ---------------------------------------------------------------------------


class Guidance:
    """Online guidance: re-times a :class:`GuidedReference` (or detours it, when ``goal`` is given)
    when the predicted clearance to a moving obstacle drops under the margin (module docstring).
    Call :meth:`update` every control step (it works every ``check_period``); events go to
    ``log.add_event`` when a log is given.
    """

    HOLD_STEPS = (0.0, 5.0, 10.0, 15.0, 20.0, 30.0, 40.0, 60.0)
    SPEED_FACTORS = (0.75, 0.5, 0.25, 0.1)
    PREDICT_DT = 0.25

    DETOUR_OFFSETS = (4.0, 6.0, 9.0, 13.0)   # m, lateral offsets tried, starboard first
    DETOUR_SPAN = 12.0                        # m, before and after the conflict point along the path

    def __init__(self, reference: GuidedReference, obstacles, envelope: SafetyEnvelope, guidance: GuidanceSpec,
                 speed: float, log=None, goal=None):
        self.reference = reference
        self.goal = None if goal is None else np.asarray(goal, dtype=float)
        self.obstacles = tuple(obstacles)
        self.moving = [i for i, o in enumerate(self.obstacles) if o.moving]
        self.static = [i for i, o in enumerate(self.obstacles) if not o.moving]
        self.envelope, self.spec, self.speed = envelope, guidance, float(speed)
        self.log = log
        self.events: list[Event] = []
        self._next_check = 0.0
        self._conflict_reported = False

    def predicted_slack(self, profile: SpeedProfile, t: float, segments=None) -> tuple[float, int, float]:
        """min over tau in [t, t + horizon] and all obstacles of dist(p_d(tau), O(tau)) - G(tau) - margin,
        with the obstacle index and the time of the minimum."""
        times = np.arange(t, t + self.spec.horizon + 1e-9, self.PREDICT_DT)
        pos = self.reference.positions(times, profile, segments)
        dist = obstacle_distances(self.obstacles, pos, times)
        slack = dist - self.envelope.required(times)[:, None]
        k, i = np.unravel_index(int(np.argmin(slack)), slack.shape)
        return float(slack[k, i]), int(i), float(times[k])

    def update(self, t: float) -> bool:
        """Check (every ``check_period``) and re-time if needed; True when the reference changed."""
        if not self.moving or t + 1e-12 < self._next_check:
            return False
        self._next_check = t + self.spec.check_period
        profile = self.reference.profile
        slack, i, t_min = self.predicted_slack(profile, t)
        if slack >= 0.0:
            self._conflict_reported = False
            return False
        s, u, _ = profile.state(t)
        best = None
        for factor in self.SPEED_FACTORS:
            for hold in self.HOLD_STEPS:
                pieces = retimed_pieces(t, s, u, factor * self.speed, hold, self.speed, self.spec.max_accel)
                cand = profile.copy()
                cand.replace_from(t, pieces)
                c_slack, _, _ = self.predicted_slack(cand, t)
                if c_slack >= 0.0:
                    progress = cand.state(t + self.spec.horizon)[0]
                    if best is None or progress > best[0]:
                        best = (progress, factor, hold, pieces, c_slack)
                    break  # longer holds at this speed only lose progress
        name = self.obstacles[i].name
        if best is None and self.goal is not None:
            detour = self._detour(t, t_min)
            if detour is not None:
                path, side, offset, c_slack = detour
                self.reference.switch_path(t, path)
                self._conflict_reported = False
                self._emit(Event(t, "replan", f"detour for {name}: predicted clearance margin {slack:.2f} m at "
                                 f"t = {t_min:.1f} s, no re-timing avoids it -> path shifted {offset:g} m to "
                                 f"{side} (new margin {c_slack:.2f} m)",
                                 {"obstacle": name, "mode": "path", "predicted_slack_m": slack, "t_conflict_s": t_min,
                                  "side": side, "offset_m": offset, "new_slack_m": c_slack}))
                return True
        if best is None:
            if not self._conflict_reported:
                self._conflict_reported = True
                self._emit(Event(t, "guidance_conflict", f"predicted clearance to {name} drops to "
                                 f"{slack + self.envelope.margin:.2f} m at t = {t_min:.1f} s and no re-timing "
                                 f"avoids it", {"obstacle": name, "predicted_slack_m": slack, "t_conflict_s": t_min}))
            return False
        progress, factor, hold, pieces, c_slack = best
        profile.replace_from(t, pieces)
        self._conflict_reported = False
        self._emit(Event(t, "replan", f"re-timed the reference for {name}: predicted clearance margin "
                         f"{slack:.2f} m at t = {t_min:.1f} s -> speed {factor * self.speed:.2f} m/s held "
                         f"{hold:g} s (new margin {c_slack:.2f} m)",
                         {"obstacle": name, "mode": "timing", "predicted_slack_m": slack, "t_conflict_s": t_min,
                          "speed_mps": factor * self.speed, "hold_s": hold, "new_slack_m": c_slack}))
        return True

    def _detour(self, t: float, t_conflict: float):
        """Shift the path sideways around the conflict point (starboard first, then port; growing
        offsets): current point -> offset point 12 m before the conflict -> offset point 12 m after ->
        back on the path 12 m later -> goal, smoothed from the current heading and curvature, and
        accepted when the predicted clearance over the horizon (moving and static obstacles) holds.
        Returns (path, side, offset, slack) or None."""
        x, y, psi, kappa, s_loc, (t0, s0, path) = self.reference.geometry(t)
        s_c = self.reference.profile.state(t_conflict)[0] - s0
        goal_s = float(np.argmin(np.hypot(path.x - self.goal[0], path.y - self.goal[1]))) * path.ds
        sa = max(s_c - self.DETOUR_SPAN, s_loc + 4.0)
        sb = max(s_c + self.DETOUR_SPAN, sa + 4.0)
        sr = sb + self.DETOUR_SPAN
        u = self.speed
        extend = u * self.spec.horizon * 2.0 + 10.0
        for side, sign in (("starboard", -1.0), ("port", 1.0)):
            for offset in self.DETOUR_OFFSETS:
                pts = [(x, y)]
                for sv, off in ((sa, offset), (sb, offset), (sr, 0.0)):
                    px, py, pp, _ = path.at(sv)
                    # the left normal is (-sin psi, cos psi); sign -1 is starboard
                    pts.append((px - sign * off * math.sin(pp), py + sign * off * math.cos(pp)))
                if goal_s > sr + 1.0:
                    pts.append(tuple(self.goal))
                new = smooth_polyline(np.array(pts), psi, self.spec.max_yaw_rate / u, self.spec.max_yaw_accel / u**2,
                                      self.spec.lookahead_m, extend, kappa0=kappa)
                segments = self.reference.segments_with(t, new)
                c_slack, _, _ = self.predicted_slack(self.reference.profile, t, segments)
                if c_slack >= 0.0:
                    return new, side, offset, c_slack
        return None

    def _emit(self, event: Event) -> None:
        self.events.append(event)
        if self.log is not None:
            self.log.add_event(event)
