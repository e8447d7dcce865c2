"""Hysteresis input quantizer of the paper's Eq. 3, as the state machine of docs/model.md §2.

The printed case table maps one input to different levels after a reversal inside a band and then
chatters, so we implement the quantizer as a state machine on the signed level index ``k``:

    magnitude ladder  L_0 = 0,  L_{2i-1} = u_i,  L_{2i} = u_i (1 + delta),  u_i = rho^(1-i) u_min
    rho = (1 - delta) / (1 + delta)
    up(n)   = u_i            if n = 2i-1;   u_i / (1 - delta)  if n = 2i   (enter L_n from below)
    down(n) = u_i / (1+delta) if n = 2i-1;  u_i                if n = 2i   (= L_n / (1 + delta))

``down(2i)`` is written as ``u_i`` rather than ``L_{2i}/(1+delta)`` so that the thresholds are exact in
floating point (docs/model.md §2's worked example sits on them).

Lemma 1 holds for every input: |Q - tau| <= delta |tau| when |tau| >= u_min, |Q - tau| <= u_min below.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit


@njit(cache=True)
def _level(delta, u_min, n):
    """Magnitude L_n of level index n >= 0."""
    if n == 0:
        return 0.0
    i = (n + 1) // 2
    rho = (1.0 - delta) / (1.0 + delta)
    u_i = u_min * rho ** (1 - i)
    return u_i if n % 2 == 1 else u_i * (1.0 + delta)


@njit(cache=True)
def _up(delta, u_min, n):
    """|tau| above which level n is entered from below (n >= 1)."""
    i = (n + 1) // 2
    rho = (1.0 - delta) / (1.0 + delta)
    u_i = u_min * rho ** (1 - i)
    return u_i if n % 2 == 1 else u_i / (1.0 - delta)


@njit(cache=True)
def _down(delta, u_min, n):
    """|tau| at or below which level n (n >= 1) is left downward."""
    i = (n + 1) // 2
    rho = (1.0 - delta) / (1.0 + delta)
    u_i = u_min * rho ** (1 - i)
    return u_i / (1.0 + delta) if n % 2 == 1 else u_i


@njit(cache=True)
def quantize_step(delta, u_min, k, tau):
    """One step of the state machine: returns (Q(tau), new signed level index k).

    ``tau`` must be finite; the caller checks it (a non-finite input is a controller failure).
    """
    sign = 1 if tau > 0 else (-1 if tau < 0 else 0)
    mag = abs(tau)
    n = abs(k)
    if k != 0 and sign != (1 if k > 0 else -1):
        n = 0
    while n >= 1 and mag <= _down(delta, u_min, n):
        n -= 1
    while mag > _up(delta, u_min, n + 1):
        n += 1
    if n == 0 or sign == 0:
        return 0.0, 0
    return sign * _level(delta, u_min, n), sign * n


@njit(cache=True)
def quantizer_kernel(tau, state, delta, u_min, enabled):
    """:meth:`HysteresisQuantizer.step` natively (usv_mj.core.kernels); ``state`` = (k, output, switches)."""
    if enabled:
        q, k = quantize_step(delta, u_min, np.int64(state[0]), tau)
        state[0] = k
    else:
        q = tau
    if q != state[1]:
        state[2] += 1.0
        state[1] = q
    return q, state[0]


@dataclass(frozen=True)
class QuantizerParams:
    """Parameters of one hysteresis quantizer channel (Eq. 3).

    Attributes
    ----------
    delta:
        Relative band half-width, in (0, 1); the quantization density is rho = (1-delta)/(1+delta).
    u_min:
        Smallest non-zero level tau_min (> 0), in the channel's unit (N or N m); it sets the dead zone.
    """

    delta: float
    u_min: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.delta) and 0.0 < self.delta < 1.0):
            raise ValueError(f"delta must be in (0, 1), got {self.delta!r}")
        if not (math.isfinite(self.u_min) and self.u_min > 0.0):
            raise ValueError(f"u_min must be > 0, got {self.u_min!r}")

    @property
    def density(self) -> float:
        """rho = (1 - delta)/(1 + delta): the larger, the finer the quantizer."""
        return (1.0 - self.delta) / (1.0 + self.delta)

    def level(self, n: int) -> float:
        """Magnitude of the level with index n >= 0 (L_n of docs/model.md §2)."""
        return _level(self.delta, self.u_min, n)


class HysteresisQuantizer:
    """The hysteresis quantizer Q(tau) of Eq. 3 on one input channel.

    >>> q = HysteresisQuantizer(QuantizerParams(delta=0.3, u_min=0.003))
    >>> [round(q.step(t), 7) for t in (0.002, 0.0031, 0.0043, 0.0056)]
    [0.0, 0.003, 0.0039, 0.0055714]

    ``enabled=False`` makes it the identity (Q(tau) = tau), for runs without quantization.
    """

    def __init__(self, params: QuantizerParams, enabled: bool = True):
        self.params = params
        self.enabled = enabled
        # (k, output, switches): the state quantizer_kernel reads and writes, for step() and the
        # compiled loop alike (one implementation)
        self._state = np.zeros(3)
        self._delta, self._u_min = float(params.delta), float(params.u_min)

    @property
    def k(self) -> int:
        """The signed level index of the last output."""
        return int(self._state[0])

    @property
    def output(self) -> float:
        """The last output Q(tau)."""
        return float(self._state[1])

    @property
    def switches(self) -> int:
        """How many times the output changed since :meth:`reset`."""
        return int(self._state[2])

    def reset(self) -> None:
        """Back to level 0, as at t = 0 (docs/model.md §3 step 11)."""
        self._state[:] = 0.0

    def kernel(self):
        """(quantizer_kernel, its state and parameters) for the compiled loop (the state is this
        object's own: nothing to write back)."""
        from usv_mj.core.kernels import Kernel

        return Kernel(quantizer_kernel, (self._state, self._delta, self._u_min, bool(self.enabled)))

    def step(self, tau: float) -> float:
        """Quantize one input sample; returns Q(tau) and counts output changes in ``switches``."""
        return quantizer_kernel(float(tau), self._state, self._delta, self._u_min, bool(self.enabled))[0]
