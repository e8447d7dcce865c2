"""The loads the capability search scales (:mod:`usv_mj.jobs.sweep.capability`): plain data, standard
library only, so that the command line lists them (``usv-mj capability --load``) without the physics."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class LoadKind:
    """A load the capability search can scale: its scenario path(s), unit and default range."""

    name: str
    path: str
    direction_path: str | None
    unit: str
    spacing: str  # "log" or "linear"
    default_min: float
    default_max: float
    label: str


LOADS = {
    "disturbance": LoadKind("disturbance", "disturbance.scale", None, "", "log", 1e-6, 1.0,
                            "disturbance scale s (docs/model.md §1)"),
    "current": LoadKind("current", "sea.current.speed", "sea.current.direction_deg", "m/s", "linear", 0.0, 2.0,
                        "current speed [m/s]"),
    "wind": LoadKind("wind", "sea.wind.speed", "sea.wind.direction_deg", "m/s", "linear", 0.0, 30.0,
                     "mean wind speed [m/s]"),
    "waves": LoadKind("waves", "sea.waves.hs", "sea.waves.direction_deg", "m", "linear", 0.0, 1.0,
                      "significant wave height Hs [m]"),
}
