"""Clearance between the hull and every obstacle, and the contacts, once per control step.

Two monitors with one interface, ``update(t, plant_or_state) -> clearance`` (a float64 array, one
signed distance [m] per obstacle, negative = penetration) plus the attributes ``normal_force`` [N]
(sum of the normal forces of the hull's contacts with each obstacle at this step, 0 without
contact) and ``in_contact`` (bool per obstacle):

- :class:`MuJoCoClearance`: MuJoCo's own distance query, ``mujoco.mj_geomDistance``, between each of
  the hull's collision geoms and each obstacle geom of a :class:`~usv_mj.obstacles.compose.HarbourPlant`
  (the minimum over the hull geoms), after ``mj_kinematics`` so that the poses are those of the
  current state; contacts from ``d.contact`` with ``mujoco.mj_contactForce``.
- :class:`GeometricClearance`: the same quantity from the geometry (shapely) for plants without
  contact physics (the analytic plant): the hull's collision footprint
  (:func:`~usv_mj.obstacles.compose.hull_footprint`) at the plant's pose against each obstacle's
  section. Separated: the exact polygon distance (circles exactly: distance to the centre minus
  the radius). Overlapping: minus an estimate of the penetration depth (the deepest vertex of one
  shape inside the other, circles exactly), so the sign is right and the magnitude is indicative.
  The analytic plant passes through obstacles; :attr:`GeometricClearance.note` says so.

Both report, for obstacles farther than ``exact_within`` (10 m) by a bounding-circle test, that
lower bound instead of the exact distance (cheap with 50 obstacles; ``math.inf`` = always exact).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import shapely
from llvmlite import ir as llvmlite_ir
from numba import njit, types
from numba.extending import intrinsic
from shapely import affinity

from usv_mj.plants.mujoco_callback import call_model_data, mujoco_function_address

from .compose import hull_footprint, vessel_collision_geoms, vessel_hull_radius

ANALYTIC_NOTE = ("the analytic plant has no contact physics: clearance is computed from the geometry, "
                 "a collision is recorded when it reaches zero, and the hull passes through obstacles")


@intrinsic
def _call_geom_distance(typingctx, fn_address, m_addr, d_addr, geom1, geom2, distmax, fromto_addr):
    """Call ``mjtNum mj_geomDistance(const mjModel*, mjData*, int, int, mjtNum, mjtNum*)`` at
    ``fn_address`` (numba intrinsic; the address is an argument so that callers can be cached)."""
    sig = types.float64(types.int64, types.int64, types.int64, types.int32, types.int32, types.float64,
                        types.int64)

    def codegen(context, builder, signature, args):
        i64, i32, f64 = llvmlite_ir.IntType(64), llvmlite_ir.IntType(32), llvmlite_ir.DoubleType()
        fnty = llvmlite_ir.FunctionType(f64, [i64, i64, i32, i32, f64, i64])
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(fn, list(args[1:]))

    return sig, codegen


#: [m] a skipped obstacle's bound must beat the best distance so far by this much (min_only): far
#: above the error of MuJoCo's convex distance (its tolerance, 1e-6) and of the bounding circles
SKIP_MARGIN = 1e-2


@njit(cache=True)
def mujoco_clearance_kernel(m_addr, d_addr, kinematics, geom_distance, hull, obstacles, bound, exact_within,
                            prefilter, distmax, qpos, geom_xpos, clearance, exact, witness, fromto, normal_force,
                            in_contact, min_only, order):
    """:meth:`MuJoCoClearance.update` but the contacts, natively: ``mj_kinematics`` (at address
    ``kinematics``), the bounding-circle prefilter (when ``prefilter``) and ``mj_geomDistance`` (at
    ``geom_distance``) of every hull geom against every obstacle left to do, in the same order.

    ``min_only`` (branch and bound, for a caller that reads only the minimum, its argmin and
    whether any entry is <= 0): the obstacles are visited by increasing bound (``order``, scratch
    of n int64) and one whose bound exceeds the least clearance so far by :data:`SKIP_MARGIN` keeps
    its bound (not exact): its distance is larger than that least one, so the minimum, its first
    index and the contact test are those of the full update."""
    call_model_data(kinematics, m_addr, d_addr)
    n = obstacles.shape[0]
    for i in range(n):
        if prefilter or min_only:  # np.sqrt(rel_x ** 2 + rel_y ** 2) - bound < exact_within
            rx = geom_xpos[obstacles[i], 0] - qpos[0]
            ry = geom_xpos[obstacles[i], 1] - qpos[1]
            lower = math.sqrt(rx * rx + ry * ry) - bound[i]
            clearance[i] = lower
            exact[i] = lower < exact_within if prefilter else True
        else:
            exact[i] = True
    least = math.inf  # the least final entry so far (min_only)
    for j in range(n):  # min_only: insertion sort of the indices by bound (a NaN stays in place)
        order[j] = j
        if min_only:
            if not exact[j] and clearance[j] < least:
                least = clearance[j]
            i = j
            while i > 0 and clearance[j] < clearance[order[i - 1]]:
                order[i] = order[i - 1]
                i -= 1
            order[i] = j
    address = fromto.ctypes.data
    for j in range(n):
        i = order[j]
        if not exact[i]:
            continue
        if min_only and clearance[i] - SKIP_MARGIN > least:
            exact[i] = False
            continue
        best = math.inf
        for h in range(hull.shape[0]):
            dist = _call_geom_distance(geom_distance, m_addr, d_addr, np.int32(hull[h]), np.int32(obstacles[i]),
                                       distmax, address)
            if dist < best:
                best = dist
                for k in range(6):
                    witness[i, k] = fromto[k]
        clearance[i] = best
        if best < least:
            least = best
    for i in range(n):
        normal_force[i] = 0.0
        in_contact[i] = False


class MuJoCoClearance:
    """Signed distances hull <-> obstacles and contact forces on a ``HarbourPlant`` (module docstring).

    ``exact_within`` [m]: MuJoCo's distance query runs for the obstacles whose bounding-circle
    lower bound |c_obstacle - p_hull| - R_hull - R_obstacle is below it; the others report that
    lower bound (a true lower bound of the clearance, exact enough for the minimum and the
    near-miss events as long as ``exact_within`` exceeds the margin). ``math.inf``: always exact.
    """

    note = ""
    PREFILTER_FROM = 8  # fewer obstacles: the numpy bound costs more than it saves

    def __init__(self, plant, exact_within: float = 10.0, distmax: float = 1e4):
        self.plant = plant
        self.model, self.data = plant.model, plant.data
        self.hull_geoms = [int(g) for g in plant.hull_geoms]
        self.obstacle_geoms = [int(g) for g in plant.obstacle_geoms]
        n = len(self.obstacle_geoms)
        self.distmax = float(distmax)
        self.clearance = np.full(n, np.inf)
        self.normal_force = np.zeros(n)
        self.in_contact = np.zeros(n, dtype=bool)
        self.witness = np.zeros((n, 6))  # fromto of the nearest points (hull side, obstacle side) [m]
        self._fromto = np.zeros(6)
        self._force = np.zeros(6)
        # geom id -> obstacle index (-1: not an obstacle); geom id -> is a hull collision geom
        self._obstacle_of = np.full(self.model.ngeom, -1, dtype=np.int64)
        self._obstacle_of[self.obstacle_geoms] = np.arange(n)
        self._is_hull = np.zeros(self.model.ngeom, dtype=bool)
        self._is_hull[self.hull_geoms] = True
        self.exact_within = float(exact_within)
        self._ogeoms = np.array(self.obstacle_geoms, dtype=np.int64)
        # the plant's hull as MuJoCo collides it (scaled to the vessel at load)
        self._bound = vessel_hull_radius(getattr(plant, "dimensions", None)) + np.array(
            [o.bounding_radius for o in plant.obstacles], dtype=float)
        self.exact = np.ones(n, dtype=bool)  # which entries of the last update are exact
        self._order = np.zeros(n, dtype=np.int64)  # the kernel's visiting order (min_only)
        # the native update (mujoco_clearance_kernel): views of the mjData's arrays, the libmujoco
        # addresses; every (hull geom, obstacle geom) pair is asked once through the bindings
        # first, so that a pair MuJoCo cannot measure raises here, not inside compiled code
        self._qpos, self._geom_xpos = self.data.qpos, self.data.geom_xpos
        self._hgeoms = np.array(self.hull_geoms, dtype=np.int64)
        self._addresses = (self.model._address, self.data._address, mujoco_function_address("mj_kinematics"),
                           mujoco_function_address("mj_geomDistance"))
        mujoco.mj_kinematics(self.model, self.data)
        for og in self.obstacle_geoms:
            for hg in self.hull_geoms:
                mujoco.mj_geomDistance(self.model, self.data, hg, og, self.distmax, None)
        self._args = self.kernel_args()   # update's (made once: 2 us a step)

    def update(self, t: float = 0.0, plant_or_state=None) -> np.ndarray:
        """Clearance [m] per obstacle at the plant's current state (``t`` and the argument are
        accepted for interface symmetry; the plant's mjData is read)."""
        mujoco_clearance_kernel(*self._args)
        self.add_contacts()
        return self.clearance

    def kernel_args(self, min_only: bool = False) -> tuple:
        """The arguments of :func:`mujoco_clearance_kernel` for this monitor (the distances, the
        exact flags and witnesses written into its arrays; contacts cleared): a caller that runs
        the kernel itself (the harbor task, fused with its other per-step work) then calls
        :meth:`add_contacts`. ``min_only``: the kernel's branch and bound, for a caller that reads
        only the minimum of :attr:`clearance`, its first index and the contact test (entries of
        obstacles farther than the nearest are then their bounds, :attr:`exact` False)."""
        m_addr, d_addr, kinematics, geom_distance = self._addresses
        prefilter = math.isfinite(self.exact_within) and len(self._ogeoms) >= self.PREFILTER_FROM
        return (m_addr, d_addr, kinematics, geom_distance, self._hgeoms, self._ogeoms, self._bound, self.exact_within,
                prefilter, self.distmax, self._qpos, self._geom_xpos, self.clearance, self.exact, self.witness,
                self._fromto, self.normal_force, self.in_contact, bool(min_only), self._order)

    def add_contacts(self) -> bool:
        """The hull's contacts in ``d.contact`` into :attr:`normal_force` and :attr:`in_contact`
        (after the kernel cleared them); True when there was any contact to look at."""
        m, d = self.model, self.data
        ncon = d.ncon
        if not ncon:
            return False
        geoms = d.contact.geom[:ncon]
        for c in range(ncon):
            g1, g2 = geoms[c]
            if self._is_hull[g1]:
                i = self._obstacle_of[g2]
            elif self._is_hull[g2]:
                i = self._obstacle_of[g1]
            else:
                continue
            if i < 0:
                continue
            mujoco.mj_contactForce(m, d, c, self._force)
            self.normal_force[i] += abs(self._force[0])
            self.in_contact[i] = True
        return True

