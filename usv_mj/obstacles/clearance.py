"""Clearance between the hull and every obstacle, and the contacts, once per control step.

Two monitors with one interface, ``update(t, plant_or_state) -> clearance`` (a float64 array, one
signed distance [m] per obstacle, negative = penetration) plus the attributes ``normal_force`` [N]
(sum of the normal forces of the hull's contacts with each obstacle at this step, 0 without
contact) and ``in_contact`` (bool per obstacle):

- :class:`MuJoCoClearance`: MuJoCo's own distance query, ``mujoco.mj_geomDistance``, between each of
  the hull's collision geoms and each obstacle geom of a :class:`~usv_mj.plants.harbour.HarbourPlant`
  (the minimum over the hull geoms), after ``mj_kinematics`` so that the poses are those of the
  current state; contacts from ``d.contact`` with ``mujoco.mj_contactForce``.
- :class:`GeometricClearance`: the same quantity from the geometry (shapely) for plants without
  contact physics (the analytic plant): the hull's collision footprint
  (:func:`~usv_mj.scene.hull.hull_footprint`) at the plant's pose against each obstacle's
  section. Separated: the exact polygon distance (circles exactly: distance to the centre minus
  the radius; the kernels of usv_mj.obstacles.footprint_kernels). Overlapping: minus an estimate of the penetration depth (the deepest vertex of one
  shape inside the other, circles exactly), so the sign is right and the magnitude is indicative.
  The analytic plant passes through obstacles; :attr:`GeometricClearance.note` says so.

Both report, for obstacles farther than ``exact_within`` (10 m) by a bounding-circle test, that
lower bound instead of the exact distance (cheap with 50 obstacles; ``math.inf`` = always exact).

Broad phase (``broad_phase=True``, what a run's monitor uses: :func:`make_clearance_monitor`): a
step's work scales with the obstacles within reach, not with all of them. The standing obstacles
sit in a uniform grid (:class:`usv_mj.obstacles.broad_phase.StandingGrid`, built once: cells of
about the reach, each listing the obstacles whose bounding box overlaps it); a step looks only at
the cells that the square of half side ``exact_within + R_hull`` about the hull overlaps, and
measures exactly those of their obstacles whose bounding-circle lower bound is under
``exact_within`` (the same test and the same distance as without the broad phase, so these entries
are bit for bit the same). Every other entry is **NaN, meaning "beyond reach": not measured, its
clearance is at least ``exact_within``** (the bounding-circle bound says so; :data:`BEYOND_REACH`).
Nothing is claimed that was not measured: the minimum over the obstacles, its obstacle, the near
misses (margin < ``exact_within``) and the contacts are those of the all-pairs update whenever the
minimum is within reach (a run whose hull never comes within ``exact_within`` of any obstacle has
no measured minimum). Moving obstacles are tested all-pairs (they are few; a moving grid is not
worth it) with the same rule.
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

from usv_mj.support.native_mujoco import call_model_data, mujoco_function_address

from usv_mj.obstacles.broad_phase import StandingGrid, grid_candidates
from usv_mj.scene.hull import hull_footprint, vessel_collision_geoms, vessel_hull_radius
from usv_mj.obstacles.footprint_kernels import footprint_clearances, footprint_clearances_broad, scatter_clearances

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
                            in_contact, min_only, order, broad, grid_geometry, grid_shape, grid_start, grid_items,
                            moving, seen, stamp, active, n_active, touched, n_touched):
    """:meth:`MuJoCoClearance.update` but the contacts, natively: ``mj_kinematics`` (at address
    ``kinematics``), the bounding-circle prefilter (when ``prefilter``) and ``mj_geomDistance`` (at
    ``geom_distance``) of every hull geom against every obstacle left to do, in the same order.

    ``min_only`` (branch and bound, for a caller that reads only the minimum, its argmin and
    whether any entry is <= 0): the obstacles are visited by increasing bound (``order``, scratch
    of n int64) and one whose bound exceeds the least clearance so far by :data:`SKIP_MARGIN` keeps
    its bound (not exact): its distance is larger than that least one, so the minimum, its first
    index and the contact test are those of the full update.

    ``broad`` (the broad phase, module docstring): the candidates of the standing obstacles' grid
    (``grid_*``, :class:`StandingGrid`) and the ``moving`` obstacles are tested, the entries of the
    last update (``active[:n_active[0]]``) and the contacts :meth:`MuJoCoClearance.add_contacts`
    set (``touched[:n_touched[0]]``) are cleared first; everything else stays NaN (beyond reach)."""
    call_model_data(kinematics, m_addr, d_addr)
    if broad:
        _mujoco_broad(m_addr, d_addr, geom_distance, hull, obstacles, bound, exact_within, distmax, qpos, geom_xpos,
                      clearance, exact, witness, fromto, normal_force, in_contact, order, grid_geometry, grid_shape,
                      grid_start, grid_items, moving, seen, stamp, active, n_active, touched, n_touched)
        return
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
    for j in range(n):
        i = order[j]
        if not exact[i]:
            continue
        if min_only and clearance[i] - SKIP_MARGIN > least:
            exact[i] = False
            continue
        best = _hull_distance(m_addr, d_addr, geom_distance, hull, obstacles[i], distmax, fromto, witness, i)
        clearance[i] = best
        if best < least:
            least = best
    for i in range(n):
        normal_force[i] = 0.0
        in_contact[i] = False
    n_touched[0] = 0


@njit(cache=True)
def _hull_distance(m_addr, d_addr, geom_distance, hull, geom, distmax, fromto, witness, i):
    """min over the hull geoms of mj_geomDistance to ``geom`` [m], its fromto into witness[i]."""
    address = fromto.ctypes.data
    best = math.inf
    for h in range(hull.shape[0]):
        dist = _call_geom_distance(geom_distance, m_addr, d_addr, np.int32(hull[h]), np.int32(geom), distmax, address)
        if dist < best:
            best = dist
            for k in range(6):
                witness[i, k] = fromto[k]
    return best


@njit(cache=True)
def _mujoco_broad(m_addr, d_addr, geom_distance, hull, obstacles, bound, exact_within, distmax, qpos, geom_xpos,
                  clearance, exact, witness, fromto, normal_force, in_contact, scratch, grid_geometry, grid_shape,
                  grid_start, grid_items, moving, seen, stamp, active, n_active, touched, n_touched):
    """The broad phase of :func:`mujoco_clearance_kernel` (its docstring); the same bound and the
    same distance as its all-pairs loop, for the candidates only."""
    for j in range(n_active[0]):
        i = active[j]
        clearance[i] = np.nan
        exact[i] = False
    for j in range(n_touched[0]):
        i = touched[j]
        normal_force[i] = 0.0
        in_contact[i] = False
    n_touched[0] = 0
    count = grid_candidates(grid_geometry, grid_shape, grid_start, grid_items, qpos[0], qpos[1], seen, stamp, scratch)
    for j in range(moving.shape[0]):
        scratch[count] = moving[j]
        count += 1
    na = 0
    for j in range(count):
        i = scratch[j]
        rx = geom_xpos[obstacles[i], 0] - qpos[0]
        ry = geom_xpos[obstacles[i], 1] - qpos[1]
        lower = math.sqrt(rx * rx + ry * ry) - bound[i]
        if lower < exact_within:
            clearance[i] = _hull_distance(m_addr, d_addr, geom_distance, hull, obstacles[i], distmax, fromto, witness, i)
            exact[i] = True
            active[na] = i
            na += 1
    n_active[0] = na


class MuJoCoClearance:
    """Signed distances hull <-> obstacles and contact forces on a ``HarbourPlant`` (module docstring).

    ``exact_within`` [m]: MuJoCo's distance query runs for the obstacles whose bounding-circle
    lower bound |c_obstacle - p_hull| - R_hull - R_obstacle is below it; the others report that
    lower bound (a true lower bound of the clearance, exact enough for the minimum and the
    near-miss events as long as ``exact_within`` exceeds the margin). ``math.inf``: always exact.
    ``broad_phase``: the grid of the module docstring (at least :data:`PREFILTER_FROM` obstacles
    and a finite ``exact_within``): the obstacles out of reach are NaN instead of their bound, and
    a step costs what the obstacles within reach cost.
    """

    note = ""
    PREFILTER_FROM = 8  # fewer obstacles: the numpy bound costs more than it saves

    def __init__(self, plant, exact_within: float = 10.0, distmax: float = 1e4, broad_phase: bool = False):
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
        hull_r = vessel_hull_radius(getattr(plant, "dimensions", None))
        self._bound = hull_r + np.array([o.bounding_radius for o in plant.obstacles], dtype=float)
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
        # the broad phase (module docstring): the standing obstacles' grid from their geoms' poses
        # (world-body geoms: constant), the moving ones tested all-pairs
        self.broad_phase = (bool(broad_phase) and math.isfinite(self.exact_within)
                            and n >= self.PREFILTER_FROM)
        mocap = np.asarray(getattr(plant, "obstacle_mocap", np.full(n, -1)), dtype=np.int64).reshape(-1)
        moving = np.flatnonzero(mocap >= 0) if len(mocap) == n else np.zeros(0, np.int64)
        standing = np.setdiff1d(np.arange(n), moving)
        self._moving = moving.astype(np.int64)
        self._grid = StandingGrid(self._geom_xpos[self._ogeoms[standing], :2], self._bound[standing] - hull_r,
                                  self.exact_within + hull_r, standing)
        self._seen = np.zeros(n, np.int64)
        self._stamp = np.zeros(1, np.int64)
        self._active = np.zeros(n, np.int64)
        self._n_active = np.zeros(1, np.int64)
        self._touched = np.zeros(n, np.int64)
        self._n_touched = np.zeros(1, np.int64)
        if self.broad_phase:
            self.clearance[:] = np.nan
            self.exact[:] = False
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
        broad = self.broad_phase and not min_only
        return (m_addr, d_addr, kinematics, geom_distance, self._hgeoms, self._ogeoms, self._bound, self.exact_within,
                prefilter, self.distmax, self._qpos, self._geom_xpos, self.clearance, self.exact, self.witness,
                self._fromto, self.normal_force, self.in_contact, bool(min_only), self._order, broad,
                *self._grid.args, self._moving, self._seen, self._stamp, self._active, self._n_active, self._touched,
                self._n_touched)

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
            if not self.in_contact[i]:   # what the next update clears (the broad phase clears only these)
                self._touched[self._n_touched[0]] = i
                self._n_touched[0] += 1
            self.normal_force[i] += abs(self._force[0])
            self.in_contact[i] = True
        return True

# --- numba kernels: signed distances between convex polygons (the hull footprint is convex) -----


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

    ``obstacles``: the :class:`~usv_mj.scenario.obstacles.ObstacleSpec` tuple; moving obstacles are
    placed at ``center + velocity t``. ``dimensions``: the vessel's main dimensions (its
    footprint: the collision geoms scaled as the MuJoCo plant scales them); None: the paper hull.
    """

    note = ANALYTIC_NOTE

    def __init__(self, obstacles, resolution: int = 16, method: str = "numba", exact_within: float = 10.0,
                 dimensions=None, broad_phase: bool = False):
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
        # the broad phase (module docstring; the numba method): a grid over the standing obstacles
        # (their bounding circles about their centres at t = 0), the moving ones all-pairs
        self.broad_phase = (bool(broad_phase) and method == "numba" and math.isfinite(self.exact_within)
                            and n >= MuJoCoClearance.PREFILTER_FROM)
        self._kind = np.zeros(n, np.int64)
        self._slot = np.zeros(n, np.int64)
        self._kind[self._boxes] = 1
        self._slot[self._circles] = np.arange(len(self._circles))
        self._slot[self._boxes] = np.arange(len(self._boxes))
        radius = np.array([o.bounding_radius for o in self.obstacles], dtype=float).reshape(n)
        center = self._center0.copy()
        if len(self._boxes):
            center[self._boxes] = self._corners0.mean(axis=1)  # the kernel's bound is about the corners' mean
        moving = np.array([i for i, o in enumerate(self.obstacles) if o.moving], dtype=np.int64)
        standing = np.setdiff1d(np.arange(n), moving)
        self._moving = moving
        self._grid = StandingGrid(center[standing], radius[standing], self.exact_within + self._body_radius, standing)
        self._seen = np.zeros(n, np.int64)
        self._stamp = np.zeros(1, np.int64)
        self._scratch = np.zeros(n, np.int64)
        self._active = np.zeros(n, np.int64)
        self._n_active = np.zeros(1, np.int64)
        if self.broad_phase:
            self.clearance[:] = np.nan

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
        if self.broad_phase:
            footprint_clearances_broad(self._body, self._body_radius, float(state[0]), float(state[1]),
                                       float(state[2]), centers, self._radius, boxes, self._box_radii,
                                       self.exact_within, *self._broad_args())
            return self.clearance
        footprint_clearances(self._body, self._body_radius, float(state[0]), float(state[1]), float(state[2]),
                             centers, self._radius, boxes, self._box_radii, self.exact_within, self._out_c, self._out_b)
        scatter_clearances(self._out_c, self._out_b, self._circles, self._boxes, self.clearance, self.in_contact)
        return self.clearance

    def _broad_args(self) -> tuple:
        """:func:`footprint_clearances_broad`'s arguments after ``exact_within``."""
        return (self._kind, self._slot, *self._grid.args, self._moving, self._seen, self._stamp, self._scratch,
                self._active, self._n_active, self.clearance, self.in_contact)

    def kernel_args(self) -> tuple:
        """The monitor's arguments of :func:`usv_mj.obstacles.native_step.geometric_obstacle_step`
        (standing obstacles only: the circles' centres at any t), its arrays written in place."""
        if self.method != "numba" or self._velocity.any():
            raise ValueError("GeometricClearance.kernel_args: the numba method of standing obstacles only")
        centers = np.ascontiguousarray(self._center0[self._circles])
        return (self._body, self._body_radius, centers, self._radius, self._corners0, self._box_radii,
                float(self.exact_within), self._out_c, self._out_b, self._circles, self._boxes, self.clearance,
                self.in_contact, self.broad_phase, *self._broad_args()[:-2])

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
    (a :class:`~usv_mj.plants.harbour.HarbourPlant`), :class:`GeometricClearance` of the
    vessel's ``dimensions`` otherwise; both with the broad phase (a run's monitor: its log's far
    entries are NaN, module docstring)."""
    if hasattr(plant, "obstacle_geoms"):
        return MuJoCoClearance(plant, broad_phase=True)
    return GeometricClearance(obstacles, dimensions=dimensions, broad_phase=True)
