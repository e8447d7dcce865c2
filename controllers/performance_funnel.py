"""Prescribed-performance funnel and error transformation (paper Eqs. 8-10 and 24).

rho(t) = (rho_0 - rho_inf) exp(-kappa t) + rho_inf        (Eq. 9)
z = e / rho,   e* = ln((1 + z)/(1 - z))                   (Eq. 10)

|z| >= 1 is a funnel violation. The transform is then undefined; we evaluate it at |z| clamped to
``Z_LIMIT`` so that no NaN ever leaves the controller, and the caller records the violation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from numba import njit

Z_LIMIT = 1.0 - 1e-9


@dataclass(frozen=True)
class PerformanceFunnel:
    """One performance bound rho(t) of Eq. 9.

    Attributes
    ----------
    rho_0:
        Initial half-width (m for position, rad for heading).
    rho_inf:
        Final half-width, 0 < rho_inf < rho_0 (same unit).
    rate:
        kappa, the exponential rate of shrinking [1/s], > 0.
    """

    rho_0: float
    rho_inf: float
    rate: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rho_inf) and self.rho_inf > 0):
            raise ValueError(f"rho_inf must be > 0, got {self.rho_inf!r}")
        if not (math.isfinite(self.rho_0) and self.rho_0 > self.rho_inf):
            raise ValueError(f"rho_0 must be greater than rho_inf ({self.rho_inf!r}), got {self.rho_0!r}")
        if not (math.isfinite(self.rate) and self.rate > 0):
            raise ValueError(f"rate must be > 0, got {self.rate!r}")

    def __call__(self, t):
        """rho(t); works on floats and numpy arrays."""
        import numpy as np

        return (self.rho_0 - self.rho_inf) * np.exp(-self.rate * np.asarray(t)) + self.rho_inf


@njit(cache=True)
def funnel_bound(rho_0, rho_inf, rate, t):
    """rho(t) of Eq. 9."""
    return (rho_0 - rho_inf) * math.exp(-rate * t) + rho_inf


@njit(cache=True)
def error_transform(z):
    """e* = ln((1+z)/(1-z)) of Eq. 10, with |z| clamped below 1 (see module docstring)."""
    if z > Z_LIMIT:
        z = Z_LIMIT
    elif z < -Z_LIMIT:
        z = -Z_LIMIT
    return math.log((1.0 + z) / (1.0 - z))


def funnels_of(scenario) -> tuple[PerformanceFunnel, PerformanceFunnel]:
    """The funnels of a scenario's ``[funnel]`` table: (rho_1 = rho_2 for e1, e2 [m], rho_3 for e3 [rad])."""
    f = scenario.funnel
    return (PerformanceFunnel(f.rho_xy[0], f.rho_xy[1], f.rate), PerformanceFunnel(f.rho_psi[0], f.rho_psi[1], f.rate))

