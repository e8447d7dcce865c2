"""What the video shows beyond the ship: the sea and the obstacles of the run.

The planner (parent process) reads them from the record's metadata into a small picklable
:class:`RenderWorld` that rides on every :class:`~usv_mj.outputs.render.planner.FrameSpec`; each rendering
process resolves it once (:class:`ResolvedWorld`: the seeded :class:`usv_mj.physics.sea.Environment`, the
obstacle specs and their inflation) and keeps it while the same world comes in.

- Sea: ``record.metadata["scenario"]["sea"]`` (the settings the plant ran with) and the ship (its
  rigid mass sets the equivalent draft of docs/sea.md §2, which the elevation does not use but the
  Environment's constructor needs). The Environment is a pure function of (t, eta, nu) with every
  random draw made from the seeds (docs/sea.md §0), so the renderer's waves are the plant's.
- Obstacles: ``record.metadata["scenario"]["obstacles"]`` (the scenario's tables)
  and the per-obstacle ``inflation_m`` of ``record.metadata["obstacles"]["per_obstacle"]`` (the
  :class:`~usv_mj.obstacles.sink.ObstacleLog` summary) for the safety boundary.
"""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import dataclass

import numpy as np

SEA_NODES = 101          # hfield nodes per side: 201 measured 2x slower a frame on Mesa (upload)
SEA_BASE_EXTENT = 20.0   # m, the hfield's smallest side (docs/sea.md §6)
SEA_EXTENT_STEP = 5.0    # m, the hfield's side is a multiple of this


@dataclass(frozen=True)
class RenderWorld:
    """Picklable description of the sea and obstacles of a run (JSON text: cheap to compare)."""

    sea: str = ""            # JSON of the scenario's "sea" table ("" = calm)
    ship: str = ""           # JSON of the scenario's "ship" table
    duration: float = 0.0    # s, the run's duration (the environment's horizon)
    obstacles: str = ""      # JSON list of the scenario's obstacle tables ("" = none)
    inflation: tuple = ()    # m per obstacle (NaN: no boundary drawn)

    @property
    def empty(self) -> bool:
        return not self.sea and not self.obstacles


def render_world(record) -> RenderWorld | None:
    """The :class:`RenderWorld` of a record (None when its sea is calm and it has no obstacles)."""
    md = getattr(record, "metadata", None) or {}
    sc = md.get("scenario")
    if not isinstance(sc, dict):
        return None
    sea_json = ""
    sea = sc.get("sea")
    if isinstance(sea, dict):
        try:
            from usv_mj.physics.sea.settings import SeaSettings

            if not SeaSettings.from_table(sea, "record.metadata['scenario']['sea']").calm:
                sea_json = json.dumps(sea, sort_keys=True)
        except (ValueError, TypeError) as exc:
            warnings.warn(f"render: the record's sea settings cannot be read ({exc}); the video shows calm water",
                          RuntimeWarning, stacklevel=2)
    obstacles = sc.get("obstacles") or []
    inflation = ()
    if obstacles:
        per = ((md.get("obstacles") or {}).get("per_obstacle") or [])
        vals = [p.get("inflation_m") if isinstance(p, dict) else None for p in per]
        inflation = tuple(float(v) if isinstance(v, (int, float)) and math.isfinite(v) else math.nan
                          for v in (vals + [None] * len(obstacles))[:len(obstacles)])
    world = RenderWorld(sea=sea_json, ship=json.dumps(sc.get("ship") or {}, sort_keys=True),
                        duration=float(sc.get("duration") or md.get("duration_s") or 0.0),
                        obstacles=json.dumps(obstacles, sort_keys=True) if obstacles else "", inflation=inflation)
    return None if world.empty else world


def hull_dimensions(source) -> tuple[float, float, float] | None:
    """(L, B, T) [m] (no MuJoCo import: the planner and the parent process call it before the GL
    backend is chosen) of the vessel of ``source`` (a Scenario, a record, or a record's metadata
    ``scenario`` table), or None for the paper hull (the model file's own, drawn unchanged) and
    for a record that names no vessel."""
    from usv_mj.vessels import PAPER_DIMENSIONS

    vessel = getattr(source, "vessel", None)
    model = getattr(vessel, "model", None)
    if vessel is None:
        md = getattr(source, "metadata", None)
        from usv_mj.core.errors import ScenarioError
        from usv_mj.scenario.spec import vessel_of_table as of_table

        try:
            model = of_table(md.get("scenario") if isinstance(md, dict) else source)
        except (ScenarioError, ValueError):   # a vessel this process cannot resolve: the model file's hull
            return None
    d = getattr(model, "dimensions", None)
    if d is None or (d.L, d.B, d.T) == (PAPER_DIMENSIONS.L, PAPER_DIMENSIONS.B, PAPER_DIMENSIONS.T):
        return None
    return (float(d.L), float(d.B), float(d.T))


def _ship(table: dict):
    from usv_mj.physics.ship import ShipParams

    fields = ShipParams.__dataclass_fields__
    kw = {k: (tuple(v) if isinstance(v, list) else v) for k, v in table.items() if k in fields}
    return ShipParams(**kw)


def _obstacle(table: dict):
    """An ObstacleSpec from a scenario's obstacle table as ``Scenario.to_dict`` writes it (every field)."""
    from usv_mj.scenario.obstacles import ObstacleSpec

    fields = ObstacleSpec.__dataclass_fields__
    return ObstacleSpec(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in table.items() if k in fields})


class ResolvedWorld:
    """A :class:`RenderWorld` made usable in a rendering process: ``environment`` (or None),
    ``obstacles`` (ObstacleSpec tuple), ``inflation`` (array per obstacle, NaN = none)."""

    def __init__(self, world: RenderWorld):
        self.world = world
        self.environment = None
        if world.sea:
            from usv_mj.physics.sea import Environment
            from usv_mj.physics.sea.settings import SeaSettings

            settings = SeaSettings.from_table(json.loads(world.sea), "render world")
            try:
                ship = _ship(json.loads(world.ship)) if world.ship else None
            except (TypeError, ValueError):
                ship = None
            self.environment = Environment(settings, ship=ship, t_max=max(world.duration, 1.0) + 1.0)
        self.obstacles = ()
        if world.obstacles:
            self.obstacles = tuple(_obstacle(t) for t in json.loads(world.obstacles))
        self.inflation = np.array(world.inflation, dtype=float) if world.inflation else None
        self.any_moving = any(o.moving for o in self.obstacles)


def sea_extent(half_width: float, half_height: float) -> float:
    """Side [m] of the square hfield that covers a view of +-half_width x +-half_height around its
    centre: the larger side plus 5 %, rounded up to a multiple of SEA_EXTENT_STEP (so the cell size,
    and with it the sampled points, changes only now and then while the camera zooms), at least
    SEA_BASE_EXTENT (101 nodes: cells of 0.2 m at the closest zoom, 0.5 m for a 46 m wide view)."""
    need = 2.0 * max(half_width, half_height) * 1.05
    return max(SEA_BASE_EXTENT, SEA_EXTENT_STEP * math.ceil(need / SEA_EXTENT_STEP))
