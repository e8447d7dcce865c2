"""The plant interface that the simulation loop sees (analytic and MuJoCo plants share it).

A plant is any object with

- ``name``: a short identifier ("analytic", "mujoco");
- ``control_period``: the time [s] one :meth:`step` advances;
- ``reset(eta0, nu0, t0=0.0)``: put the ship at pose eta0 = (x [m], y [m], psi [rad]) with body
  velocity nu0 = (u [m/s], v [m/s], r [rad/s]) at time t0 [s];
- ``step(tau_u, tau_r)``: advance one control period with the surge force tau_u [N] and yaw moment
  tau_r [N m] held constant over it (zero-order hold);
- ``time`` [s] and ``state``: the 6-vector (x, y, psi, u, v, r), psi unwrapped (continuous);
- ``close()``: release what the plant holds (a MuJoCo callback, say). Plants are context managers.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np


class Plant(Protocol):
    name: str
    control_period: float

    def reset(self, eta0, nu0, t0: float = 0.0) -> None: ...

    def step(self, tau_u: float, tau_r: float) -> None: ...

    @property
    def time(self) -> float: ...

    @property
    def state(self) -> np.ndarray: ...

    def close(self) -> None: ...


class PlantBase:
    """Context-manager plumbing for plants."""

    def close(self) -> None:  # pragma: no cover - trivial
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