# --- numba kernels: signed distances between convex polygons (the hull footprint is convex) -----


@njit(cache=True)
def _point_segment_distance(px, py, ax, ay, bx, by):
    dx, dy = bx - ax, by - ay
    den = dx * dx + dy * dy
    w = ((px - ax) * dx + (py - ay) * dy) / den if den > 0.0 else 0.0
    if w < 0.0:
        w = 0.0
    elif w > 1.0:
        w = 1.0
    qx, qy = ax + w * dx - px, ay + w * dy - py
    return math.sqrt(qx * qx + qy * qy)


@njit(cache=True)
def point_polygon_signed_distance(poly, px, py):
    """Signed distance [m] from (px, py) to the convex counter-clockwise polygon ``poly`` (n, 2),
    negative inside."""
    n = poly.shape[0]
    best = math.inf
    inside = True
    for i in range(n):
        j = (i + 1) % n
        ax, ay, bx, by = poly[i, 0], poly[i, 1], poly[j, 0], poly[j, 1]
        if (bx - ax) * (py - ay) - (by - ay) * (px - ax) < 0.0:
            inside = False
        d = _point_segment_distance(px, py, ax, ay, bx, by)
        if d < best:
            best = d
    return -best if inside else best


@njit(cache=True)
def _axis_overlap(a, b, nx, ny):
    amin, amax, bmin, bmax = math.inf, -math.inf, math.inf, -math.inf
    for i in range(a.shape[0]):
        p = a[i, 0] * nx + a[i, 1] * ny
        amin, amax = min(amin, p), max(amax, p)
    for i in range(b.shape[0]):
        p = b[i, 0] * nx + b[i, 1] * ny
        bmin, bmax = min(bmin, p), max(bmax, p)
    return min(amax - bmin, bmax - amin)


