"""A hull's two input channels: what its plant receives over a control period, typed.

Every hull has two channels, a surge one and a yaw one (the record's ``tau_u, tau_r`` columns and
their quantized, realized and saturated companions). What they carry is the vessel's:

- :data:`FORCES` (the paper's ship, CyberShip II, the Otter, Clarke's ships): the generalized force
  in surge tau_u [N] and the yaw moment tau_r [N m] (positive to port); the hysteresis quantizer of
  Eq. 3 acts on them;
- a ruddered ship of the MMG standard method (KVLCC2, :mod:`usv_mj.physics.mmg`,
  :func:`rudder_channels`): the propeller revolutions n_P [1/s] and the rudder angle delta [rad]
  (positive to port; shown in degrees), which a force command reaches through an **allocation**
  (the packed MMG block: the n_P and delta that make the commanded force at the present state).

Every consumer (the build, the control step, figures, video, report, compare, manoeuvres, the
environments) reads names, units and the allocation from here or from a record's metadata
(:meth:`RunChannels.to_metadata`), never from the vessel's kind.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Channel:
    """One input channel.

    Attributes
    ----------
    symbol: its name in formulas and labels ("tau_u", "n_P", "delta").
    quantity: what it is, in words ("surge force", "rudder angle").
    unit: its SI unit ("N", "N m", "1/s", "rad").
    shown_unit: the unit figures and reports show it in ("deg" for an angle); "" = ``unit``.
    shown_factor: shown value = ``shown_factor`` x value.
    largest_limit: the largest actuator limit the channel may be given, in ``unit`` (a rudder
        angle below pi/2); inf: any.
    short: its name in one-line descriptions ("surge", "rudder angle"); "" = ``symbol``.
    rate_unit: the unit of its rate of change ("N/s", "1/s^2"); "" = ``unit``/s.
    """

    symbol: str
    quantity: str
    unit: str
    shown_unit: str = ""
    shown_factor: float = 1.0
    largest_limit: float = math.inf
    short: str = ""
    rate_unit: str = ""

    @property
    def display_unit(self) -> str:
        return self.shown_unit or self.unit

    def label(self) -> str:
        """"surge force tau_u [N]": the quantity, the symbol and the unit it is shown in."""
        return f"{self.quantity} {self.symbol} [{self.display_unit}]"

    @property
    def name(self) -> str:
        return self.short or self.symbol

    @property
    def rate(self) -> str:
        return self.rate_unit or f"{self.unit}/s"

    def to_metadata(self) -> dict:
        d = dataclasses.asdict(self)
        d["largest_limit"] = d["largest_limit"] if math.isfinite(d["largest_limit"]) else None
        return d

    @classmethod
    def from_metadata(cls, d: dict) -> "Channel":
        known = {f.name for f in dataclasses.fields(cls)}
        d = {k: v for k, v in d.items() if k in known}
        if d.get("largest_limit") is None:
            d.pop("largest_limit", None)
        return cls(**d)


SURGE_FORCE = Channel("tau_u", "surge force", "N", short="surge")
YAW_MOMENT = Channel("tau_r", "yaw moment", "N m", short="yaw")
PROPELLER = Channel("n_P", "propeller revolutions", "1/s", rate_unit="1/s^2")
RUDDER_ANGLE = Channel("delta", "rudder angle", "rad", "deg", 180.0 / math.pi, math.pi / 2, short="rudder angle")


@dataclass(frozen=True)
class Channels:
    """A hull's two input channels (module docstring).

    Attributes
    ----------
    surge, yaw: the two :class:`Channel` s.
    quantized: the hysteresis quantizer of Eq. 3 (a quantizer of forces) applies to a command
        in these channels.
    allocation: None (a force command is these channels' own command), or the packed MMG block a
        force command is allocated through onto them (n_P and delta at the present state).
    """

    surge: Channel = SURGE_FORCE
    yaw: Channel = YAW_MOMENT
    quantized: bool = True
    allocation: tuple | None = None

    @property
    def forces(self) -> bool:
        """The channels are the generalized forces themselves (tau_u [N], tau_r [N m])."""
        return (self.surge, self.yaw) == (SURGE_FORCE, YAW_MOMENT)

    def __iter__(self):
        return iter((self.surge, self.yaw))


FORCES = Channels()


def rudder_channels(mmg) -> Channels:
    """A ruddered ship's channels (n_P [1/s], delta [rad]); force commands are allocated through
    the packed MMG block ``mmg``."""
    return Channels(PROPELLER, RUDDER_ANGLE, quantized=False, allocation=tuple(float(v) for v in mmg))


@dataclass(frozen=True)
class RunChannels:
    """What a run's record holds in its channel columns: ``command`` (tau and Q(tau): the
    controller's command) and ``applied`` (f: what the plant received). They differ when a force
    command is allocated to a ruddered vessel's n_P and rudder angle."""

    command: Channels = FORCES
    applied: Channels = FORCES

    @property
    def allocated(self) -> bool:
        return self.command != self.applied

    def to_metadata(self) -> dict:
        """The record's ``metadata["channels"]`` (plain data, read back by :meth:`from_metadata`)."""
        return {"command": [c.to_metadata() for c in self.command],
                "applied": [c.to_metadata() for c in self.applied],
                "allocated": self.allocated}

    @classmethod
    def from_metadata(cls, m) -> "RunChannels":
        """The channels of a record's ``metadata["channels"]``: the dict of :meth:`to_metadata`, or
        the names an earlier version wrote ("forces", "rudder", "allocated"; missing: forces).
        (The allocation's MMG block is not in a record: ``applied.allocation`` is None.)"""
        if not isinstance(m, dict):
            legacy = {"rudder": (RUDDER_CHANNELS, RUDDER_CHANNELS), "allocated": (FORCES, RUDDER_CHANNELS)}
            return cls(*legacy.get(m, (FORCES, FORCES)))

        def channels(part):
            chans = m.get(part)
            if not chans:
                return FORCES
            surge, yaw = (Channel.from_metadata(c) for c in chans)
            known = FORCES if (surge, yaw) == (SURGE_FORCE, YAW_MOMENT) else None
            return known or Channels(surge, yaw, quantized=part == "command" and (surge, yaw) == tuple(FORCES))

        command, applied = channels("command"), channels("applied")
        if not m.get("allocated", False) and command != applied:   # the same channels, read twice
            applied = command
        return cls(command, applied)


#: a ruddered vessel's channels without an allocation (what a record of one says, its block unknown)
RUDDER_CHANNELS = Channels(PROPELLER, RUDDER_ANGLE, quantized=False)


#: what a controller may declare it commands (its ``commands``): forces, the vessel's own channels
#: whatever they are ("any": the open-loop and zig-zag inputs), or a ruddered ship's n_P and rudder angle
COMMANDS = ("forces", "any", "rudder")


def run_channels(vessel: Channels, commands: str = "forces", vessel_name: str = "the vessel") -> RunChannels:
    """What a run's channel columns hold when a controller commanding ``commands``
    (:data:`COMMANDS`) drives a vessel with the ``vessel`` channels: a force command on force
    channels, or allocated onto a ruddered ship's; "any" in the vessel's own channels; "rudder" on a
    ruddered ship's. ValueError, in one sentence naming ``vessel_name``, when it cannot drive it."""
    if commands not in COMMANDS:
        raise ValueError(f"a controller's commands must be one of {', '.join(map(repr, COMMANDS))}, got {commands!r}")
    if commands == "any":
        return RunChannels(vessel, vessel)
    if commands == "forces":
        if vessel.forces or vessel.allocation is not None:
            return RunChannels(FORCES, vessel)
        raise ValueError(f"it commands a surge force and a yaw moment, but {vessel_name} takes "
                         f"{vessel.surge.label()} and {vessel.yaw.label()} and has no allocation from forces "
                         f"(only an MMG hull has one): use a controller that commands its channels")
    if (vessel.surge.symbol, vessel.yaw.symbol) == (PROPELLER.symbol, RUDDER_ANGLE.symbol):
        return RunChannels(vessel, vessel)
    raise ValueError(f"it commands the propeller's n_P and a rudder angle, but {vessel_name} takes "
                     f"{vessel.surge.label()} and {vessel.yaw.label()}")
