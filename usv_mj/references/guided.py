"""The guided reference: a path tabulated in arc length run with a speed profile (what the planner
of :mod:`usv_mj.references.planner` makes and its :class:`~usv_mj.references.planner.Guidance`
re-times and detours).

- :class:`PathTable`: x(s), y(s), psi(s), kappa(s) on s = 0, ds, 2 ds, ... [m, rad, 1/m] (kappa
  linear between the nodes, psi its integral, x and y cubic Hermite with the unit tangents);
- :class:`SpeedProfile`: s(t) in pieces of constant acceleration [s, m, m/s, m/s^2], and
  :func:`retimed_pieces`, the slow-down, hold and speed-up of a re-timing;
- :class:`GuidedReference`: pose(t) = (x(s), y(s), psi(s), kappa(s) u, u, a, kappa'(s) u^2 + kappa(s) a)
  with (s, u, a) = profile(t),
  evaluated by :func:`guided_pose` (also the native kernel :func:`guided_kernel`); a detour replaces
  the path from a time on.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from usv_mj.references.trajectories import Reference, hermite_point, unicycle_out


@dataclass
class PathTable:
    """x(s), y(s), psi(s), kappa(s) on s = 0, ds, 2 ds, ... [m, rad, 1/m]; kappa is linear between
    the nodes and psi its integral (so r_d = kappa u is continuous and psi_d_dot = r_d exactly);
    x, y are cubic Hermite interpolants with the unit tangents (cos psi, sin psi) at the nodes. Beyond the end the path goes
    on straight along psi(end) (the table ends on a straight: kappa(end) is ~0)."""

    x: np.ndarray
    y: np.ndarray
    psi: np.ndarray
    kappa: np.ndarray
    ds: float

    @property
    def length(self) -> float:
        return (len(self.x) - 1) * self.ds

    def __post_init__(self) -> None:
        # the rows (x, y, psi, kappa) that _path_at reads: the one evaluation of a path table
        self._rows = np.ascontiguousarray(np.column_stack([self.x, self.y, self.psi, self.kappa]), dtype=np.float64)

    def at(self, s: float):
        """(x, y, psi, kappa) at arc length s [m] (:func:`_path_at`; straight past either end)."""
        return _path_at(self._rows, 0, len(self.x) - 1, self.ds, float(s))

    def points(self, s: np.ndarray) -> np.ndarray:
        """Positions at many arc lengths, shape (len(s), 2) (as :meth:`at`)."""
        return _path_points(self._rows, len(self.x) - 1, self.ds, np.ascontiguousarray(s, dtype=np.float64).ravel())


# --- timing -------------------------------------------------------------------------------------


class SpeedProfile:
    """s(t): pieces (t0, s0, u0, a) of constant acceleration a [m/s^2] from time t0 [s]; the last
    piece lasts for ever. u(t) = u0 + a (t - t0), s(t) = s0 + u0 (t - t0) + a (t - t0)^2 / 2."""

    def __init__(self, speed: float):
        self.t0 = [0.0]
        self.pieces = [(0.0, 0.0, float(speed), 0.0)]

    def state(self, t: float):
        """(s [m], u [m/s], a [m/s^2]) at t."""
        i = max(bisect.bisect_right(self.t0, t) - 1, 0)
        t0, s0, u0, a = self.pieces[i]
        dt = t - t0
        return s0 + u0 * dt + 0.5 * a * dt * dt, u0 + a * dt, a

    def replace_from(self, t: float, pieces) -> None:
        """Drop every piece after ``t`` and append ``pieces`` (each (t0 >= t, s0, u0, a))."""
        i = bisect.bisect_right(self.t0, t)
        self.t0 = self.t0[:i]
        self.pieces = self.pieces[:i]
        for p in pieces:
            self.t0.append(p[0])
            self.pieces.append(p)

    def copy(self) -> "SpeedProfile":
        out = SpeedProfile(0.0)
        out.t0, out.pieces = list(self.t0), list(self.pieces)
        return out

    def states(self, times: np.ndarray) -> np.ndarray:
        return np.array([self.state(float(t))[0] for t in times])


def retimed_pieces(t: float, s: float, u: float, u_low: float, hold: float, u_cruise: float, accel: float):
    """Pieces from (t, s, u): change speed to ``u_low`` at |a| = accel, hold it ``hold`` s, then
    change speed to ``u_cruise`` and keep it."""
    pieces = []

    def ramp(t, s, u, target):
        if abs(target - u) < 1e-12:
            return t, s, u
        a = accel if target > u else -accel
        dur = (target - u) / a
        pieces.append((t, s, u, a))
        return t + dur, s + u * dur + 0.5 * a * dur * dur, target

    t, s, u = ramp(t, s, u, u_low)
    if hold > 0:
        pieces.append((t, s, u, 0.0))
        t, s = t + hold, s + u * hold
    t, s, u = ramp(t, s, u, u_cruise)
    pieces.append((t, s, u, 0.0))
    return pieces


@njit(cache=True)
def _path_at(path, a, n, ds, s):
    """(x, y, psi, kappa) at arc length s [m] of the path table on rows a .. a + n of ``path``
    (columns x, y, psi, kappa): Hermite x, y, linear kappa and its integral psi; straight along
    psi of the end row beyond either end."""
    if s <= 0.0:
        return path[a, 0] + s * math.cos(path[a, 2]), path[a, 1] + s * math.sin(path[a, 2]), path[a, 2], 0.0
    f = s / ds
    i = int(f)
    if i >= n:
        extra = s - n * ds
        p = path[a + n, 2]
        return path[a + n, 0] + extra * math.cos(p), path[a + n, 1] + extra * math.sin(p), p, 0.0
    w = f - i
    r0, r1 = a + i, a + i + 1
    k0, k1 = path[r0, 3], path[r1, 3]
    p0, p1 = path[r0, 2], path[r1, 2]
    # kappa is linear in s over a cell and psi its integral, so d psi/ds = kappa exactly;
    # x, y: cubic Hermite with the unit tangents at the nodes
    x, y = hermite_point(w, path[r0, 0], path[r0, 1], p0, path[r1, 0], path[r1, 1], p1, ds, 1.0)
    return x, y, p0 + ds * w * (k0 + 0.5 * (k1 - k0) * w), k0 + (k1 - k0) * w


@njit(cache=True)
def _path_dkappa(path, a, n, ds, s):
    """d kappa / ds [1/m^2] at arc length s of the path table of :func:`_path_at`: the slope of
    kappa over the cell of s (kappa is linear in s there), 0 beyond either end (straight)."""
    if s <= 0.0:
        return 0.0
    i = int(s / ds)
    if i >= n:
        return 0.0
    return (path[a + i + 1, 3] - path[a + i, 3]) / ds


@njit(cache=True)
def _path_points(path, n, ds, s):
    """(x, y) of :func:`_path_at` at each arc length of ``s``, shape (len(s), 2)."""
    out = np.empty((s.shape[0], 2))
    for j in range(s.shape[0]):
        x, y, _, _ = _path_at(path, 0, n, ds, s[j])
        out[j, 0], out[j, 1] = x, y
    return out


@njit(cache=True)
def guided_pose(t, prof_t0, prof_pieces, seg_t, seg_s, seg_ds, seg_row, path):
    """:meth:`GuidedReference.pose` on a snapshot of its profile (``prof_t0`` and the (t0, s0, u0, a)
    rows ``prof_pieces``) and segments (start time, start arc length, the path's ds and first row
    in ``path``; ``seg_row`` has one more entry, the end): (x, y, psi, r, u, u_dot, r_dot) with
    r = kappa u, u_dot = a of the profile's piece and r_dot = kappa' u^2 + kappa a."""
    lo, hi = 0, prof_t0.shape[0]  # bisect.bisect_right(profile.t0, t)
    while lo < hi:
        mid = (lo + hi) // 2
        if t < prof_t0[mid]:
            hi = mid
        else:
            lo = mid + 1
    i = max(lo - 1, 0)
    t0, s0, u0, a = prof_pieces[i, 0], prof_pieces[i, 1], prof_pieces[i, 2], prof_pieces[i, 3]
    dt = t - t0
    s = s0 + u0 * dt + 0.5 * a * dt * dt
    u = u0 + a * dt
    j = seg_t.shape[0] - 1
    while j > 0 and seg_t[j] > t:
        j -= 1
    row, n, ds = seg_row[j], seg_row[j + 1] - seg_row[j] - 1, seg_ds[j]
    x, y, psi, kappa = _path_at(path, row, n, ds, s - seg_s[j])
    # r = kappa(s) u, so r_dot = kappa'(s) u^2 + kappa a (s_dot = u, u_dot = a)
    return x, y, psi, kappa * u, u, a, _path_dkappa(path, row, n, ds, s - seg_s[j]) * u * u + kappa * a


@njit(cache=True)
def guided_kernel(t, prof_t0, prof_pieces, seg_t, seg_s, seg_ds, seg_row, path, out):
    """:meth:`GuidedReference.evaluate` natively (usv_mj.core.kernels), on the snapshot of :func:`guided_pose`."""
    return unicycle_out(out, *guided_pose(t, prof_t0, prof_pieces, seg_t, seg_s, seg_ds, seg_row, path))


class GuidedReference(Reference):
    """A planned path run with a speed profile (:class:`usv_mj.references.trajectories.Reference`):
    pose(t) = (x(s), y(s), psi(s), kappa(s) u, u, u_dot, r_dot) with (s, u) = profile(t) (module docstring).

    A detour replaces the path from a time on (:meth:`switch_path`): ``segments`` holds
    (t_start, s_start, path) and the path of the last segment started by t is read at s - s_start.
    """

    kind = "guided"

    def __init__(self, path: PathTable, profile: SpeedProfile):
        super().__init__()
        self.profile = profile
        self.segments = [(0.0, 0.0, path)]

    @property
    def path(self) -> PathTable:
        """The path in use at the end (the original one until a detour)."""
        return self.segments[-1][2]

    @staticmethod
    def _segment(segments, t):
        i = len(segments) - 1
        while i > 0 and segments[i][0] > t:
            i -= 1
        return segments[i]

    def geometry(self, t: float):
        """(x, y, psi, kappa, s_local, segment) of the reference at time t."""
        s, _, _ = self.profile.state(t)
        seg = self._segment(self.segments, t)
        return (*seg[2].at(s - seg[1]), s - seg[1], seg)

    def pose(self, t):
        return guided_pose(t, *self._snapshot())

    def positions(self, times, profile: SpeedProfile | None = None, segments=None) -> np.ndarray:
        """Reference positions at many times, shape (len(times), 2) (optionally for a candidate
        profile and segment list)."""
        times = np.asarray(times, dtype=float)
        profile = profile or self.profile
        segments = segments or self.segments
        s = profile.states(times)
        if len(segments) == 1:
            return segments[0][2].points(s - segments[0][1])
        starts = np.array([seg[0] for seg in segments])
        idx = np.maximum(np.searchsorted(starts, times, side="right") - 1, 0)
        out = np.empty((len(times), 2))
        for j in np.unique(idx):
            mask = idx == j
            out[mask] = segments[j][2].points(s[mask] - segments[j][1])
        return out

    def segments_with(self, t: float, path: PathTable) -> list:
        """The segment list with ``path`` taking over at time t (from the reference's s(t))."""
        keep = [seg for seg in self.segments if seg[0] <= t]
        return keep + [(t, self.profile.state(t)[0], path)]

    def switch_path(self, t: float, path: PathTable) -> None:
        self.segments = self.segments_with(t, path)

    def kernel_key(self) -> tuple:
        """What :meth:`kernel`'s snapshot was taken of: a kernel made when the key was equal is
        current (a detour rebinds ``segments``, a re-timing the profile's lists)."""
        p = self.profile
        return (id(self.segments), len(self.segments), id(p), id(p.t0), len(p.t0), id(p.pieces), len(p.pieces))

    def _snapshot(self) -> tuple:
        """:func:`guided_pose`'s arrays of the profile and the segments, made again when
        :meth:`kernel_key` changed. The snapshot keeps the lists it was taken of alive, so their
        ids in the key are not reused."""
        key = self.kernel_key()
        if getattr(self, "_snapshot_key", None) == key:
            return self._snapshot_args
        p = self.profile
        prof_t0 = np.array(p.t0, dtype=np.float64)
        prof_pieces = np.array(p.pieces, dtype=np.float64).reshape(-1, 4)
        seg_t = np.array([seg[0] for seg in self.segments], dtype=np.float64)
        seg_s = np.array([seg[1] for seg in self.segments], dtype=np.float64)
        seg_ds = np.array([seg[2].ds for seg in self.segments], dtype=np.float64)
        tables = [seg[2]._rows for seg in self.segments]
        seg_row = np.cumsum([0] + [len(tb) for tb in tables]).astype(np.int64)
        path = np.ascontiguousarray(np.vstack(tables), dtype=np.float64)
        self._kernel_snapshot = (self.segments, p, p.t0, p.pieces)
        self._snapshot_key, self._snapshot_args = key, (prof_t0, prof_pieces, seg_t, seg_s, seg_ds, seg_row, path)
        return self._snapshot_args

    def kernel(self):
        """:func:`guided_kernel` on the snapshot of the profile and the segments as they are now (make
        a new kernel when :meth:`kernel_key` changes)."""
        from usv_mj.core.kernels import Kernel

        return Kernel(guided_kernel, self._snapshot() + (self._out,))