@njit(cache=True)
def convex_signed_distance(a, b):
    """Signed distance [m] between two convex counter-clockwise polygons (n, 2) and (m, 2):
    separated, the exact distance (min over vertex-edge pairs); overlapping, minus the
    penetration depth (the smallest overlap over the edge normals: separating-axis theorem)."""
    min_overlap = math.inf
    for poly in (a, b):
        n = poly.shape[0]
        for i in range(n):
            j = (i + 1) % n
            ex, ey = poly[j, 0] - poly[i, 0], poly[j, 1] - poly[i, 1]
            norm = math.sqrt(ex * ex + ey * ey)
            if norm == 0.0:
                continue
            ov = _axis_overlap(a, b, -ey / norm, ex / norm)
            if ov < min_overlap:
                min_overlap = ov
    if min_overlap <= 0.0:
        best = math.inf
        for p, q in ((a, b), (b, a)):
            m = q.shape[0]
            for i in range(p.shape[0]):
                for j in range(m):
                    k = (j + 1) % m
                    d = _point_segment_distance(p[i, 0], p[i, 1], q[j, 0], q[j, 1], q[k, 0], q[k, 1])
                    if d < best:
                        best = d
        return best
    return -min_overlap


@njit(cache=True)
def scatter_clearances(out_circles, out_boxes, circles, boxes, clearance, in_contact):
    """The circles' and boxes' clearances into the obstacles' order; in_contact = clearance <= 0.
    Returns whether any obstacle is reached (GeometricClearance.update and the loop's hook kernel)."""
    for j in range(circles.shape[0]):
        clearance[circles[j]] = out_circles[j]
    for j in range(boxes.shape[0]):
        clearance[boxes[j]] = out_boxes[j]
    hit = False
    for i in range(clearance.shape[0]):
        in_contact[i] = clearance[i] <= 0.0
        hit = hit or in_contact[i]
    return hit


