"""The tasks of :mod:`usv_mj.envs`, each registered in :data:`usv_mj.core.registry.TASKS` by a
decorator on its factory, as dm_control's suite registers its own (``@SUITE.add(...)``).

A task is its factory, its typed options and its tags. A task of your own registers the same way
and is then a task like these: ``usv_mj.envs.load("my_task")``, ``gymnasium.make("usv_mj/MyTask-v0")``
and ``usv-mj env my_task`` (once its module is imported: an entry point of the group
``usv_mj.tasks`` names it to every process; ``usv-mj env package.module:my_task`` imports it)::

    import dataclasses
    from usv_mj.core.registry import TASKS
    from usv_mj.envs.suite import TrackOptions, track_environment

    @dataclasses.dataclass(frozen=True)
    class MyOptions(TrackOptions):
        duration: float = 10.0          # [s]

    @TASKS.register("my_task", options=MyOptions, tags=("waves",),
                    scenario={"sea": {"preset": "moderate"}, "trajectory": {"kind": "circle", "radius": 8.0}})
    def my_task(options, scenario, *, random, environment_kwargs):
        return track_environment(options, scenario, random=random, environment_kwargs=environment_kwargs)

The factory's contract: ``factory(options, scenario, *, random, environment_kwargs)`` returns a
:class:`usv_mj.envs.environment.USVEnvironment`, where

- ``options`` is the task's options dataclass filled from ``load``'s keyword options (None when it
  was registered without ``options``); ``duration`` [s] (the episode) and ``preview_times`` [s]
  are read by ``load`` too (30 s and :data:`usv_mj.envs.tasks.DEFAULT_PREVIEW` when the dataclass
  has no such field);
- ``scenario`` is the episode's :class:`usv_mj.scenario.spec.Scenario`: ``load``'s ``scenario`` as
  is, else the preset (``preset``, "paper"), the task's ``scenario`` tables and the user's
  ``overrides`` / ``vessel`` merged in that order, with ``control_period``, ``plant.substeps`` and
  a duration that covers the episode and its reference preview; its plant is MuJoCo's;
- ``random`` is the seed of ``load`` (an int, a ``numpy.random.RandomState`` or None), for the
  task's own random state;
- ``environment_kwargs`` are :class:`~usv_mj.envs.environment.USVEnvironment`'s keyword arguments
  (``time_limit`` [s], a whole number of control periods, ``n_sub_steps``, ``flat_observation``,
  ``legacy_step``): pass them on, and give the task the same ``time_limit``.

Tags say what a task holds: "waves" (the task's own sea: a vessel that runs in calm water only is
refused there, and the message names the calm tasks) and "obstacles" (a randomised harbour).
"""

from __future__ import annotations

import dataclasses
import math

from usv_mj.builder import make_environment, make_plant
from usv_mj.core.registry import TASKS

from usv_mj.envs.environment import USVEnvironment
from usv_mj.envs.physics import USVPhysics
from usv_mj.envs.tasks import DEFAULT_FORCE, DEFAULT_PREVIEW, HarbourTask, TrackTask

#: the sea of the wave tasks: the moderate sea (docs/sea.md §3), with compass directions: current
#: setting toward 060, wind from the south (180)
WAVES_SEA = {"preset": "moderate",
             "current": {"speed": 0.3, "toward_deg": 60.0, "sigma": 0.0, "time_constant": 120.0},
             "wind": {"speed": 5.0, "from_deg": 180.0, "gust_sigma": 1.0, "gust_time_constant": 2.0, "seed": 2}}
HARBOUR_FUNNEL = {"rho_xy": [3.0, 0.5], "rate": 0.2}  # as examples/scenarios/harbour_gap.toml
#: the harbour tasks' tables: the funnel, a straight plan from the origin to 40 m ahead, the start
HARBOUR_TABLES = {"funnel": HARBOUR_FUNNEL,
                  "trajectory": {"kind": "waypoints", "points": [[0.0, 0.0], [40.0, 0.0]], "speed": 0.6},
                  "initial": {"eta": [0.0, 0.0, 0.0]}}

#: [m] the harbour tasks' goal_distance: past the piers (x = 10-21 m) and the buoys drawn at 0.55-0.9
#: of it; at most 500 m (each layout's plan is smoothed along the whole distance, 0.4 s per 100 m)
GOAL_DISTANCE_RANGE = (30.0, 500.0)


