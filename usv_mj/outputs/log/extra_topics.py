"""The per-step topics a run log has only when the run has them: ``P/obstacles`` and ``P/environment``.

Both are protobuf messages laid out in bulk like the row topics (:mod:`usv_mj.outputs.log.protobuf_rows`,
one message per control step, ``log_time`` = round(t * 1e9) ns, ``sequence`` = row index k, every
float64 bit for bit). Shown as the JSON form of the message (what ``mcap cat --json`` prints):

``P/obstacles`` (schema ``usv_mj.Obstacles``), when the run has an
:class:`~usv_mj.obstacles.sink.ObstacleLog` (attached to the run's sink by
:func:`usv_mj.obstacles.run.run_obstacle_scenario`)::

    {"t": 0.0, "obstacles": [{"name": "buoy", "clearance_m": 3.2, "normal_force_N": 0.0,
                               "center": {"x": 12.0, "y": 4.0}}, ...]}

clearance_m: signed distance hull <-> obstacle [m] (negative: penetration; NaN before the first
measurement); normal_force_N: summed normal contact force [N]; center: the obstacle's centre in
the world frame [m] at t (moving obstacles move). The obstacles' fixed shapes (kind, radius, size,
yaw, velocity, inflation) are in the run's ``run_start`` metadata under ``obstacles``.
Foxglove: ``P/scene/obstacles`` (``foxglove.SceneUpdate``, entities "obstacle/NAME" from
:func:`usv_mj.scene.display.scene_entities`: cube / cylinder and the inflated boundary) at t = 0
and every 10 s, and the moving obstacles again every 20 ms.

``P/environment`` (docs/sea.md §1; schema ``usv_mj.Environment``), when the scenario's sea is
not calm::

    {"t": .., "zeta": .., "tau_wave": {"x", "y", "n"}, "tau_drift": {"x", "y", "n"},
     "tau_wind": {"x", "y", "n"}, "current": {"x", "y"}, "wind": {"speed", "direction"}}

zeta: wave elevation [m] at the hull's origin (x, y) at t; tau_wave = s(t) tau_wave1, tau_drift =
s(t)^2 tau_drift, tau_wind [N, N, N m] in the body frame (the loads that act, ramp applied);
current [m/s] in the world frame; wind speed [m/s] and going-to direction [rad] in the world frame.
They are computed by the writer (off the simulation loop) from the recorded (t, eta, nu) with
:meth:`usv_mj.physics.sea.Environment.loads_record`: the environment is a pure function of (t, eta, nu),
so these are the loads the plant saw at the start of each control step. Rows whose state is not
finite (a divergence) get NaN.
"""

from __future__ import annotations


import numpy as np

from usv_mj.record.run_record import COL
from usv_mj.outputs.log.protobuf_rows import Field, FixedLayout, Message, file_descriptor_set, message_class

OBSTACLES_SCHEMA_NAME = "usv_mj.Obstacles"
ENVIRONMENT_SCHEMA_NAME = "usv_mj.Environment"

_POINT = Message("Point2", (Field("x", doc="east [m]"), Field("y", doc="north [m]")),
                 "a point in the world frame (REP-103 ENU) [m]")
_OBSTACLE = Message("Obstacle", (
    Field("name", "string", "the obstacle's name from the scenario"),
    Field("clearance_m", doc="signed distance hull <-> obstacle [m] (negative: penetration; NaN before the first "
                             "measurement)"),
    Field("normal_force_N", doc="summed normal contact force [N]"),
    Field("center", _POINT, "obstacle centre in the world frame [m] at t")))
OBSTACLES_MESSAGE = Message(OBSTACLES_SCHEMA_NAME, (
    Field("t", doc="time [s]"), Field("obstacles", _OBSTACLE, "one per obstacle, in the scenario's order",
                                      repeated=True)),
    "clearance and contact force per obstacle at one control step (usv_mj.outputs.log.extra_topics)")
OBSTACLES_SCHEMA = file_descriptor_set(OBSTACLES_MESSAGE)

_LOAD = Message("BodyLoad", (Field("x", doc="surge force [N]"), Field("y", doc="sway force [N] (to port)"),
                             Field("n", doc="yaw moment [N m] (counter-clockwise)")), "a load in the body frame")
_VELOCITY = Message("Velocity2", (Field("x", doc="east [m/s]"), Field("y", doc="north [m/s]")),
                    "a velocity in the world frame [m/s]")
_WIND = Message("Wind", (Field("speed", doc="wind speed incl. gusts [m/s]"),
                         Field("direction", doc="going-to direction, world frame, counter-clockwise from east [rad]")))
ENVIRONMENT_MESSAGE = Message(ENVIRONMENT_SCHEMA_NAME, (
    Field("t", doc="time [s]"), Field("zeta", doc="wave elevation at the hull origin [m]"),
    Field("tau_wave", _LOAD, "first-order wave load, body frame, ramp applied [N, N, N m]"),
    Field("tau_drift", _LOAD, "wave drift load, body frame, ramp applied [N, N, N m]"),
    Field("tau_wind", _LOAD, "wind load, body frame [N, N, N m]"),
    Field("current", _VELOCITY, "current velocity, world frame [m/s]"), Field("wind", _WIND, "the wind")),
    "sea state at the hull at one control step (docs/sea.md §1; usv_mj.outputs.log.extra_topics)")
ENVIRONMENT_SCHEMA = file_descriptor_set(ENVIRONMENT_MESSAGE)


# --- obstacles -----------------------------------------------------------------------------------


