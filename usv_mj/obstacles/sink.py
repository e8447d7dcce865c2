"""The obstacle log: clearance and contact force per control step, and the obstacle events.

:class:`ObstacleLog` is a :class:`usv_mj.simulation.RunSink` (``start``/``rows``/``finish``) that is
also fed once per control step by :class:`usv_mj.obstacles.run.ObstacleStepper` with
:meth:`ObstacleLog.record_step`. It keeps, per step k (the record's row k):

- ``clearance[k, i]``: signed distance [m] hull <-> obstacle i (negative: penetration);
- ``normal_force[k, i]``: summed normal contact force [N] between the hull and obstacle i;
- ``obstacle_xy[k, i]``: obstacle i's centre [m] (moving obstacles move);

and appends :class:`usv_mj.record.Event` s to the record as they happen:

- ``near_miss``: clearance to an obstacle fell under ``margin`` (start of an episode; values:
  obstacle, clearance);
- ``contact``: the hull touches an obstacle (MuJoCo contact; values: obstacle, normal force at the
  first step); ``contact_end`` closes the episode with its peak force and duration;
- ``collision``: plants without contact physics, clearance reached zero (the note of the monitor
  says once that the hull passes through);
- ``replan`` (from :class:`usv_mj.obstacles.planner.Guidance`, via :meth:`add_event`).

:meth:`summary` gives the ``summary.json`` fields ``min_clearance_m`` (over the run and all
obstacles) and ``contacts`` (number of contact or collision events) plus per-obstacle minima;
``finish`` also stores it in ``record.metadata["obstacles"]``.
"""

from __future__ import annotations

import math

import numpy as np

from usv_mj.record import Event