@dataclasses.dataclass(frozen=True)
class TrackOptions:
    """The options of the track tasks (:class:`usv_mj.envs.tasks.TrackTask`'s, and the episode's length)."""

    duration: float = 30.0                          # [s] the episode
    quantize: bool = True                           # the hysteresis quantizer of Eq. 3 between action and actuators
    max_surge_force: float = DEFAULT_FORCE          # [N] the action bound of an unlimited surge channel
    max_yaw_moment: float = DEFAULT_FORCE           # [N m] the action bound of an unlimited yaw channel
    preview_times: tuple = DEFAULT_PREVIEW          # [s] the reference preview's times ahead
    start_offset: tuple = (3.0, 3.0, 0.5)           # [m, m, rad] the start's largest offsets from the reference
    max_distance: float = 50.0                      # [m] farther from the reference ends the episode ("lost")

    def task_kwargs(self) -> dict:
        """The keyword arguments of :class:`TrackTask` these options give."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(TrackOptions) if f.name != "duration"}


@dataclasses.dataclass(frozen=True)
class HarbourOptions(TrackOptions):
    """The options of the harbour tasks (:class:`usv_mj.envs.tasks.HarbourTask`'s): the track's, a
    longer episode, the start on the plan (no offset), the rangefinders and the goal."""

    duration: float = 90.0                          # [s]
    start_offset: tuple = (0.0, 0.0, 0.0)           # [m, m, rad] (the harbour's start is the plan's)
    n_rays: int = 16                                # rangefinders fanned around the hull
    max_range: float = 20.0                         # [m] the rangefinders' range
    goal_radius: float = 1.5                        # [m] nearer the goal ends the episode ("goal")
    goal_distance: float = 40.0                     # [m] the goal ahead of the start, in GOAL_DISTANCE_RANGE

    def __post_init__(self):
        lo, hi = GOAL_DISTANCE_RANGE
        goal_distance = float(self.goal_distance)
        if not (math.isfinite(goal_distance) and lo <= goal_distance <= hi):
            raise ValueError(f"goal_distance must be in [{lo:g}, {hi:g}] m (the goal beyond the piers at x = 10-21 m, "
                             f"within reach of the planner), got {self.goal_distance!r}")
        object.__setattr__(self, "goal_distance", goal_distance)

    def task_kwargs(self) -> dict:
        return {**super().task_kwargs(), "n_rays": self.n_rays, "max_range": self.max_range,
                "goal_radius": self.goal_radius}


def track_environment(options: TrackOptions, scenario, *, random, environment_kwargs, task_class=TrackTask):
    """A track task's environment: ``task_class`` (:class:`TrackTask` or a subclass) on one MuJoCo
    plant of ``scenario`` (made by :func:`usv_mj.builder.make_plant`)."""
    task = task_class(scenario, random=random, time_limit=environment_kwargs["time_limit"], **options.task_kwargs())
    return USVEnvironment(USVPhysics.from_plant(make_plant(scenario, "mujoco")), task, **environment_kwargs)


def harbour_environment(options: HarbourOptions, scenario, *, random, environment_kwargs):
    """A harbour task's environment: a new randomised layout (:func:`usv_mj.envs.layout.harbour_layout`)
    and its MuJoCo plant with rangefinders at every episode, in one sea for every layout."""
    from usv_mj.obstacles.clearance import MuJoCoClearance

    from usv_mj.envs.layout import harbour_layout

    time_limit = environment_kwargs["time_limit"]
    tsk = HarbourTask(scenario, margin_m=scenario.guidance.margin_m, random=random, time_limit=time_limit,
                      **options.task_kwargs())
    tsk.goal_distance = options.goal_distance
    sea = make_environment(scenario)  # one sea for every layout (a pure function of t and the seeds)
    duration = float(options.duration)

    def build():
        layout = harbour_layout(tsk.random, scenario, scenario.guidance, duration, options.goal_distance)
        episode = dataclasses.replace(scenario, obstacles=tuple(layout.obstacles))
        plant = make_plant(episode, "mujoco", sea, rangefinders=tsk.ray_angles)
        tsk.attach_layout(layout, MuJoCoClearance(plant), episode)
        return USVPhysics.from_plant(plant)

    return USVEnvironment(build(), tsk, rebuild=build, **environment_kwargs)


@TASKS.register("track", options=TrackOptions)
def track(options, scenario, *, random, environment_kwargs):
    """Follow the paper's reference (docs/model.md §4) from a start drawn uniformly within
    +-start_offset of its pose at t = 0, at rest; 30 s episodes."""
    return track_environment(options, scenario, random=random, environment_kwargs=environment_kwargs)


@TASKS.register("track_waves", options=TrackOptions, tags=("waves",), scenario={"sea": WAVES_SEA})
def track_waves(options, scenario, *, random, environment_kwargs):
    """``track`` in the moderate sea (JONSWAP Hs 0.2 m, Tp 2 s, from the west) with a 0.3 m/s
    current (setting toward compass 060) and a 5 m/s wind (from the south; gusts sigma 1 m/s)."""
    return track_environment(options, scenario, random=random, environment_kwargs=environment_kwargs)


@TASKS.register("harbor", options=HarbourOptions, tags=("obstacles",), scenario=HARBOUR_TABLES)
def harbor(options, scenario, *, random, environment_kwargs):
    """From the origin to a goal goal_distance ahead through a randomised harbour (two piers with a
    gap, a buoy field; a new layout every episode) without contact; 16 rangefinders; 90 s episodes."""
    return harbour_environment(options, scenario, random=random, environment_kwargs=environment_kwargs)


@TASKS.register("harbor_waves", options=HarbourOptions, tags=("obstacles", "waves"),
                scenario={**HARBOUR_TABLES, "sea": WAVES_SEA})
def harbor_waves(options, scenario, *, random, environment_kwargs):
    """``harbor`` in the sea of ``track_waves``."""
    return harbour_environment(options, scenario, random=random, environment_kwargs=environment_kwargs)
