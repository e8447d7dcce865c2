"""The control step: one control period of one vessel's input channels, written once.

What happens to a controller's command (or an environment's action) before the plant holds it
over the period, in this order (docs/model.md §2-3):

1. **clip** to the channel's bounds (the environments' action bounds; a run's loop passes
   -inf/inf: its controller's output goes on as it is, its divergence checked before);
2. **quantize** each channel with the hysteresis quantizer of Eq. 3 (``quantizer_kernel`` of
   ``controllers/hysteresis_quantizer.py``; off: Q(tau) = tau): the transmitted command;
3. **actuators**: what the thrusters realize of it (:func:`usv_mj.physics.actuators.actuator_kernel`:
   limits, lags, rates; a ruddered vessel's allocation to n_P and the rudder angle);
4. the **record row**'s control columns (tau, Q(tau), k, f, sat of :mod:`usv_mj.record.run_record`)
   written from these values;
5. the **plant** holds f over the period: the Python loop calls ``plant.step``, the compiled loop
   and the environments' native step call the plant's kernel in the function
   :mod:`usv_mj.loop.generate` composes from :func:`control_step` and that kernel (``advance``).

:func:`control_step` is the njit function every loop calls (the Python loop through
:meth:`ControlStep.__call__`, the generated loops directly); :class:`ControlStep` holds its
arguments: the bounds, the two quantizers' state and parameters, the actuators' state and
parameters.

Indices: a vessel's state ``x`` = (x, y, psi, u, v, r) (:data:`usv_mj.core.layouts.STATE_FIELDS`);
the row is the record's (core columns first).
"""

from __future__ import annotations

import math

from numba import njit

from usv_mj.controllers.hysteresis_quantizer import quantizer_kernel
from usv_mj.core.errors import PluginContractError
from usv_mj.core.kernels import Kernel, kernel_blocker
from usv_mj.physics.actuators import actuator_kernel
from usv_mj.record.run_record import COL

C_TAU_U, C_TAU_R, C_Q_U, C_Q_R, C_K_U, C_K_R, C_F_U, C_F_R, C_S_U, C_S_R = (COL[c] for c in (
    "tau_u", "tau_r", "q_tau_u", "q_tau_r", "k_u", "k_r", "f_u", "f_r", "sat_u", "sat_r"))
#: the control columns are contiguous in a row: tau (2), Q(tau) (2), k (2), f (2), sat (2)
assert (C_TAU_R, C_Q_U, C_Q_R, C_K_U, C_K_R, C_F_U, C_F_R, C_S_U, C_S_R) == tuple(range(C_TAU_U + 1, C_TAU_U + 10))


@njit(cache=True)
def control_step(tau_u, tau_r, x, row, lo_u, hi_u, lo_r, hi_r, qs_u, delta_u, u_min_u, qs_r, delta_r, u_min_r,
                 quantize, unlimited, act_p, act_state, mmg):
    """One control period of one vessel's channels (module docstring): clip (``lo``/``hi`` [N, N m]),
    quantize (the quantizers' states ``qs_*`` = (k, output, switches), updated; ``quantize``
    False: Q(tau) = tau), the actuators (``unlimited``, their parameters ``act_p``, their state
    ``act_state``, updated, and ``mmg``: empty, or a ruddered vessel's allocation read at the state
    ``x``); writes tau, Q(tau), k, f and sat into ``row``'s control columns. Returns (f_u, f_r):
    what the plant holds over the period."""
    a_u = min(max(tau_u, lo_u), hi_u)
    a_r = min(max(tau_r, lo_r), hi_r)
    q_u, k_u = quantizer_kernel(a_u, qs_u, delta_u, u_min_u, quantize)
    q_r, k_r = quantizer_kernel(a_r, qs_r, delta_r, u_min_r, quantize)
    f_u, f_r, s_u, s_r = actuator_kernel(q_u, q_r, x, unlimited, act_p, act_state, mmg)
    row[C_TAU_U] = a_u
    row[C_TAU_R] = a_r
    row[C_Q_U] = q_u
    row[C_Q_R] = q_r
    row[C_K_U] = k_u
    row[C_K_R] = k_r
    row[C_F_U] = f_u
    row[C_F_R] = f_r
    row[C_S_U] = s_u
    row[C_S_R] = s_r
    return f_u, f_r


