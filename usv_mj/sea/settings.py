"""Typed, validated settings of the sea state (SEA.md §2-5; the fixed scenario keys of issue 7).

The scenario keys are fixed (other tools read them)::

    [sea.waves]    hs, tp, gamma, direction_deg, spreading, components, drift, seed
    [sea.current]  speed, direction_deg, sigma, time_constant
    [sea.wind]     speed, direction_deg, gust_sigma, gust_time_constant, seed

Every direction is a **going-to** angle in the earth frame, counter-clockwise from +x (SEA.md §0).
Every default is calm (hs = 0, no current, no wind), which reproduces the calm model bit for bit.

:class:`HullGeometry` holds the box and windage of SEA.md §2; it is not a scenario key.

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

from usv_mj.toml_values import coerce

DRIFT_MODES = ("newman", "mean", "off")


from usv_mj.errors import SeaSettingsError  # noqa: E402  (one error family: a ScenarioError)


def _finite(section: str, name: str, value: float) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SeaSettingsError(f"sea.{section}.{name} must be a finite number, got {value!r}")


@dataclass(frozen=True)
class WaveSettings:
    """Irregular waves from a JONSWAP spectrum (SEA.md §3).

    Attributes
    ----------
    hs:
        Significant wave height H_s [m], >= 0; 0 means calm (no components at all).
    tp:
        Peak period T_p [s], > 0 (w_p = 2 pi / T_p).
    gamma:
        JONSWAP peak enhancement [-], >= 1; 1 gives Pierson-Moskowitz.
    direction_deg:
        Mean going-to direction of the waves in the earth frame [deg].
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
        if isinstance(self.components, bool) or not isinstance(self.components, int) or self.components < 1:
            raise SeaSettingsError(f"sea.waves.components must be an integer >= 1, got {self.components!r}")
        if self.drift not in DRIFT_MODES:
            raise SeaSettingsError(f"sea.waves.drift must be one of {DRIFT_MODES}, got {self.drift!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise SeaSettingsError(f"sea.waves.seed must be an integer >= 0, got {self.seed!r}")

    @property
    def active(self) -> bool:
        return self.hs > 0


@dataclass(frozen=True)
class CurrentSettings:
    """Uniform, irrotational current (SEA.md §4): mean plus an Ornstein-Uhlenbeck process per axis.

    Attributes
    ----------
    speed:
        Mean current speed [m/s], >= 0.
    direction_deg:
        Going-to direction of the mean current in the earth frame [deg].
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
    def active(self) -> bool:
        return self.speed > 0 or self.sigma > 0


@dataclass(frozen=True)
class WindSettings:
    """Wind with gusts (SEA.md §5): V_w(t) = max(0, speed + g(t)), g an OU process; constant direction.

    Attributes
    ----------
    speed:
        Mean wind speed [m/s], >= 0.
    direction_deg:
        Going-to direction of the wind in the earth frame [deg] (air flows toward it).
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

    def to_dict(self) -> dict:
        """The settings as a plain nested dict (the ``[sea]`` table; for summary.json)."""
        return {name: dataclasses.asdict(getattr(self, name)) for name in _SECTIONS}


def _hint(key: str, known) -> str:
    match = difflib.get_close_matches(key, sorted(known), n=1)
    return f" (did you mean {match[0]!r}?)" if match else ""


def _build_section(section: str, table: Any, source: str):
    cls = _SECTIONS[section]
    if not isinstance(table, dict):
        raise SeaSettingsError(f"{source}: [sea.{section}] must be a table, got {table!r}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    defaults = cls()
    kwargs = {}
    for key, value in table.items():
        where = f"sea.{section}.{key}"
        if key not in fields:
            raise SeaSettingsError(
                f"{source}: unknown key {where!r}{_hint(key, fields)}; "
                f"known keys of [sea.{section}]: {', '.join(fields)}")
        kwargs[key] = _convert(source, where, value, getattr(defaults, key))
    try:
        return cls(**kwargs)
    except SeaSettingsError as exc:
        raise SeaSettingsError(f"{source}: {exc}") from None


def _convert(source: str, where: str, value: Any, default: Any) -> Any:
    return coerce(source, where, value, default, SeaSettingsError)


def sea_preset_names() -> list[str]:
    """Names of the sea presets shipped in ``usv_mj/sea/presets/`` (``moderate``, ...)."""
    return sorted(p.name[:-5] for p in resources.files("usv_mj.sea.presets").iterdir()
                  if p.name.endswith(".toml"))


def sea_preset_table(name: str) -> dict:
    """The raw ``[sea]`` table of a preset (to merge under a scenario's own ``[sea]`` keys)."""
    path = resources.files("usv_mj.sea.presets") / f"{name}.toml"
    if not path.is_file():
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


# --- hull box and windage (SEA.md §2) ---------------------------------------------------------


@dataclass(frozen=True)
class HullGeometry:
    """The box that feels the waves and the windage that feels the wind (SEA.md §2) [E].

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
