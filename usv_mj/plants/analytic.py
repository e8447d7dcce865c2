"""The analytic plant: the 3-DOF model of Eqs. 1-2 integrated with classic RK4.

The thrust is held over each control period (zero-order hold); ``substeps`` RK4 steps of
control_period/substeps each advance one period, with d(t) evaluated at the stage times.

The RK4 step is :func:`usv_mj.physics.sea.sea_rk4_advance`, the package's only one; calm water is its case
with the sea's terms off (:func:`rk4_advance`, bit-identical to RK4 of usv_mj.physics.ship.state_derivative).
"""

from __future__ import annotations

import numpy as np

from numba import njit

from usv_mj.core.registry import PLANTS
from usv_mj.physics.sea.dynamics import calm_rk4_advance, sea_rk4_advance
from usv_mj.physics.disturbances import packed_disturbance
from usv_mj.physics.ship import PaperDisturbance, ShipParams

from usv_mj.plants.base import PlantBase

#: ``rk4_advance(p, dp, t, x, tau_u, tau_r, h, n)``: ``n`` classic RK4 steps of size ``h`` from
#: (t, x) under constant thrust in calm water; returns the new x.
rk4_advance = calm_rk4_advance


@njit(cache=True)
def _step_start(k, t0, dt):
    """The time [s] the k-th step starts from: t0 + k dt (t0 itself for k = 0)."""
    return t0 + k * dt if k > 0 else t0


@njit(cache=True)
def analytic_kernel(k, x, f_u, f_r, p, dp, t0, dt, h, n):
    """:meth:`AnalyticPlant.step` in calm water (step() calls it; the compiled loop's kernel,
    usv_mj.core.kernels): the k-th step, from t0 + k dt."""
    return rk4_advance(p, dp, _step_start(k, t0, dt), x, f_u, f_r, h, n), False


@njit(cache=True)
def analytic_sea_kernel(k, x, f_u, f_r, p, dp, ep, waves, current_grid, wind_grid, t0, dt, h, n):
    """:meth:`AnalyticPlant.step` in a sea (step() calls it; the compiled loop's kernel): the k-th step."""
    return sea_rk4_advance(p, dp, ep, waves, current_grid, wind_grid, _step_start(k, t0, dt), x, f_u, f_r, h, n), False


@PLANTS.register("analytic")
class AnalyticPlant(PlantBase):
    """RK4 integration of M nu_dot + C nu + D nu = tau + d(t) + Delta, eta_dot = J nu (docs/model.md §1).

    Parameters
    ----------
    ship, disturbance:
        The physics (:mod:`usv_mj.physics.ship`); ``disturbance`` of any registered kind
        (:mod:`usv_mj.physics.disturbances`: its d(t) at every RK4 stage time).
    control_period:
        Hold time of the input [s].
    substeps:
        RK4 steps per control period (>= 1).
    environment:
        A :class:`usv_mj.physics.sea.Environment` (waves, current, wind; docs/sea.md §1) or None for calm water.
        Calm water takes the exact same kernels as before the sea existed (bit-identical runs).
    """

    name = "analytic"

    def __init__(self, ship: ShipParams, disturbance: PaperDisturbance, control_period: float = 1e-3,
                 substeps: int = 1, environment=None):
        if not control_period > 0:
            raise ValueError(f"control_period must be > 0, got {control_period!r}")
        if int(substeps) < 1:
            raise ValueError(f"substeps must be >= 1, got {substeps!r}")
        self.ship, self.disturbance = ship, disturbance
        # dp: the packed d(t) of the disturbance's kind (usv_mj.physics.disturbances), made in this process
        self._p, self._dp = ship.as_array(), packed_disturbance(disturbance)
        self.control_period = float(control_period)
        self.substeps = int(substeps)
        self._h = self.control_period / self.substeps
        self._x = np.zeros(6)
        self._t0 = 0.0
        self._t = 0.0
        self._k = 0
        self._calm_args = None
        self.environment = environment if environment is not None and not environment.calm else None
        if self.environment is not None and ship.calm_water_only:
            raise ValueError("AnalyticPlant: this hull's model holds in calm water only (no [sea])")

    def reset(self, eta0, nu0, t0: float = 0.0) -> None:
        self._x = np.concatenate([np.asarray(eta0, float), np.asarray(nu0, float)])
        self._t0 = float(t0)
        self._t = float(t0)
        self._k = 0

    def step(self, tau_u: float, tau_r: float) -> None:
        fn, args = self._kernel_args(self._t)
        self._x, _ = fn(self._k, self._x, float(tau_u), float(tau_r), *args)
        self._k += 1
        # time from the step count: no drift from summing dt 300 000 times
        self._t = self._t0 + self._k * self.control_period

    def _kernel_args(self, t_end: float) -> tuple:
        """(the kernel, its arguments after (k, x, f_u, f_r)), the sea's grids covering ``t_end`` [s]."""
        env = self.environment
        if env is None:
            if self._calm_args is None or self._calm_args[1][2] != self._t0:  # made once per reset
                self._calm_args = analytic_kernel, (self._p, self._dp, self._t0, self.control_period, self._h,
                                                    self.substeps)
            return self._calm_args
        env.ensure_horizon(t_end + 2 * self.control_period)
        return analytic_sea_kernel, (self._p, self._dp, *env.packed, self._t0, self.control_period, self._h,
                                     self.substeps)

    def kernel(self, t_end: float):
        """(analytic_kernel or analytic_sea_kernel, its arrays) for steps up to ``t_end`` [s] (the
        sea's grids cover them); :meth:`step` is the same kernel, one step at a time."""
        from usv_mj.core.kernels import Kernel

        def sync(k, x):
            self._x, self._k = x, k
            self._t = self._t0 + k * self.control_period

        fn, args = self._kernel_args(t_end)
        return Kernel(fn, args, sync, state=())   # writes nothing: the state is returned

    @property
    def time(self) -> float:
        return self._t

    @property
    def state(self) -> np.ndarray:
        """(x, y, psi, u, v, r): a copy (the next :meth:`step` starts from the plant's own; editing
        what it hands out moves nothing, as on the MuJoCo plant)."""
        return self._x.copy()

    @classmethod
    def from_scenario(cls, options, scenario, environment=None, obstacles=(), contact=None, safety_radii=None):
        """The analytic plant of ``scenario`` (``options``: None, it has none) in ``environment`` (obstacles are seen by geometry only:
        the clearance hooks measure them; this plant has no contact forces)."""
        return cls(scenario.ship, scenario.disturbance, scenario.control_period, scenario.plant.substeps,
                   environment=environment)

