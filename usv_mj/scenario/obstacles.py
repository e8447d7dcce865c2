"""Obstacles and guidance of a scenario: the ``[[obstacles]]`` and ``[guidance]`` tables (docs/model.md §7).

The keys ``kind``, ``center``, ``radius``, ``size``, ``yaw``, ``velocity`` (obstacles) and ``avoid``,
``margin_m`` (guidance) are fixed because other tools read them::

    [[obstacles]]
    kind = "circle"          # "circle" (buoy, pile) or "box" (pier, moored hull)
    center = [12.0, 4.0]     # m, world frame, at t = 0
    radius = 0.8             # m (circle)
    # size = [6.0, 1.5]      # m, full length and width (box)
    # yaw = 0.3              # rad (box)
    velocity = [0.0, 0.0]    # m/s, constant; non-zero makes a moving obstacle (another boat)

    [guidance]
    avoid = true             # plan the reference around obstacles; false: track it as given
    margin_m = 0.3           # extra clearance on top of the guaranteed one

The other ``[guidance]`` keys (``max_yaw_rate``, ``max_yaw_accel``, ...) are this package's own and
documented in :class:`GuidanceSpec`. Every value is validated with a :class:`usv_mj.scenario.spec.ScenarioError`
that names its key, e.g. ``obstacles[2].radius``.

A leaf of the scenario (it imports only the error family): the obstacle features
(:mod:`usv_mj.obstacles`) import these types, never the other way round.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from usv_mj.core.errors import ScenarioError

OBSTACLE_KINDS = ("circle", "box")
#: how obstacles look, the same in the MuJoCo scene, the figures and the Foxglove scene (RGBA)
OBSTACLE_COLORS = {"circle": (0.90, 0.35, 0.10, 1.0), "box": (0.45, 0.33, 0.22, 1.0),
                   "moving": (0.75, 0.75, 0.78, 1.0)}
OBSTACLE_HALF_HEIGHT = 1.0  # m: obstacles span z in [-1, 1]


@dataclass(frozen=True)
class ObstacleSpec:
    """One obstacle: a vertical cylinder ("circle") or a vertical box ("box") in the water plane.

    Attributes
    ----------
    kind: "circle" or "box".
    center: (x, y) [m] in the world frame at t = 0.
    radius: circle radius [m] (circle only).
    size: (length, width) [m], full extents along the box's own x and y axes (box only).
    yaw: box orientation [rad], counter-clockwise from world x (box only).
    velocity: constant (vx, vy) [m/s]; non-zero makes a moving obstacle (a MuJoCo mocap body).
    name: label used in events and MuJoCo geom names (default ``obstacle_<index>``).
    """

    kind: str = "circle"
    center: tuple[float, float] = (0.0, 0.0)
    radius: float = 0.0
    size: tuple[float, float] = (0.0, 0.0)
    yaw: float = 0.0
    velocity: tuple[float, float] = (0.0, 0.0)
    name: str = ""

    @property
    def moving(self) -> bool:
        return self.velocity[0] != 0.0 or self.velocity[1] != 0.0

    def center_at(self, t: float) -> tuple[float, float]:
        """Centre [m] at time t [s]: center + velocity t."""
        return (self.center[0] + self.velocity[0] * t, self.center[1] + self.velocity[1] * t)

    @property
    def bounding_radius(self) -> float:
        """Radius [m] of the smallest disc about the centre that holds the obstacle."""
        if self.kind == "circle":
            return self.radius
        return 0.5 * math.hypot(*self.size)

    def shape(self, t: float = 0.0, resolution: int = 16):
        """The obstacle as a shapely geometry at time t (circles as 4*resolution-gons, outer-tangent
        is not guaranteed: use :func:`usv_mj.obstacles.clearance.point_distance` for exact distances)."""
        import shapely
        from shapely import affinity

        cx, cy = self.center_at(t)
        if self.kind == "circle":
            return shapely.Point(cx, cy).buffer(self.radius, quad_segs=resolution)
        half_l, half_w = 0.5 * self.size[0], 0.5 * self.size[1]
        box = shapely.box(-half_l, -half_w, half_l, half_w)
        return affinity.translate(affinity.rotate(box, self.yaw, origin=(0, 0), use_radians=True), cx, cy)


@dataclass(frozen=True)
class GuidanceSpec:
    """How the reference is planned around obstacles.

    Attributes
    ----------
    avoid: plan the reference around the obstacles (false: track the scenario's trajectory as given).
    margin_m: clearance [m] required on top of the guaranteed one (hull radius + controlled-point
        offset + sqrt(2) rho(t)); also the near-miss threshold of the clearance log.
    max_yaw_rate: bound on the planned r_d [rad/s].
    max_yaw_accel: bound on the planned r_d_dot [rad/s^2] (at the nominal speed).
    lookahead_m: look-ahead distance [m] of the virtual boat that smooths the planned polyline.
    allowance_m: extra inflation [m] used only while searching the path, so that the smoothed
        path (which cuts corners) still keeps the required clearance; the clearance is verified on
        the final reference, not assumed.
    check_period: how often [s] the predicted clearance to moving obstacles is checked.
    horizon: prediction horizon [s] of that check.
    max_accel: bound on the reference's surge acceleration u_d_dot [m/s^2] when it is re-timed.
    """

    avoid: bool = True
    margin_m: float = 0.3
    max_yaw_rate: float = 0.15
    max_yaw_accel: float = 0.05
    lookahead_m: float = 3.0
    allowance_m: float = 0.4
    check_period: float = 0.5
    horizon: float = 60.0
    max_accel: float = 0.05

    def __post_init__(self) -> None:
        if not (math.isfinite(self.margin_m) and self.margin_m >= 0):
            raise ValueError(f"margin_m must be a finite number >= 0 m, got {self.margin_m!r}")
        if not (math.isfinite(self.allowance_m) and self.allowance_m >= 0):
            raise ValueError(f"allowance_m must be a finite number >= 0 m, got {self.allowance_m!r}")
        for name in ("max_yaw_rate", "max_yaw_accel", "lookahead_m", "check_period", "horizon", "max_accel"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


# --- parsing ------------------------------------------------------------------------------------


def _number(source: str, where: str, value: Any, minimum: float | None = None, strict: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ScenarioError(f"{source}: {where} must be a finite number, got {value!r}")
    value = float(value)
    if minimum is not None and (value <= minimum if strict else value < minimum):
        raise ScenarioError(f"{source}: {where} must be {'>' if strict else '>='} {minimum:g}, got {value!r}")
    return value


def _pair(source: str, where: str, value: Any) -> tuple[float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ScenarioError(f"{source}: {where} must be a list of 2 numbers, got {value!r}")
    return (_number(source, f"{where}[0]", value[0]), _number(source, f"{where}[1]", value[1]))


_OBSTACLE_KEYS = {"kind", "center", "radius", "size", "yaw", "velocity", "name"}


def obstacle_from_table(table: Any, index: int, source: str = "<obstacles>") -> ObstacleSpec:
    """One ``[[obstacles]]`` entry -> :class:`ObstacleSpec`; errors name ``obstacles[index].key``."""
    where = f"obstacles[{index}]"
    if not isinstance(table, dict):
        raise ScenarioError(f"{source}: {where} must be a table, got {table!r}")
    for key in table:
        if key not in _OBSTACLE_KEYS:
            raise ScenarioError(f"{source}: unknown key '{where}.{key}'; known keys of [[obstacles]]: "
                                f"{', '.join(sorted(_OBSTACLE_KEYS))}")
    kind = table.get("kind", "circle")
    if kind not in OBSTACLE_KINDS:
        raise ScenarioError(f"{source}: {where}.kind must be one of {OBSTACLE_KINDS}, got {kind!r}")
    if "center" not in table:
        raise ScenarioError(f"{source}: {where}.center is missing (the obstacle's [x, y] in m)")
    center = _pair(source, f"{where}.center", table["center"])
    velocity = _pair(source, f"{where}.velocity", table.get("velocity", [0.0, 0.0]))
    name = table.get("name", f"obstacle_{index}")
    if not isinstance(name, str) or not name or not all(c.isalnum() or c in "_-" for c in name):
        raise ScenarioError(f"{source}: {where}.name must be a non-empty string of letters, digits, _ or -, "
                            f"got {name!r}")
    if kind == "circle":
        for key in ("size", "yaw"):
            if key in table:
                raise ScenarioError(f"{source}: {where}.{key} is for kind = \"box\", not \"circle\"")
        if "radius" not in table:
            raise ScenarioError(f"{source}: {where}.radius is missing (m, > 0, for kind = \"circle\")")
        radius = _number(source, f"{where}.radius", table["radius"], 0.0, strict=True)
        return ObstacleSpec("circle", center, radius, (0.0, 0.0), 0.0, velocity, name)
    if "radius" in table:
        raise ScenarioError(f"{source}: {where}.radius is for kind = \"circle\", not \"box\"")
    if "size" not in table:
        raise ScenarioError(f"{source}: {where}.size is missing ([length, width] in m, for kind = \"box\")")
    size = _pair(source, f"{where}.size", table["size"])
    for i, s in enumerate(size):
        if not s > 0:
            raise ScenarioError(f"{source}: {where}.size[{i}] must be > 0 m, got {s!r}")
    yaw = _number(source, f"{where}.yaw", table.get("yaw", 0.0))
    return ObstacleSpec("box", center, 0.0, size, yaw, velocity, name)


def from_tables(tables: Any, source: str = "<obstacles>") -> tuple[ObstacleSpec, ...]:
    """The ``[[obstacles]]`` array of tables -> a tuple of :class:`ObstacleSpec` (names must be unique)."""
    if tables is None:
        return ()
    if not isinstance(tables, (list, tuple)):
        raise ScenarioError(f"{source}: obstacles must be an array of tables ([[obstacles]]), got {tables!r}")
    out = tuple(obstacle_from_table(t, i, source) for i, t in enumerate(tables))
    seen: dict[str, int] = {}
    for i, o in enumerate(out):
        if o.name in seen:
            raise ScenarioError(f"{source}: obstacles[{i}].name {o.name!r} is already used by obstacles[{seen[o.name]}]")
        seen[o.name] = i
    return out


def guidance_from_table(table: Any, source: str = "<guidance>") -> GuidanceSpec:
    """The ``[guidance]`` table -> :class:`GuidanceSpec`; errors name ``guidance.key``."""
    if table is None:
        return GuidanceSpec()
    if not isinstance(table, dict):
        raise ScenarioError(f"{source}: [guidance] must be a table, got {table!r}")
    fields = {f.name: f for f in dataclasses.fields(GuidanceSpec)}
    defaults = GuidanceSpec()
    kwargs = {}
    for key, value in table.items():
        if key not in fields:
            raise ScenarioError(f"{source}: unknown key 'guidance.{key}'; known keys of [guidance]: "
                                f"{', '.join(sorted(fields))}")
        if isinstance(getattr(defaults, key), bool):
            if not isinstance(value, bool):
                raise ScenarioError(f"{source}: guidance.{key} must be true or false, got {value!r}")
            kwargs[key] = value
        else:
            kwargs[key] = _number(source, f"guidance.{key}", value)
    try:
        return GuidanceSpec(**kwargs)
    except ValueError as exc:
        raise ScenarioError(f"{source}: guidance.{exc}") from None
