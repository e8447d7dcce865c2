"""Typed, validated settings of the sea state (docs/sea.md).

The scenario keys (other tools read them)::

    [sea.waves]    hs, tp, gamma, from_deg, spreading, components, drift, seed
    [sea.current]  speed, toward_deg, sigma, time_constant
    [sea.wind]     speed, from_deg, gust_sigma, gust_time_constant, seed

Directions are written as marine users write them, with the meaning in the key: waves and wind by
the direction they come **from**, the current by the direction it sets **toward**, both in compass
degrees (clockwise from north = +y). :func:`going_to_deg` converts them, once, here, to the angle the
kernels use: the direction the load travels toward, counter-clockwise from east (+x), in degrees.
That internal angle is the ``direction_deg`` attribute of the settings classes (and of the run's
metadata, ``Scenario.to_dict``, so that it rebuilds the sea bit for bit); what a user reads
(:meth:`SeaSettings.to_dict` in summary.json and compare.json, :meth:`SeaSettings.describe` in
report.md) gives the directions as they are written, ``from_deg`` / ``toward_deg``.

``direction_deg`` is also still accepted as a key, a deprecated alias with its old meaning (going-to,
counter-clockwise from +x); a table that gives it beside ``from_deg`` / ``toward_deg`` is refused.
When a table sits over another one (the scenario's ``[sea.*]`` over a sea preset, a sweep's dotted
path over its base), its direction replaces the lower one's whatever the spelling
(:func:`merge_sea_tables`, :func:`replace_direction`).

Every default is calm (hs = 0, no current, no wind), which reproduces the calm model bit for bit.

:class:`HullGeometry` holds the hull box and windage (docs/sea.md); it is not a scenario key.

Bad values raise :class:`SeaSettingsError` (a ``ValueError``) whose message names the key, e.g.
``preset moderate: sea.waves.hs must be >= 0 m, got -1.0``.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

from usv_mj.support.toml_values import coerce

DRIFT_MODES = ("newman", "mean", "off")
MAX_COMPONENTS = 4096  # wave components: each costs every step (128 by default; 4096 is ~30x slower)


from usv_mj.core.errors import SeaSettingsError  # noqa: E402  (one error family: a ScenarioError)


# --- directions: what a user types, and the angle the kernels use ----------------------------------

#: The direction key of each ``[sea.*]`` table and what it means.
DIRECTION_KEYS = {"waves": "from_deg", "current": "toward_deg", "wind": "from_deg"}
#: The deprecated key: the internal going-to angle, counter-clockwise from +x (before docs/sea.md).
DEPRECATED_DIRECTION_KEY = "direction_deg"
_MEANING = {"from_deg": "coming from, compass degrees clockwise from north",
            "toward_deg": "setting toward, compass degrees clockwise from north",
            DEPRECATED_DIRECTION_KEY: "going toward, degrees counter-clockwise from east (+x); deprecated"}


def going_to_deg(compass_deg: float, sense: str) -> float:
    """The internal direction of a load [deg] from the compass direction a user writes.

    ``compass_deg`` is measured clockwise from north (+y of the world frame): 0 north, 90 east,
    180 south, 270 west. ``sense`` says what it names:

    - ``"from"`` (waves, wind): where the load comes from; it travels toward the opposite direction,
      so the internal angle is ``(270 - compass_deg) mod 360``;
    - ``"toward"`` (current): where the load goes; the internal angle is ``(90 - compass_deg) mod 360``.

    The result is the going-to angle that the kernels use, counter-clockwise from east (+x), in
    [0, 360): wind from north (0) -> 270 (blows toward -y), waves from west (270) -> 0 (travel
    toward +x), a current toward east (90) -> 0 (sets toward +x). This is the only place where a user's
    direction is converted (docs/sea.md, "Directions").
    """
    if sense == "from":
        return (270.0 - compass_deg) % 360.0
    if sense == "toward":
        return (90.0 - compass_deg) % 360.0
    raise ValueError(f"sense must be 'from' or 'toward', got {sense!r}")


def compass_deg(direction_deg: float, sense: str) -> float:
    """The inverse of :func:`going_to_deg`: the compass direction (``"from"`` or ``"toward"``) of an
    internal going-to angle ``direction_deg`` (counter-clockwise from +x) [deg], in [0, 360)."""
    return going_to_deg(direction_deg, sense)  # both maps are their own inverse


def direction_meaning(key: str) -> str:
    """What a direction key of ``[sea.*]`` means, in words (for help texts and listings)."""
    return _MEANING[key]


def describe_directions(table: dict) -> str:
    """One line naming every direction of a ``[sea]`` table with its meaning, e.g.
    ``wind from_deg = 180 (coming from, compass degrees clockwise from north; toward 90 deg from +x)``."""
    parts = []
    for section, marine in DIRECTION_KEYS.items():
        sub = table.get(section) if isinstance(table, dict) else None
        if not isinstance(sub, dict):
            continue
        for key in (marine, DEPRECATED_DIRECTION_KEY):
            if key in sub and isinstance(sub[key], (int, float)):
                inner = sub[key] if key == DEPRECATED_DIRECTION_KEY else going_to_deg(sub[key], marine[:-4])
                parts.append(f"{section} {key} = {sub[key]:g} ({direction_meaning(key)}; "
                             f"toward {inner:g} deg counter-clockwise from +x)")
    return "; ".join(parts)


def _direction_keys(section: str) -> tuple[str, str]:
    return DIRECTION_KEYS[section], DEPRECATED_DIRECTION_KEY


def replace_direction(section: str, table: dict, key: str) -> dict:
    """``table`` (one ``[sea.<section>]`` table) without the spellings of its direction other than
    ``key``: to be called before ``key`` is set over it, so that the new direction replaces the old one
    whatever its spelling (a sweep's ``sea.current.toward_deg`` over a base that wrote ``direction_deg``).
    A key that is not a direction leaves the table as it is."""
    if section not in DIRECTION_KEYS or key not in _direction_keys(section) or not isinstance(table, dict):
        return table
    return {k: v for k, v in table.items() if k == key or k not in _direction_keys(section)}


def merge_sea_tables(base: dict, over: dict) -> dict:
    """``over`` (a scenario's ``[sea]`` table) on top of ``base`` (a sea preset's), section by section,
    key by key; a direction in ``over`` replaces the direction of ``base`` under any spelling."""
    out = dict(base)
    for section, value in over.items():
        below = out.get(section)
        if isinstance(value, dict) and isinstance(below, dict):
            merged = dict(below)
            for key, item in value.items():
                merged = replace_direction(section, merged, key)
                merged[key] = item
            out[section] = merged
        else:
            out[section] = value
    return out


def _finite(section: str, name: str, value: float) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SeaSettingsError(f"sea.{section}.{name} must be a finite number, got {value!r}")


@dataclass(frozen=True)
class WaveSettings:
    """Irregular waves from a JONSWAP spectrum (docs/sea.md, "Waves").

    Attributes
    ----------
    hs:
        Significant wave height H_s [m], >= 0; 0 means calm (no components at all).
    tp:
        Peak period T_p [s], > 0 (w_p = 2 pi / T_p).
    gamma:
        JONSWAP peak enhancement [-], >= 1; 1 gives Pierson-Moskowitz.
    direction_deg:
        Mean direction the waves travel toward, counter-clockwise from east (+x) [deg]: the internal
        angle. A scenario writes ``from_deg`` (compass, coming from); see :func:`going_to_deg`.
    spreading:
        True: cos^2 directional spreading (2/pi) cos^2(mu), |mu| <= pi/2; False: long-crested.
    components:
        Number of wave components N [-], >= 1 (one direction per component, single summation).
    drift:
        Second-order drift: "newman" (slowly varying, Newman's approximation), "mean" or "off".
    seed:
        Seed of the wave (and current) random draws, an integer >= 0.
    """

    hs: float = 0.0
    tp: float = 2.0
    gamma: float = 3.3
    direction_deg: float = 0.0
    spreading: bool = True
    components: int = 128
    drift: str = "newman"
    seed: int = 1

    def __post_init__(self) -> None:
        for name in ("hs", "tp", "gamma", "direction_deg"):
            _finite("waves", name, getattr(self, name))
        if self.hs < 0:
            raise SeaSettingsError(f"sea.waves.hs must be >= 0 m, got {self.hs!r}")
        if self.tp <= 0:
            raise SeaSettingsError(f"sea.waves.tp must be > 0 s, got {self.tp!r}")
        if self.gamma < 1:
            raise SeaSettingsError(f"sea.waves.gamma must be >= 1 (1 = Pierson-Moskowitz), got {self.gamma!r}")
        if not isinstance(self.spreading, bool):
            raise SeaSettingsError(f"sea.waves.spreading must be true or false, got {self.spreading!r}")
        if isinstance(self.components, bool) or not isinstance(self.components, int) \
                or not 1 <= self.components <= MAX_COMPONENTS:
            raise SeaSettingsError(f"sea.waves.components must be an integer from 1 to {MAX_COMPONENTS}, "
                                   f"got {self.components!r}")
        if self.drift not in DRIFT_MODES:
            raise SeaSettingsError(f"sea.waves.drift must be one of {DRIFT_MODES}, got {self.drift!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise SeaSettingsError(f"sea.waves.seed must be an integer >= 0, got {self.seed!r}")

    @property
    def from_deg(self) -> float:
        """The direction as a scenario writes it: compass degrees, coming from [deg]."""
        return compass_deg(self.direction_deg, "from")

    @property
    def active(self) -> bool:
        return self.hs > 0


@dataclass(frozen=True)
class CurrentSettings:
    """Uniform, irrotational current (docs/sea.md, "Current"): mean plus an Ornstein-Uhlenbeck process per axis.

    Attributes
    ----------
    speed:
        Mean current speed [m/s], >= 0.
    direction_deg:
        Direction the mean current sets toward, counter-clockwise from east (+x) [deg]: the internal
        angle. A scenario writes ``toward_deg`` (compass); see :func:`going_to_deg`.
    sigma:
        Standard deviation of the slow variation per earth axis [m/s], >= 0 (0 = steady).
    time_constant:
        Correlation time T of the variation [s], > 0.
    """

    speed: float = 0.0
    direction_deg: float = 0.0
    sigma: float = 0.0
    time_constant: float = 120.0

    def __post_init__(self) -> None:
        for name in ("speed", "direction_deg", "sigma", "time_constant"):
            _finite("current", name, getattr(self, name))
        if self.speed < 0:
            raise SeaSettingsError(f"sea.current.speed must be >= 0 m/s, got {self.speed!r}")
        if self.sigma < 0:
            raise SeaSettingsError(f"sea.current.sigma must be >= 0 m/s, got {self.sigma!r}")
        if self.time_constant <= 0:
            raise SeaSettingsError(f"sea.current.time_constant must be > 0 s, got {self.time_constant!r}")

    @property
    def toward_deg(self) -> float:
        """The direction as a scenario writes it: compass degrees, setting toward [deg]."""
        return compass_deg(self.direction_deg, "toward")

    @property
    def active(self) -> bool:
        return self.speed > 0 or self.sigma > 0


@dataclass(frozen=True)
class WindSettings:
    """Wind with gusts (docs/sea.md, "Wind"): V_w(t) = max(0, speed + g(t)), g an OU process; constant direction.

    Attributes
    ----------
    speed:
        Mean wind speed [m/s], >= 0.
    direction_deg:
        Direction the air flows toward, counter-clockwise from east (+x) [deg]: the internal angle. A
        scenario writes ``from_deg`` (compass, coming from); see :func:`going_to_deg`.
    gust_sigma:
        Standard deviation sigma_g of the gust process [m/s], >= 0.
    gust_time_constant:
        Correlation time T_g of the gusts [s], > 0.
    seed:
        Seed of the gust draws, an integer >= 0 (independent of the wave seed).
    """

    speed: float = 0.0
    direction_deg: float = 0.0
    gust_sigma: float = 0.0
    gust_time_constant: float = 2.0
    seed: int = 2

    def __post_init__(self) -> None:
        for name in ("speed", "direction_deg", "gust_sigma", "gust_time_constant"):
            _finite("wind", name, getattr(self, name))
        if self.speed < 0:
            raise SeaSettingsError(f"sea.wind.speed must be >= 0 m/s, got {self.speed!r}")
        if self.gust_sigma < 0:
            raise SeaSettingsError(f"sea.wind.gust_sigma must be >= 0 m/s, got {self.gust_sigma!r}")
        if self.gust_time_constant <= 0:
            raise SeaSettingsError(
                f"sea.wind.gust_time_constant must be > 0 s, got {self.gust_time_constant!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise SeaSettingsError(f"sea.wind.seed must be an integer >= 0, got {self.seed!r}")

    @property
    def from_deg(self) -> float:
        """The direction as a scenario writes it: compass degrees, coming from [deg]."""
        return compass_deg(self.direction_deg, "from")

    @property
    def active(self) -> bool:
        return self.speed > 0 or self.gust_sigma > 0


_SECTIONS = {"waves": WaveSettings, "current": CurrentSettings, "wind": WindSettings}


@dataclass(frozen=True)
class SeaSettings:
    """The ``[sea]`` table: waves, current and wind; calm by default."""

    waves: WaveSettings = field(default_factory=WaveSettings)
    current: CurrentSettings = field(default_factory=CurrentSettings)
    wind: WindSettings = field(default_factory=WindSettings)

    @property
    def calm(self) -> bool:
        """True when no load is on: the environment then reproduces the calm model bit for bit."""
        return not (self.waves.active or self.current.active or self.wind.active)

    @classmethod
    def from_table(cls, table: dict, source: str = "<dict>") -> "SeaSettings":
        """Build from the TOML ``[sea]`` table (``{"waves": {...}, "current": {...}, "wind": {...}}``).

        Unknown keys, wrong types and out-of-range values raise :class:`SeaSettingsError` with
        ``source`` and the full key (``sea.waves.xyz``) in the message.
        """
        if not isinstance(table, dict):
            raise SeaSettingsError(f"{source}: [sea] must be a table, got {table!r}")
        parts = {}
        for section, value in table.items():
            if section not in _SECTIONS:
                raise SeaSettingsError(
                    f"{source}: unknown key 'sea.{section}'{_hint(section, _SECTIONS)}; "
                    f"known keys of [sea]: {', '.join(_SECTIONS)}")
            parts[section] = _build_section(section, value, source)
        return cls(**parts)

    def describe(self) -> str:
        """One line for reports, each direction as a scenario writes it (compass degrees clockwise
        from north; waves and wind coming from, the current setting toward): ``waves Hs 0.2 m, Tp 2 s,
        from 250 deg; current 0.3 m/s toward 60 deg; wind 5 m/s from 200 deg`` (calm: ``calm water``)."""
        w, c, a = self.waves, self.current, self.wind
        parts, deg = [], lambda v: f"{round(v, 6):g}"
        if w.active:
            parts.append(f"waves Hs {w.hs:g} m, Tp {w.tp:g} s, from {deg(w.from_deg)} deg")
        if c.active:
            parts.append(f"current {c.speed:g} m/s toward {deg(c.toward_deg)} deg")
        if a.active:
            parts.append(f"wind {a.speed:g} m/s from {deg(a.from_deg)} deg")
        return "; ".join(parts) or "calm water"

    def to_dict(self) -> dict:
        """The settings as the ``[sea]`` table a user writes (for summary.json, report.md,
        compare.json): each direction in its marine key, compass degrees clockwise from north
        (waves and wind ``from_deg``, coming from; the current ``toward_deg``, setting toward),
        not the internal ``direction_deg``. :meth:`from_table` reads it back to the same settings."""
        out = {}
        for name in _SECTIONS:
            marine = DIRECTION_KEYS[name]
            out[name] = {(marine if k == DEPRECATED_DIRECTION_KEY else k):
                         (compass_deg(v, marine[:-4]) if k == DEPRECATED_DIRECTION_KEY else v)
                         for k, v in dataclasses.asdict(getattr(self, name)).items()}
        return out


def _hint(key: str, known) -> str:
    match = difflib.get_close_matches(key, sorted(known), n=1)
    return f" (did you mean {match[0]!r}?)" if match else ""


def _build_section(section: str, table: Any, source: str):
    cls = _SECTIONS[section]
    if not isinstance(table, dict):
        raise SeaSettingsError(f"{source}: [sea.{section}] must be a table, got {table!r}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    marine = DIRECTION_KEYS[section]
    known = [marine if f == DEPRECATED_DIRECTION_KEY else f for f in fields]
    given = [k for k in (marine, DEPRECATED_DIRECTION_KEY) if k in table]
    if len(given) == 2:
        raise SeaSettingsError(
            f"{source}: [sea.{section}] gives both {marine} ({direction_meaning(marine)}) and the deprecated "
            f"{DEPRECATED_DIRECTION_KEY} ({direction_meaning(DEPRECATED_DIRECTION_KEY).removesuffix('; deprecated')}); "
            f"give only {marine}")
    defaults = cls()
    kwargs = {}
    for key, value in table.items():
        where = f"sea.{section}.{key}"
        if key == marine:
            value = _convert(source, where, value, 0.0)  # a finite number
            kwargs[DEPRECATED_DIRECTION_KEY] = going_to_deg(value, marine.removesuffix("_deg"))
            continue
        if key not in fields:
            raise SeaSettingsError(
                f"{source}: unknown key {where!r}{_hint(key, known)}; "
                f"known keys of [sea.{section}]: {', '.join(known)}")
        kwargs[key] = _convert(source, where, value, getattr(defaults, key))
    try:
        return cls(**kwargs)
    except SeaSettingsError as exc:
        raise SeaSettingsError(f"{source}: {exc}") from None


def _convert(source: str, where: str, value: Any, default: Any) -> Any:
    return coerce(source, where, value, default, SeaSettingsError)


def sea_preset_names() -> list[str]:
    """Names of the sea presets shipped in ``usv_mj/physics/sea/presets/`` (``moderate``, ...)."""
    return sorted(p.name[:-5] for p in resources.files("usv_mj.physics.sea.presets").iterdir()
                  if p.name.endswith(".toml"))


def sea_preset_table(name: str) -> dict:
    """The raw ``[sea]`` table of a preset (to merge under a scenario's own ``[sea]`` keys)."""
    path = resources.files("usv_mj.physics.sea.presets") / f"{name}.toml"
    if name not in sea_preset_names():  # a name, never a path
        raise SeaSettingsError(
            f"unknown sea preset {name!r}{_hint(name, sea_preset_names())}; "
            f"sea presets are {', '.join(sea_preset_names())}")
    data = tomllib.loads(path.read_text())
    extra = set(data) - {"sea"}
    if extra:
        raise SeaSettingsError(f"sea preset {name}: only a [sea] table is allowed, found {sorted(extra)}")
    return data.get("sea", {})


def load_sea_preset(name: str) -> SeaSettings:
    """The validated :class:`SeaSettings` of a named preset (``moderate``, ``steady-current``, ``breeze``)."""
    return SeaSettings.from_table(sea_preset_table(name), source=f"sea preset {name}")


# --- hull box and windage (docs/sea.md) ----------------------------------------------------------


@dataclass(frozen=True)
class HullGeometry:
    """The box that feels the waves and the windage that feels the wind (docs/sea.md, "Hull").

    Attributes
    ----------
    length, beam:
        Box length L and beam B [m] (models/usv.xml: about 2.0 m x 0.8 m).
    draft:
        Box draft T [m]; None: the equivalent draft T_eq = m_RB / (rho_w L B) from the ship's m11
        (about 0.0865 m for the paper's ship).
    box_center_x:
        x_b, box centre ahead of the body origin [m].
    diffraction_factor:
        c_dif, a diagonal factor on the Froude-Krylov load (1 = Froude-Krylov only).
    length_overall:
        L_oa [m] (wind yaw moment arm).
    frontal_area, lateral_area:
        Windage A_Fw, A_Lw [m^2].
    lateral_centroid:
        s_L, centroid of A_Lw ahead of the origin [m].
    rho_water, rho_air, g:
        [kg/m^3], [kg/m^3], [m/s^2].
    """

    length: float = 2.0
    beam: float = 0.8
    draft: float | None = None
    box_center_x: float = 0.0
    diffraction_factor: float = 1.0
    length_overall: float = 2.0
    frontal_area: float = 0.25
    lateral_area: float = 0.60
    lateral_centroid: float = 0.0
    rho_water: float = 1025.0
    rho_air: float = 1.225
    g: float = 9.81

    def __post_init__(self) -> None:
        for name in ("length", "beam", "length_overall", "frontal_area", "lateral_area", "rho_water",
                     "rho_air", "g"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise SeaSettingsError(f"hull.{name} must be a finite number > 0, got {value!r}")
        for name in ("box_center_x", "lateral_centroid", "diffraction_factor"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise SeaSettingsError(f"hull.{name} must be a finite number, got {value!r}")
        if self.draft is not None and not (math.isfinite(self.draft) and self.draft > 0):
            raise SeaSettingsError(f"hull.draft must be > 0 m (or None for T_eq), got {self.draft!r}")

    def box_draft(self, rigid_mass: float) -> float:
        """The draft T [m]: the given one, else T_eq = m_RB / (rho_w L B)."""
        if self.draft is not None:
            return float(self.draft)
        return float(rigid_mass) / (self.rho_water * self.length * self.beam)
