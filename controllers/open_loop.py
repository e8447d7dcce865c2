"""Open-loop inputs: the surge force tau_u [N] and yaw moment tau_r [N m] as given functions of time.

A controller kind that ignores the state and the reference (``[controller] kind = "open_loop"``),
for manoeuvres, identification runs and stability studies (docs/model.md §8: the paper's hull is
directionally unstable with no control). Each input is a constant or a table over ``times``:

    [controller]
    kind = "open_loop"
    tau_u = 53.7                       # N: a constant (the drag at 0.6 m/s)
    tau_r = 0.0                        # N m

    [controller]                       # a step of tau_r at 5 s, a ramp of tau_u from 0 to 10 s
    kind = "open_loop"
    times = [0.0, 5.0, 5.0, 10.0]      # s, non-decreasing; a time given twice is a step
    tau_u = [0.0, 26.85, 26.85, 53.7]  # N, one value per time (or one number: a constant)
    tau_r = [0.0, 0.0, 2.0, 2.0]       # N m
    interpolation = "linear"           # "linear" (ramps between the points) or "step"

With ``interpolation = "step"`` the value at time t is the table's value at the last time <= t (a
zero-order hold: a step at each time); with ``"linear"`` it is interpolated linearly between the
points, and a time given twice is a step (from that time on the second value holds: the inputs are
continuous from the right). Before the first time and after the last one the end values hold. The
loop quantizes the inputs like any controller's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from usv_mj.record.criteria import NotJudged
from usv_mj.core.errors import ScenarioError
from usv_mj.core.registry import CONTROLLERS

INTERPOLATIONS = ("step", "linear")


def _number(name, v):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ScenarioError(f"controller.{name} must be a finite number, got {v!r}")
    return float(v)


@dataclass(frozen=True)
class OpenLoopGains:
    """The inputs as functions of time (module docstring). ``tau_u`` and ``tau_r`` are each a number
    (a constant) or a list with one value per entry of ``times``; None is 0."""

    times: tuple | None = None       # s: the table's times, non-decreasing (None: constant inputs)
    tau_u: float | tuple | None = None   # N: surge force, a number or one value per time
    tau_r: float | tuple | None = None   # N m: yaw moment, a number or one value per time
    interpolation: str = "linear"    # "linear" or "step" (zero-order hold)

    def __post_init__(self) -> None:
        if self.interpolation not in INTERPOLATIONS:
            raise ScenarioError(f"controller.interpolation must be one of {', '.join(map(repr, INTERPOLATIONS))}, "
                                f"got {self.interpolation!r}")
        times = self.times
        if times is not None:
            if not isinstance(times, (list, tuple)) or not times:
                raise ScenarioError(f"controller.times must be a non-empty list of times [s], got {times!r}")
            times = tuple(_number(f"times[{i}]", v) for i, v in enumerate(times))
            bad = next((i for i in range(1, len(times)) if times[i] < times[i - 1]), None)
            if bad is not None:
                raise ScenarioError(f"controller.times must be non-decreasing: times[{bad}] = {times[bad]!r} "
                                    f"< times[{bad - 1}] = {times[bad - 1]!r}")
            object.__setattr__(self, "times", times)
        for name in ("tau_u", "tau_r"):
            v = getattr(self, name)
            if v is None:  # kept None (read as 0 by table()): the scenario loader reads a default of None
                continue   # as "any type", so that a table's key may take a number or a list
            if isinstance(v, (list, tuple)):
                if times is None:
                    raise ScenarioError(f"controller.{name} is a list of {len(v)} values but controller.times "
                                        "is not given; give times, or one number for a constant")
                if len(v) != len(times):
                    raise ScenarioError(f"controller.{name} has {len(v)} values but controller.times has "
                                        f"{len(times)}: one value per time")
                v = tuple(_number(f"{name}[{i}]", x) for i, x in enumerate(v))
            else:
                v = _number(name, v)
            object.__setattr__(self, name, v)

    def table(self, name: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(times, values) of input ``name`` ("tau_u" or "tau_r"); a constant is a table of one point."""
        v = getattr(self, name)
        if isinstance(v, tuple):
            return self.times, v
        return (0.0,), (0.0 if v is None else v,)


@njit(cache=True)
def table_at(times, values, t, linear):
    """The table's value at time ``t`` [s] (module docstring: zero-order hold, or linear when
    ``linear``; ends held): the one evaluation, for ``__call__`` and the compiled loop."""
    i = np.searchsorted(times, t, side="right") - 1  # the last time <= t (times[i + 1] > t: no division by 0)
    if i < 0:
        return values[0]
    if not linear or i == len(times) - 1:
        return values[i]
    s = (t - times[i]) / (times[i + 1] - times[i])
    return values[i] + s * (values[i + 1] - values[i])


def table_value(times, values, t: float, interpolation: str) -> float:
    """The table's value at time ``t`` (:func:`table_at` on the tuples of :meth:`OpenLoopGains.table`)."""
    return float(table_at(np.asarray(times, float), np.asarray(values, float), float(t), interpolation == "linear"))


@njit(cache=True)
def open_loop_kernel(t, x, ref, tu, vu, tr, vr, linear, diag):
    """The compiled loop's kernel of :class:`OpenLoopController` (usv_mj.core.kernels): ``__call__`` natively."""
    return table_at(tu, vu, t, linear), table_at(tr, vr, t, linear), diag


@CONTROLLERS.register("open_loop", gains=OpenLoopGains)
class OpenLoopController:
    """Commanded tau_u(t), tau_r(t) from :class:`OpenLoopGains`; no feedback (module docstring)."""

    commands = "any"   # its channels are numbers given as they are: a force, or a ruddered vessel's n_P and angle (usv_mj.builder.commands_error)

    name = "open_loop"
    diagnostic_fields = ()
    criterion = NotJudged("open-loop input")

    @classmethod
    def from_scenario(cls, gains: OpenLoopGains, scenario) -> "OpenLoopController":
        return cls(gains)

    def __init__(self, gains: OpenLoopGains):
        self.gains = gains
        self._u = tuple(np.asarray(a, float) for a in gains.table("tau_u"))
        self._r = tuple(np.asarray(a, float) for a in gains.table("tau_r"))
        self._linear = gains.interpolation == "linear"
        self._diag = np.zeros(0)

    def reset(self) -> None:
        pass

    def kernel(self):
        """(open_loop_kernel, its tables) for the compiled loop."""
        from usv_mj.core.kernels import Kernel

        return Kernel(open_loop_kernel, (*self._u, *self._r, self._linear, self._diag), n_diag=len(self._diag))

    def __call__(self, t, state, reference):
        return open_loop_kernel(float(t), state, reference, *self._u, *self._r, self._linear, self._diag)