@njit(cache=True)
def footprint_clearances(body, body_radius, x, y, psi, centers, radii, boxes, box_radii, exact_within,
                         out_circles, out_boxes):
    """Clearance of the hull footprint ``body`` (convex, CCW, body frame, within ``body_radius`` of
    its origin) at pose (x, y, psi) to circles (centres (k, 2), radii (k,)) and boxes (corners
    (m, 4, 2), CCW, half-diagonals ``box_radii``) [m]. Obstacles whose bounding-circle lower bound
    exceeds ``exact_within`` get that lower bound instead of the exact distance."""
    c, s = math.cos(psi), math.sin(psi)
    n = body.shape[0]
    hull = np.empty((n, 2))
    for i in range(n):
        hull[i, 0] = x + c * body[i, 0] - s * body[i, 1]
        hull[i, 1] = y + s * body[i, 0] + c * body[i, 1]
    for i in range(centers.shape[0]):
        lower = math.hypot(centers[i, 0] - x, centers[i, 1] - y) - body_radius - radii[i]
        if lower > exact_within:
            out_circles[i] = lower
        else:
            out_circles[i] = point_polygon_signed_distance(hull, centers[i, 0], centers[i, 1]) - radii[i]
    for i in range(boxes.shape[0]):
        bx = 0.25 * (boxes[i, 0, 0] + boxes[i, 1, 0] + boxes[i, 2, 0] + boxes[i, 3, 0])
        by = 0.25 * (boxes[i, 0, 1] + boxes[i, 1, 1] + boxes[i, 2, 1] + boxes[i, 3, 1])
        lower = math.hypot(bx - x, by - y) - body_radius - box_radii[i]
        if lower > exact_within:
            out_boxes[i] = lower
        else:
            out_boxes[i] = convex_signed_distance(hull, boxes[i])