class ObstacleLog:
    """Per-step clearance / contact-force arrays and obstacle events (module docstring)."""

    def __init__(self, obstacles, n_rows: int, margin: float, control_period: float, note: str = "",
                 inflation=None):
        """``inflation``: per obstacle, the safety boundary distance [m] to display (NaN: none)."""
        self.obstacles = tuple(obstacles)
        n = len(self.obstacles)
        self.margin = float(margin)
        self.dt = float(control_period)
        self.note = note
        self.inflation = None if inflation is None else np.asarray(inflation, dtype=float)
        self.clearance = np.full((n_rows, n), np.nan)
        self.normal_force = np.zeros((n_rows, n))  # pages untouched until a contact: no memory
        self.events: list[Event] = []
        self.n_rows = 0
        self.record = None
        self._near = np.zeros(n, dtype=bool)
        self._contact = np.zeros(n, dtype=bool)
        self._any_contact = False
        self._contact_start = np.zeros(n)
        self._contact_peak = np.zeros(n)
        self._contacts = 0
        self._noted = False
        self._center0 = np.array([o.center for o in self.obstacles], dtype=float).reshape(n, 2)
        self._velocity = np.array([o.velocity for o in self.obstacles], dtype=float).reshape(n, 2)
        self._any_moving = any(o.moving for o in self.obstacles)
        # static obstacles stay (a read-only view of the centres: no rows x obstacles array to fill);
        # moving ones are written per step
        self.obstacle_xy = (np.repeat(self._center0[None], n_rows, axis=0) if self._any_moving
                            else np.broadcast_to(self._center0, (n_rows, n, 2)))

    # --- fed by the stepper ----------------------------------------------------------------------

    def record_step(self, t: float, clearance: np.ndarray, normal_force: np.ndarray, in_contact: np.ndarray) -> None:
        """Store step k = round(t / dt) and raise the events that start at it."""
        k = int(round(t / self.dt))
        if k >= len(self.clearance):
            return
        self.clearance[k] = clearance
        self.normal_force[k] = normal_force
        if self._any_moving:
            self.obstacle_xy[k] = self._center0 + self._velocity * t
        if k >= self.n_rows:
            self.n_rows = k + 1
        near = clearance < self.margin
        if (near & ~self._near).any():
            for i in np.flatnonzero(near & ~self._near):
                o = self.obstacles[i]
                self.add_event(Event(t, "near_miss", f"clearance to {o.name} fell to {clearance[i]:.3f} m "
                                     f"(< margin {self.margin:g} m)",
                                     {"obstacle": o.name, "index": int(i), "clearance_m": float(clearance[i])}))
        self._near[:] = near              # in place: the compiled loop's hook kernel holds it
        if self._any_contact or in_contact.any():
            kind = "contact" if not self.note else "collision"
            for i in np.flatnonzero(in_contact & ~self._contact):
                o = self.obstacles[i]
                if self.note and not self._noted:
                    self._noted = True
                    self.add_event(Event(t, "note", self.note, {}))
                self._contacts += 1
                self._contact_start[i] = t
                self._contact_peak[i] = normal_force[i]
                msg = (f"hull touches {o.name}: normal force {normal_force[i]:.1f} N" if kind == "contact" else
                       f"hull reaches {o.name} (clearance {clearance[i]:.3f} m; no contact physics)")
                self.add_event(Event(t, kind, msg, {"obstacle": o.name, "index": int(i),
                                                    "normal_force_N": float(normal_force[i]),
                                                    "clearance_m": float(clearance[i])}))
            both = in_contact & self._contact
            self._contact_peak[both] = np.maximum(self._contact_peak[both], normal_force[both])
            for i in np.flatnonzero(~in_contact & self._contact):
                o = self.obstacles[i]
                self.add_event(Event(t, f"{kind}_end", f"hull leaves {o.name} after {t - self._contact_start[i]:.3f} s "
                                     f"(peak normal force {self._contact_peak[i]:.1f} N)",
                                     {"obstacle": o.name, "index": int(i), "duration_s": float(t - self._contact_start[i]),
                                      "peak_normal_force_N": float(self._contact_peak[i])}))
            self._contact[:] = in_contact
            self._any_contact = bool(self._contact.any())

    def kernel_state(self) -> tuple:
        """(clearance rows, near-miss flags, contact flags, margin [m]): what the compiled loop's
        hook kernel (usv_mj.obstacles.native_step) reads and writes in place of :meth:`record_step`."""
        return self.clearance, self._near, self._contact, float(self.margin)

    def add_event(self, event: Event) -> None:
        self.events.append(event)
        if self.record is not None:
            self.record.events.append(event)

    # --- RunSink -----------------------------------------------------------------------------------

    def start(self, record) -> None:
        self.record = record

    def rows(self, record, lo: int, hi: int) -> None:  # data are already here (record_step)
        pass

    def finish(self, record) -> None:
        record.metadata["obstacles"] = self.summary()

    # --- results -----------------------------------------------------------------------------------

    def summary(self) -> dict:
        """``min_clearance_m``, ``contacts`` and per-obstacle ``min_clearance_m`` / time / peak force."""
        c = self.clearance[: self.n_rows]
        ok = np.isfinite(c)
        first = (np.zeros(len(self.obstacles), int) if not self.n_rows else
                 c.argmin(axis=0) if ok.all() else np.argmin(np.where(ok, c, np.inf), axis=0))
        any_ok = ok.any(axis=0)
        peak = self.normal_force[: self.n_rows].max(axis=0) if self.n_rows else np.zeros(len(self.obstacles))
        per = []
        for i, o in enumerate(self.obstacles):
            k = int(first[i]) if any_ok[i] else -1
            per.append({"name": o.name, "kind": o.kind, "moving": o.moving,
                        "min_clearance_m": float(c[k, i]) if k >= 0 else None,
                        "t_min_s": float(k * self.dt) if k >= 0 else None,
                        "peak_normal_force_N": float(peak[i]),
                        "inflation_m": self._inflation(i)})
        finite = c[ok]
        kinds = [e.kind for e in self.events]
        return {
            "min_clearance_m": float(finite.min()) if finite.size else None,
            "contacts": self._contacts,
            "near_misses": kinds.count("near_miss"),
            "replans": kinds.count("replan"),
            "contact_physics": not bool(self.note),
            "per_obstacle": per,
        }

    def _inflation(self, i: int):
        """The safety boundary [m] drawn around obstacle i (the plan's G + margin at the pass), or None."""
        if self.inflation is None or not math.isfinite(self.inflation[i]):
            return None
        return float(self.inflation[i])

    def frame(self, k: int) -> dict:
        """What the MCAP topic ``/usv/obstacles`` and the renderer need at row k (plain data)."""
        return {
            "t": k * self.dt,
            "obstacles": [{"name": o.name, "kind": o.kind, "center": self.obstacle_xy[k, i].tolist(),
                           "radius": o.radius, "size": list(o.size), "yaw": o.yaw, "moving": o.moving,
                           "inflation_m": self._inflation(i),
                           "clearance_m": float(self.clearance[k, i]), "normal_force_N": float(self.normal_force[k, i])}
                          for i, o in enumerate(self.obstacles)],
        }
