"""Reference trajectories for the tracking controllers (docs/model.md §4 and scenario ``[trajectory]``).

Every reference is a unicycle-like path: position (x_d, y_d), heading psi_d along the path, yaw rate
r_d = psi_d_dot and surge speed u_d (v_d = 0). ``reference.evaluate(t)`` returns the vector of
:data:`usv_mj.core.layouts.REF_VECTOR_FIELDS` = (x_d, y_d, psi_d, x_d_dot, y_d_dot, r_d, u_d,
x_d_ddot, y_d_ddot, r_d_dot) in m, rad, m/s, rad/s, m/s^2, rad/s^2 (the first 7 are the record's
reference columns, :data:`~usv_mj.core.layouts.REF_FIELDS`); the returned array is the reference's
own buffer (copy it to keep it).

The accelerations are closed forms of the unicycle, d/dt of (u cos psi, u sin psi):
x_d_ddot = u_dot cos psi - u r sin psi, y_d_ddot = u_dot sin psi + u r cos psi, with each kind's own
u_dot and r_dot = d r_d / dt (:func:`unicycle_out`; docs/controllers.md writes each kind's out).
A pose returns (x, y, psi, r, u, u_dot, r_dot); a plug-in's ``pose`` that returns the first five
only leaves the accelerations unknown: NaN (a law that reads them then says so by its NaN force).

A new trajectory kind is a :class:`Reference` subclass (or any object with ``evaluate(t)``) and
a typed options dataclass (the keys of its ``[trajectory]`` table), registered with
``@TRAJECTORIES.register(kind, options=Options)`` on a ``from_scenario(options, scenario, *,
duration)`` classmethod or a factory of that signature (:mod:`usv_mj.core.registry`; the built-ins
below are registered the same way).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from usv_mj.core.layouts import N_REF
from usv_mj.core.registry import TRAJECTORIES
from usv_mj.physics.ship import wrap_angle


class Reference:
    """Base class: subclasses implement :meth:`pose` returning (x, y, psi, r, u, u_dot, r_dot)
    [m, m, rad, rad/s, m/s, m/s^2, rad/s^2] (or the first five: the accelerations are then NaN).

    A built-in reference's ``pose`` is an njit function of this module (one implementation: its
    kernel for the compiled loop composes the same function with :func:`unicycle_out`); a subclass
    that overrides ``pose`` (or any other method) runs in the Python loop (usv_mj.core.kernels).
    """

    kind = "base"

    def __init__(self) -> None:
        self._out = np.zeros(N_REF)

    def pose(self, t: float) -> tuple:
        raise NotImplementedError

    def evaluate(self, t: float) -> np.ndarray:
        p = self.pose(t)
        if len(p) == 5:   # a pose without its accelerations (a plug-in's): unknown, NaN
            return unicycle_out(self._out, *p, math.nan, math.nan)
        return unicycle_out(self._out, *p)

    def sample(self, times) -> np.ndarray:
        """The reference at many times, shape (len(times), N_REF)."""
        return np.array([self.evaluate(float(t)).copy() for t in np.asarray(times, dtype=float)])


@njit(cache=True)
def unicycle_out(out, x, y, psi, r, u, u_dot, r_dot):
    """The reference vector (REF_VECTOR_FIELDS) of a unicycle pose, written into ``out`` (returned):
    (x, y, psi, u cos psi, u sin psi, r, u, u_dot cos psi - u r sin psi, u_dot sin psi + u r cos psi,
    r_dot) [m, m, rad, m/s, m/s, rad/s, m/s, m/s^2, m/s^2, rad/s^2]. :meth:`Reference.evaluate`."""
    c, s = math.cos(psi), math.sin(psi)
    out[0], out[1], out[2] = x, y, psi
    out[3], out[4] = u * c, u * s
    out[5], out[6] = r, u
    out[7] = u_dot * c - u * r * s
    out[8] = u_dot * s + u * r * c
    out[9] = r_dot
    return out


@njit(cache=True)
def hermite_point(w, x0, y0, p0, x1, y1, p1, h, v):
    """(x, y) at w in [0, 1] across one cell of a cubic Hermite interpolant: nodes (x0, y0), (x1, y1)
    [m] a parameter step ``h`` apart, with tangents v (cos p, sin p) per unit of the parameter
    (the paper's table: h [s], v = u_d [m/s]; a path table: h = ds [m], v = 1). The one Hermite
    interpolation of the package (the paper's reference and usv_mj.references.planner's paths)."""
    h00 = 2 * w**3 - 3 * w**2 + 1
    h10 = w**3 - 2 * w**2 + w
    h01 = -2 * w**3 + 3 * w**2
    h11 = w**3 - w**2
    c0, s0 = math.cos(p0), math.sin(p0)
    c1, s1 = math.cos(p1), math.sin(p1)
    x = h00 * x0 + h10 * h * v * c0 + h01 * x1 + h11 * h * v * c1
    y = h00 * y0 + h10 * h * v * s0 + h01 * y1 + h11 * h * v * s1
    return x, y


@njit(cache=True)
def paper_heading(t, u_d, t_turn, t_phase, amplitude, period):
    """psi_d and r_d of docs/model.md §4: r_d = -A sin(pi (t - t_phase)/P) for t >= t_turn, 0 before.

    Closed form for t >= t_turn: psi_d = (A P/pi)[cos(pi (t - t_phase)/P) - cos(pi (t_turn - t_phase)/P)].
    """
    if t < t_turn:
        return 0.0, 0.0
    w = math.pi / period
    r = -amplitude * math.sin(w * (t - t_phase))
    psi = amplitude / w * (math.cos(w * (t - t_phase)) - math.cos(w * (t_turn - t_phase)))
    return psi, r


@njit(cache=True)
def paper_yaw_acceleration(t, t_turn, t_phase, amplitude, period):
    """r_d_dot = -A (pi/P) cos(pi (t - t_phase)/P) for t >= t_turn, 0 before (the derivative of
    :func:`paper_heading`'s r_d; at t_turn r_d jumps, as printed, and this is its right limit)."""
    if t < t_turn:
        return 0.0
    w = math.pi / period
    return -amplitude * w * math.cos(w * (t - t_phase))


@njit(cache=True)
def paper_pose(t, tab_x, tab_y, tab_psi, h, u_d, t_turn, t_phase, amplitude, period):
    """:meth:`PaperReference.pose`: the heading in closed form, the position from the table (Hermite
    with exact end slopes u_d (cos, sin) psi; past the table's last cell, its cubic); u_dot = 0 and
    r_dot of :func:`paper_yaw_acceleration`."""
    psi, r = paper_heading(t, u_d, t_turn, t_phase, amplitude, period)
    i = int(t / h)
    if i >= tab_x.shape[0] - 1:
        i = tab_x.shape[0] - 2
    x, y = hermite_point(t / h - i, tab_x[i], tab_y[i], tab_psi[i], tab_x[i + 1], tab_y[i + 1], tab_psi[i + 1], h,
                         u_d)
    return x, y, psi, r, u_d, 0.0, paper_yaw_acceleration(t, t_turn, t_phase, amplitude, period)


@njit(cache=True)
def paper_kernel(t, tab_x, tab_y, tab_psi, h, u_d, t_turn, t_phase, amplitude, period, out):
    """:meth:`PaperReference.evaluate` natively (usv_mj.core.kernels; the loop checks the table's t_max)."""
    return unicycle_out(out, *paper_pose(t, tab_x, tab_y, tab_psi, h, u_d, t_turn, t_phase, amplitude, period))


@njit(cache=True)
def line_pose(t, x0, y0, heading, speed):
    """:meth:`LineReference.pose`: from (x0, y0) [m] along ``heading`` [rad] at ``speed`` [m/s]
    (no acceleration: u_dot = r_dot = 0)."""
    d = speed * t
    return x0 + d * math.cos(heading), y0 + d * math.sin(heading), heading, 0.0, speed, 0.0, 0.0


@njit(cache=True)
def line_kernel(t, x0, y0, heading, speed, out):
    """:class:`LineReference` natively."""
    return unicycle_out(out, *line_pose(t, x0, y0, heading, speed))


@njit(cache=True)
def circle_pose(t, cx, cy, radius, speed, theta0, direction):
    """:meth:`CircleReference.pose`: polar angle theta0 + w t about (cx, cy), w = direction speed/radius
    (constant u and r: u_dot = r_dot = 0; the centripetal x_d_ddot, y_d_ddot = u w (-sin, cos) psi_d)."""
    w = direction * speed / radius
    th = theta0 + w * t
    return cx + radius * math.cos(th), cy + radius * math.sin(th), th + direction * math.pi / 2, w, speed, 0.0, 0.0


@njit(cache=True)
def circle_kernel(t, cx, cy, radius, speed, theta0, direction, out):
    """:class:`CircleReference` natively."""
    return unicycle_out(out, *circle_pose(t, cx, cy, radius, speed, theta0, direction))


@njit(cache=True)
def waypoint_pose(t, speed, starts, pieces):
    """:meth:`WaypointReference.pose`; ``pieces`` rows (kind 0 line / 1 arc, then the piece's
    numbers: line x0, y0, heading, length; arc cx, cy, theta0, sign, radius, length), ``starts``
    their start arc lengths [m]. Past the last piece (a line: the path never ends on an arc) the
    reference goes on along it. Inside a piece u and r are constant (u_dot = r_dot = 0); where a
    line meets an arc r_d jumps by speed/radius (r_d_dot is a Dirac there, not represented)."""
    s = speed * t
    i = 0  # bisect_right(starts, s) - 1, at least 0
    for j in range(starts.shape[0]):
        if starts[j] <= s:
            i = j
        else:
            break
    ds = s - starts[i]
    pc = pieces[i]
    if pc[0] == 0.0:
        h = pc[3]
        return pc[1] + ds * math.cos(h), pc[2] + ds * math.sin(h), h, 0.0, speed, 0.0, 0.0
    th = pc[3] + pc[4] * ds / pc[5]
    return (pc[1] + pc[5] * math.cos(th), pc[2] + pc[5] * math.sin(th), th + pc[4] * math.pi / 2,
            pc[4] * speed / pc[5], speed, 0.0, 0.0)


@njit(cache=True)
def waypoint_kernel(t, speed, starts, pieces, out):
    """:class:`WaypointReference` natively."""
    return unicycle_out(out, *waypoint_pose(t, speed, starts, pieces))


@functools.lru_cache(maxsize=8)
def _paper_table(n, grid, speed, t_turn, t_phase, amplitude, period):
    """x_d, y_d, psi_d of :class:`PaperReference` on ``n`` points of ``grid`` [s], and the last time."""
    times = np.arange(n) * grid
    nodes, weights = np.polynomial.legendre.leggauss(8)

    def heading(t):
        return paper_heading(t, speed, t_turn, t_phase, amplitude, period)[0]

    psi = np.array([heading(t) for t in times])
    dx = np.zeros(n)
    dy = np.zeros(n)
    for i in range(n - 1):
        tq = times[i] + (nodes + 1) * 0.5 * grid
        pq = np.array([heading(t) for t in tq])
        dx[i + 1] = 0.5 * grid * speed * np.dot(weights, np.cos(pq))
        dy[i + 1] = 0.5 * grid * speed * np.dot(weights, np.sin(pq))
    return np.cumsum(dx), np.cumsum(dy), psi, times[-1]


class PaperReference(Reference):
    """The paper's reference (docs/model.md §4): u_d = 0.6 m/s, straight until 110 s, then
    r_d = -0.006 sin(pi (t - 100)/500) (the jump of r_d at 110 s is as printed).

    x_d, y_d integrate u_d (cos psi_d, sin psi_d) from (0, 0): tabulated once with 8-point
    Gauss-Legendre quadrature on a 0.05 s grid and read back by cubic Hermite interpolation (error
    far below 1e-9 m). Checkpoints: t = 200 s: (119.804, -3.582, -0.1805).
    """

    kind = "paper"
    GRID = 0.05

    def __init__(self, duration: float = 300.0, speed: float = 0.6, t_turn: float = 110.0,
                 t_phase: float = 100.0, amplitude: float = 0.006, period: float = 500.0):
        super().__init__()
        self.speed, self.t_turn, self.t_phase = speed, t_turn, t_phase
        self.amplitude, self.period = amplitude, period
        n = int(math.ceil((max(duration, 1.0) + 10.0) / self.GRID)) + 1
        # the table is the same for every reference of these values (a sweep builds one per run):
        # made once per process, each reference its own copy
        x, y, psi, self.t_max = _paper_table(n, self.GRID, speed, t_turn, t_phase, amplitude, period)
        self._x, self._y, self._psi = x.copy(), y.copy(), psi.copy()

    def pose(self, t):
        if t > self.t_max:
            raise ValueError(f"reference asked at t = {t:.3f} s beyond its table ({self.t_max:.1f} s)")
        return paper_pose(t, self._x, self._y, self._psi, self.GRID, self.speed, self.t_turn, self.t_phase,
                          self.amplitude, self.period)

    def kernel(self):
        from usv_mj.core.kernels import Kernel

        return Kernel(paper_kernel, (self._x, self._y, self._psi, self.GRID, self.speed, self.t_turn, self.t_phase,
                                     self.amplitude, self.period, self._out), state=(9,))


class LineReference(Reference):
    """A straight line from ``start`` [m] at ``heading_deg`` [deg], run at ``speed`` [m/s]."""

    kind = "line"

    def __init__(self, start=(0.0, 0.0), heading_deg: float = 0.0, speed: float = 0.6):
        super().__init__()
        self.start = (float(start[0]), float(start[1]))
        self.heading = math.radians(heading_deg)
        self.speed = float(speed)

    def kernel(self):
        from usv_mj.core.kernels import Kernel

        return Kernel(line_kernel, (self.start[0], self.start[1], self.heading, self.speed, self._out), state=(4,))

    def pose(self, t):
        return line_pose(t, self.start[0], self.start[1], self.heading, self.speed)


class CircleReference(Reference):
    """A circle about ``center`` [m] of ``radius`` [m], counter-clockwise (``clockwise`` flips it),
    starting at polar angle ``start_angle_deg`` (default -90: the bottom of the circle, heading +x)."""

    kind = "circle"

    def __init__(self, center=(0.0, 20.0), radius: float = 20.0, speed: float = 0.6,
                 start_angle_deg: float = -90.0, clockwise: bool = False):
        super().__init__()
        if not radius > 0:
            raise ValueError(f"trajectory.radius must be > 0, got {radius!r}")
        self.center = (float(center[0]), float(center[1]))
        self.radius, self.speed = float(radius), float(speed)
        self.theta0 = math.radians(start_angle_deg)
        self.direction = -1.0 if clockwise else 1.0

    def kernel(self):
        from usv_mj.core.kernels import Kernel

        return Kernel(circle_kernel, (self.center[0], self.center[1], self.radius, self.speed, self.theta0,
                                      self.direction, self._out), state=(6,))

    def pose(self, t):
        return circle_pose(t, self.center[0], self.center[1], self.radius, self.speed, self.theta0, self.direction)


class WaypointReference(Reference):
    """Straight legs through ``points`` [m] joined by circular arcs of ``turn_radius`` [m], so that
    psi_d is continuous and r_d = +-speed/turn_radius in the turns. After the last point the
    reference goes on straight along the last leg."""

    kind = "waypoints"

    def __init__(self, points, speed: float = 0.6, turn_radius: float = 5.0):
        super().__init__()
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
            raise ValueError("trajectory.points must be a list of at least two [x, y] pairs")
        if np.any(np.linalg.norm(np.diff(pts, axis=0), axis=1) <= 0):
            raise ValueError("trajectory.points has two equal consecutive points")
        if not turn_radius > 0:
            raise ValueError(f"trajectory.turn_radius must be > 0, got {turn_radius!r}")
        self.speed = float(speed)
        headings = [math.atan2(*(pts[i + 1] - pts[i])[::-1]) for i in range(len(pts) - 1)]
        # pieces: ("line", x0, y0, heading, length) or ("arc", cx, cy, theta0, sign, radius, length)
        pieces = []
        cursor = pts[0].copy()
        for i in range(len(pts) - 1):
            end = pts[i + 1].copy()
            h = headings[i]
            if i + 1 < len(headings):
                turn = float(wrap_angle(headings[i + 1] - h))
                d = turn_radius * math.tan(abs(turn) / 2)
                leg_in = np.linalg.norm(pts[i + 1] - cursor)
                leg_out = np.linalg.norm(pts[i + 2] - pts[i + 1]) / 2
                if d > min(leg_in, leg_out):
                    raise ValueError(
                        f"trajectory.turn_radius {turn_radius} m is too large for the turn at point {i + 1}")
                end = pts[i + 1] - d * np.array([math.cos(h), math.sin(h)])
            length = float(np.linalg.norm(end - cursor))
            pieces.append(("line", cursor[0], cursor[1], h, length))
            if i + 1 < len(headings) and abs(turn) > 1e-12:
                sign = 1.0 if turn > 0 else -1.0
                cx = end[0] - sign * turn_radius * math.sin(h)
                cy = end[1] + sign * turn_radius * math.cos(h)
                theta0 = math.atan2(end[1] - cy, end[0] - cx)
                pieces.append(("arc", cx, cy, theta0, sign, turn_radius, turn_radius * abs(turn)))
                h2 = headings[i + 1]
                cursor = pts[i + 1] + d * np.array([math.cos(h2), math.sin(h2)])
            else:
                cursor = end
        self.pieces = pieces
        self._starts = np.cumsum([0.0] + [pc[-1] for pc in pieces[:-1]])
        self._rows = np.zeros((len(pieces), 7))  # waypoint_pose's layout of the pieces
        for i, pc in enumerate(pieces):
            self._rows[i, 0] = 0.0 if pc[0] == "line" else 1.0
            self._rows[i, 1:len(pc)] = pc[1:]

    def kernel(self):
        from usv_mj.core.kernels import Kernel

        return Kernel(waypoint_kernel, (self.speed, self._starts, self._rows, self._out), state=(3,))

    def pose(self, t):
        return waypoint_pose(t, self.speed, self._starts, self._rows)



# --- registration: the scenario's [trajectory] kinds, each with its own options ------------------
#
# A kind is registered as a plug-in's would be: ``TRAJECTORIES.register(kind, options=Options)`` on
# a factory ``(options, scenario, *, duration) -> Reference`` (or a Reference subclass with that
# ``from_scenario`` classmethod); ``duration`` [s] is the horizon the reference must cover.


def _check_speed(speed) -> None:
    if not (math.isfinite(speed) and speed > 0):
        raise ValueError(f"speed must be > 0 m/s, got {speed!r}")


@dataclass(frozen=True)
class PaperOptions:
    """``kind = "paper"``: the paper's reference (docs/model.md §4)."""

    speed: float = 0.6  # [m/s] reference surge speed u_d (paper: 0.6)

    def __post_init__(self) -> None:
        _check_speed(self.speed)


@dataclass(frozen=True)
class LineOptions:
    """``kind = "line"``: a straight line."""

    speed: float = 0.6                       # [m/s] reference surge speed u_d
    start: tuple[float, float] = (0.0, 0.0)  # [m] the start point (x, y)
    heading_deg: float = 0.0                 # [deg] direction, counter-clockwise from +x

    def __post_init__(self) -> None:
        _check_speed(self.speed)


@dataclass(frozen=True)
class CircleOptions:
    """``kind = "circle"``: a circle, counter-clockwise unless ``clockwise``."""

    speed: float = 0.6                        # [m/s] reference surge speed u_d
    center: tuple[float, float] = (0.0, 20.0)  # [m] the centre (x, y)
    radius: float = 20.0                      # [m] the radius (> 0)
    start_angle_deg: float = -90.0            # [deg] polar angle of the start (-90: the bottom, heading +x)
    clockwise: bool = False                   # [-] run clockwise

    def __post_init__(self) -> None:
        _check_speed(self.speed)
        if not self.radius > 0:
            raise ValueError(f"radius must be > 0 m, got {self.radius!r}")


@dataclass(frozen=True)
class WaypointsOptions:
    """``kind = "waypoints"``: straight legs through the points joined by arcs."""

    speed: float = 0.6                                # [m/s] reference surge speed u_d
    points: tuple = ((0.0, 0.0), (40.0, 0.0))          # [m] the waypoints [[x, y], ...] (at least two)
    turn_radius: float = 5.0                          # [m] radius of the arcs that join the legs

    def __post_init__(self) -> None:
        _check_speed(self.speed)


@TRAJECTORIES.register("paper", options=PaperOptions)
def paper_from_scenario(options: PaperOptions, scenario, *, duration: float) -> PaperReference:
    return PaperReference(duration=duration, speed=options.speed)


@TRAJECTORIES.register("line", options=LineOptions)
def line_from_scenario(options: LineOptions, scenario, *, duration: float) -> LineReference:
    return LineReference(options.start, options.heading_deg, options.speed)


@TRAJECTORIES.register("circle", options=CircleOptions)
def circle_from_scenario(options: CircleOptions, scenario, *, duration: float) -> CircleReference:
    return CircleReference(options.center, options.radius, options.speed, options.start_angle_deg, options.clockwise)


@TRAJECTORIES.register("waypoints", options=WaypointsOptions)
def waypoints_from_scenario(options: WaypointsOptions, scenario, *, duration: float) -> WaypointReference:
    return WaypointReference(options.points, options.speed, options.turn_radius)


def make_reference(spec, duration: float, scenario=None) -> Reference:
    """The reference that ``spec`` (a scenario's ``TrajectorySpec``) names, valid over ``duration``
    [s]; ``scenario`` is handed to the kind's factory (the built-ins do not read it)."""
    return TRAJECTORIES.get(spec.kind, "trajectory.kind").make(spec.options, scenario, duration=duration)