def obstacle_layout(names) -> FixedLayout:
    """Layout of ``P/obstacles``; its values are the columns of :func:`obstacle_block`:
    [t, (clearance, force, cx, cy) per obstacle]."""
    return FixedLayout(message_class(OBSTACLES_SCHEMA, OBSTACLES_SCHEMA_NAME),
                       {"obstacles": [{"name": str(name)} for name in names]})


def obstacle_block(t: np.ndarray, clearance: np.ndarray, normal_force: np.ndarray, center: np.ndarray) -> np.ndarray:
    """(n, 1 + 4 m) float64 block for :func:`obstacle_layout` from the ObstacleLog's rows."""
    n, m = clearance.shape
    per = np.stack([clearance, normal_force, center[:, :, 0], center[:, :, 1]], axis=2).reshape(n, 4 * m)
    return np.concatenate([np.asarray(t, float).reshape(n, 1), per], axis=1)


def obstacle_arrays(cols: dict) -> dict:
    """Flattened ``P/obstacles`` columns ("t", "obstacles.I.name", "obstacles.I.clearance_m",
    "obstacles.I.normal_force_N", "obstacles.I.center.x" / ".y") -> {"t" (n,), "names" [m],
    "clearance_m" (n, m), "normal_force_N" (n, m), "center" (n, m, 2)} (float64)."""
    t = np.asarray(cols["t"], np.float64)
    m = 0
    while f"obstacles.{m}.clearance_m" in cols:
        m += 1

    def take(key):
        return np.stack([np.asarray(cols[f"obstacles.{i}.{key}"], np.float64) for i in range(m)], axis=1) \
            if m else np.zeros((len(t), 0))

    names = [str(cols[f"obstacles.{i}.name"][0]) for i in range(m)] if len(t) else []
    return {"t": t, "names": names, "clearance_m": take("clearance_m"), "normal_force_N": take("normal_force_N"),
            "center": np.stack([take("center.x"), take("center.y")], axis=2)}


# --- environment ---------------------------------------------------------------------------------


def environment_layout() -> FixedLayout:
    """Layout of ``P/environment``; its values are the columns of :func:`environment_block`
    (:data:`ENVIRONMENT_FIELDS`)."""
    return FixedLayout(message_class(ENVIRONMENT_SCHEMA, ENVIRONMENT_SCHEMA_NAME))


#: the values of P/environment in message order ("t", "zeta", "tau_wave.x", ..., "wind.direction"),
#: the columns of :func:`environment_block`
ENVIRONMENT_FIELDS = environment_layout().paths


def environment_block(env, rows: np.ndarray) -> np.ndarray:
    """(n, 15) block of :data:`ENVIRONMENT_FIELDS` for record rows (columns of :data:`usv_mj.record.run_record.COLUMNS`).

    From the rows' (t, eta, nu) with ``env.loads_record`` and ``env.elevation`` (docs/sea.md §1);
    current in the world frame = R(psi) nu_c. Rows with a non-finite t or state are NaN.
    """
    from usv_mj.physics.sea import layout as lay

    t = rows[:, COL["t"]]
    eta = rows[:, [COL["x"], COL["y"], COL["psi"]]]
    nu = rows[:, [COL["u"], COL["v"], COL["r"]]]
    out = np.full((rows.shape[0], len(ENVIRONMENT_FIELDS)), np.nan)
    out[:, 0] = t
    ok = np.isfinite(t) & np.all(np.isfinite(eta), axis=1) & np.all(np.isfinite(nu), axis=1)
    if not ok.any():
        return out
    ts, etas, nus = t[ok], eta[ok], nu[ok]
    loads = env.loads_record(ts, etas, nus)
    sel = out[ok]
    sel[:, 1] = env.elevation(etas[:, 0], etas[:, 1], ts)
    sel[:, 2:5] = loads[:, lay.L_WAVE1:lay.L_WAVE1 + 3]
    sel[:, 5:8] = loads[:, lay.L_DRIFT:lay.L_DRIFT + 3]
    sel[:, 8:11] = loads[:, lay.L_WIND:lay.L_WIND + 3]
    c, s = np.cos(etas[:, 2]), np.sin(etas[:, 2])
    ucb, vcb = loads[:, lay.L_NU_C], loads[:, lay.L_NU_C + 1]
    sel[:, 11] = c * ucb - s * vcb
    sel[:, 12] = s * ucb + c * vcb
    sel[:, 13] = env.wind_speed(ts)
    sel[:, 14] = np.radians(env.settings.wind.direction_deg)
    out[ok] = sel
    return out


def environment_arrays(cols: dict) -> dict:
    """Flattened ``P/environment`` columns -> {"t", "zeta" (n,), "tau_wave", "tau_drift", "tau_wind" (n, 3),
    "current" (n, 2), "wind_speed", "wind_direction" (n,)}."""
    def stack(*names):
        return np.stack([np.asarray(cols[k], np.float64) for k in names], axis=1)

    return {"t": np.asarray(cols["t"], np.float64), "zeta": np.asarray(cols["zeta"], np.float64),
            "tau_wave": stack("tau_wave.x", "tau_wave.y", "tau_wave.n"),
            "tau_drift": stack("tau_drift.x", "tau_drift.y", "tau_drift.n"),
            "tau_wind": stack("tau_wind.x", "tau_wind.y", "tau_wind.n"),
            "current": stack("current.x", "current.y"),
            "wind_speed": np.asarray(cols["wind.speed"], np.float64),
            "wind_direction": np.asarray(cols["wind.direction"], np.float64)}