def _penetration(a, b) -> float:
    """Indicative penetration depth [m] of two overlapping polygons: the deepest vertex of one
    inside the other, measured to the other's boundary."""
    depth = 0.0
    for inner, outer in ((a, b), (b, a)):
        pts = shapely.points(np.asarray(inner.exterior.coords))
        inside = shapely.contains(outer, pts)
        if inside.any():
            depth = max(depth, float(np.max(shapely.distance(outer.exterior, pts[inside]))))
    return depth


class GeometricClearance:
    """Clearance from the geometry for plants without contact physics (module docstring).

    ``obstacles``: the :class:`~usv_mj.obstacle_tables.ObstacleSpec` tuple; moving obstacles are
    placed at ``center + velocity t``. ``dimensions``: the vessel's main dimensions (its
    footprint: the collision geoms scaled as the MuJoCo plant scales them); None: the paper hull.
    """

    note = ANALYTIC_NOTE

    def __init__(self, obstacles, resolution: int = 16, method: str = "numba", exact_within: float = 10.0,
                 dimensions=None):
        if method not in ("numba", "shapely"):
            raise ValueError(f"GeometricClearance: method must be 'numba' or 'shapely', got {method!r}")
        self.method = method
        self.obstacles = tuple(obstacles)
        n = len(self.obstacles)
        # the vessel's footprint (``dimensions``: usv_mj.vessels.Dimensions; None: the paper hull's)
        self.footprint = shapely.orient_polygons(hull_footprint(resolution, vessel_collision_geoms(dimensions)))
        self._vertices = np.asarray(self.footprint.exterior.coords)  # body frame, closed ring
        self._body = np.ascontiguousarray(self._vertices[:-1])
        if not np.isclose(shapely.convex_hull(self.footprint).area, self.footprint.area, rtol=1e-9):
            raise ValueError("GeometricClearance: the hull footprint must be convex for the numba kernels")
        self.clearance = np.full(n, np.inf)
        self.normal_force = np.zeros(n)        # never any: no contact physics
        self.in_contact = np.zeros(n, dtype=bool)
        self._circles = np.array([i for i, o in enumerate(self.obstacles) if o.kind == "circle"], dtype=np.int64)
        self._boxes = np.array([i for i, o in enumerate(self.obstacles) if o.kind == "box"], dtype=np.int64)
        self._radius = np.array([self.obstacles[i].radius for i in self._circles])
        self._center0 = np.array([o.center for o in self.obstacles], dtype=float).reshape(n, 2)
        self._velocity = np.array([o.velocity for o in self.obstacles], dtype=float).reshape(n, 2)
        self._box_shapes0 = np.array([self.obstacles[i].shape(0.0) for i in self._boxes], dtype=object)
        self._any_moving_box = any(self.obstacles[i].moving for i in self._boxes)
        self._corners0 = np.zeros((len(self._boxes), 4, 2))
        for j, i in enumerate(self._boxes):
            o = self.obstacles[i]
            c, s = math.cos(o.yaw), math.sin(o.yaw)
            hl, hw = 0.5 * o.size[0], 0.5 * o.size[1]
            for k, (px, py) in enumerate(((-hl, -hw), (hl, -hw), (hl, hw), (-hl, hw))):  # CCW
                self._corners0[j, k] = (o.center[0] + c * px - s * py, o.center[1] + s * px + c * py)
        self.exact_within = float(exact_within)
        self._body_radius = float(np.max(np.hypot(self._body[:, 0], self._body[:, 1])))
        self._box_radii = np.array([self.obstacles[i].bounding_radius for i in self._boxes])
        self._out_c = np.zeros(len(self._circles))
        self._out_b = np.zeros(len(self._boxes))

    def hull_at(self, x: float, y: float, psi: float):
        """The hull footprint at pose (x [m], y [m], psi [rad]) as a shapely polygon."""
        c, s = math.cos(psi), math.sin(psi)
        v = self._vertices
        return shapely.polygons(np.c_[x + c * v[:, 0] - s * v[:, 1], y + s * v[:, 0] + c * v[:, 1]])

    def update(self, t: float, plant_or_state) -> np.ndarray:
        """Clearance [m] per obstacle at time t for the plant (its ``state``) or a state 6-vector."""
        state = getattr(plant_or_state, "state", plant_or_state)
        if self.method == "shapely":
            return self.update_shapely(t, state)
        centers = self._center0[self._circles] + self._velocity[self._circles] * t
        boxes = self._corners0
        if self._any_moving_box:
            boxes = boxes + (self._velocity[self._boxes] * t)[:, None, :]
        footprint_clearances(self._body, self._body_radius, float(state[0]), float(state[1]), float(state[2]),
                             centers, self._radius, boxes, self._box_radii, self.exact_within, self._out_c, self._out_b)
        scatter_clearances(self._out_c, self._out_b, self._circles, self._boxes, self.clearance, self.in_contact)
        return self.clearance

    def kernel_args(self) -> tuple:
        """The monitor's arguments of :func:`usv_mj.obstacles.native_step.geometric_obstacle_step`
        (standing obstacles only: the circles' centres at any t), its arrays written in place."""
        if self.method != "numba" or self._velocity.any():
            raise ValueError("GeometricClearance.kernel_args: the numba method of standing obstacles only")
        centers = np.ascontiguousarray(self._center0[self._circles])
        return (self._body, self._body_radius, centers, self._radius, self._corners0, self._box_radii,
                float(self.exact_within), self._out_c, self._out_b, self._circles, self._boxes, self.clearance,
                self.in_contact)

    def update_shapely(self, t: float, state) -> np.ndarray:
        """The same with shapely (the reference for the numba kernels; slower)."""
        hull = self.hull_at(float(state[0]), float(state[1]), float(state[2]))
        out = self.clearance
        if len(self._circles):
            centers = self._center0[self._circles] + self._velocity[self._circles] * t
            pts = shapely.points(centers)
            d = shapely.distance(hull, pts)
            out[self._circles] = d - self._radius
            inside = d <= 0.0
            if inside.any():
                out[self._circles[inside]] = -(self._radius[inside] + shapely.distance(hull.exterior, pts[inside]))
        if len(self._boxes):
            boxes = self._box_shapes0
            if self._any_moving_box:
                shift = self._velocity[self._boxes] * t
                boxes = np.array([affinity.translate(b, dx, dy) for b, (dx, dy) in zip(boxes, shift)], dtype=object)
            d = shapely.distance(hull, boxes)
            out[self._boxes] = d
            for j in np.flatnonzero(d <= 0.0):
                out[self._boxes[j]] = -_penetration(hull, boxes[j])
        self.in_contact[:] = out <= 0.0
        return out


def make_clearance_monitor(plant, obstacles, dimensions=None):
    """The monitor that fits ``plant``: :class:`MuJoCoClearance` when it has ``obstacle_geoms``
    (a :class:`~usv_mj.obstacles.compose.HarbourPlant`), :class:`GeometricClearance` of the
    vessel's ``dimensions`` otherwise."""
    if hasattr(plant, "obstacle_geoms"):
        return MuJoCoClearance(plant)
    return GeometricClearance(obstacles, dimensions=dimensions)