UNBOUNDED = (-math.inf, math.inf, -math.inf, math.inf)
_QUANTIZE = 10   # where ``quantize`` sits in ControlStep.args()
#: the arguments control_step writes (ControlStep.args() indices): the two quantizers' states and the actuators'
STEP_STATE = (4, 7, 13)


class ControlStep:
    """The input channels of one vessel between its controller and its plant (module docstring).

    ``quantizers``: the (surge, yaw) :class:`HysteresisQuantizer` pair (Eq. 3); ``actuators``: the
    vessel's :class:`usv_mj.physics.actuators.Actuators`; ``bounds``: (lo_u, hi_u, lo_r, hi_r) the
    command is clipped to (default: none). ``quantize`` (default: the quantizers' own switch) may
    be set to turn quantization off or on (the environments' ``quantize`` option).
    """

    def __init__(self, quantizers, actuators, bounds=UNBOUNDED):
        self.quantizers = tuple(quantizers)
        self.actuators = actuators
        self.bounds = tuple(float(b) for b in bounds)
        if len(self.bounds) != 4 or not (self.bounds[0] <= self.bounds[1] and self.bounds[2] <= self.bounds[3]):
            raise ValueError(f"ControlStep: bounds must be (lo_u <= hi_u, lo_r <= hi_r), got {bounds!r}")
        q_u, q_r = self.quantizers
        self.quantize = bool(q_u.enabled and q_r.enabled)
        self._args = None

    def reset(self) -> None:
        """Both quantizers at level 0, the actuators at rest (t = 0)."""
        for q in self.quantizers:
            q.reset()
        self.actuators.reset()

    @property
    def switches(self) -> tuple[int, int]:
        """How many times each quantizer's output changed since :meth:`reset` (surge, yaw)."""
        return tuple(q.switches for q in self.quantizers)

    def args(self) -> tuple:
        """:func:`control_step`'s arguments after (tau_u, tau_r, x, row): this object's own arrays
        (updated in place by every call) and parameters."""
        args = self._args
        if args is None or args[_QUANTIZE] != self.quantize:
            self._check_parts()
            q_u, q_r = self.quantizers
            act = self.actuators
            args = self._args = (*self.bounds, q_u._state, q_u._delta, q_u._u_min, q_r._state, q_r._delta,
                                 q_r._u_min, self.quantize, bool(act.unlimited), act.params, act.state, act.mmg)
            assert control_step.py_func.__code__.co_varnames[4 + _QUANTIZE] == "quantize"
            assert tuple(control_step.py_func.__code__.co_varnames[4 + i] for i in STEP_STATE) == (
                "qs_u", "qs_r", "act_state")
        return args

    def _check_parts(self) -> None:
        """The channel stage is this one compiled function in every loop: a quantizer or actuators
        object whose class overrides what the function computes (a subclass replacing ``step``, an
        instance attribute in place of a method) would be ignored without a word, so it is refused."""
        for role, part in (("surge quantizer", self.quantizers[0]), ("yaw quantizer", self.quantizers[1]),
                           ("actuators", self.actuators)):
            why = kernel_blocker(part)
            if why is not None:
                raise PluginContractError(
                    f"the {role}: {why}: the control step (clip, quantize by Eq. 3, actuators) is one compiled "
                    f"function in every loop (usv_mj/loop/step.py), which reads the part's state and parameters, "
                    f"never its methods; change the quantizer or the actuators through their options "
                    f"([quantizer], [actuators]), or the command before it in your controller")

    def kernel(self) -> Kernel:
        """(:func:`control_step`, :meth:`args`) for the generated loops (usv_mj.loop.generate)."""
        return Kernel(control_step, self.args(), state=STEP_STATE)

    def __call__(self, tau_u: float, tau_r: float, x, row) -> tuple[float, float]:
        """One control period (module docstring): writes ``row``'s control columns, returns (f_u, f_r)."""
        return control_step(float(tau_u), float(tau_r), x, row, *self.args())
