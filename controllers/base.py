"""What every controller shares: the interface the simulation loop sees, and named array layouts.

A controller is any object with

- ``reset()``: back to its initial internal state;
- ``__call__(t, state, reference) -> (tau_u, tau_r, diagnostics)``: the continuous control law at
  time ``t`` [s] for the plant state ``state = (x, y, psi, u, v, r)`` and the reference vector
  (layout ``REF_*`` below); it returns the surge force tau_u [N], the yaw moment tau_r [N m] before
  quantization and a float64 diagnostics vector laid out as the controller's own
  ``diagnostic_fields``. The vector is the controller's own buffer, overwritten on the next call:
  copy it to keep it;
- ``diagnostic_fields``: the names of that vector, which become the run record's columns after the
  core every run has (time, state, reference, forces). A controller that tracks inside a funnel
  declares :data:`FUNNEL_FIELDS` among them, and the outputs then show funnel errors and
  violations; ``diagnostic_events`` (optional) maps a 0/1 field to the event kind its episodes
  are logged as (the PPC law's ``{"s2_clamped": "s2_clamp"}``);
- ``from_scenario(gains, scenario)`` (a classmethod) when it is registered in
  :data:`usv_mj.core.registry.CONTROLLERS` with its typed gains dataclass.

The loop quantizes the outputs (the quantizer is the actuator channel, shared by every controller)
and holds them over the control period. Controllers import no plant, no MuJoCo and not the loop.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

# Reference vector: pose, its time derivative and the reference surge speed.
REF_FIELDS = ("x_d", "y_d", "psi_d", "x_d_dot", "y_d_dot", "r_d", "u_d")
REF_X, REF_Y, REF_PSI, REF_XDOT, REF_YDOT, REF_R, REF_U = range(len(REF_FIELDS))

# The funnel block (Eqs. 9, 14): a controller that tracks in a funnel declares these among its diagnostics.
FUNNEL_FIELDS = ("e1", "e2", "e3", "rho1", "rho2", "rho3", "z1", "z2", "z3")

# The PPC law's diagnostics vector: tracking errors in the funnel (Eqs. 8-15), then the adaptive
# states (Eqs. 19, 29, 37). Its first 13 entries (TRACKING_FIELDS) are what tracking_errors fills.
DIAG_FIELDS = (
    "e1", "e2", "e3",            # Eq. 14: x_bar - x_bar_d [m], y_bar - y_bar_d [m], wrap(psi - psi_a) [rad]
    "rho1", "rho2", "rho3",      # Eq. 9 bounds
    "z1", "z2", "z3",            # e_i / rho_i
    "e1s", "e2s", "e3s",         # Eq. 10 transformed errors e_i*
    "psi_a",                     # Eq. 15 [rad]
    "u_e", "v_e", "r_e",         # Eq. 19 velocity errors
    "alpha_u", "alpha_v", "alpha_r",  # Eq. 17 virtual controls
    "w_u_norm", "w_v_norm", "w_r_norm",  # |W_u|, |W_v|, |W_r|
    "s2",                        # tanh(gamma_2)
    "s2_clamped",                # 1 when s2 hit its clamp this step
)
DIAG = {name: i for i, name in enumerate(DIAG_FIELDS)}
TRACKING_FIELDS = DIAG_FIELDS[:13]
N_DIAG = len(DIAG_FIELDS)

# Integer indices of the diagnostics vector, for numba kernels (which cannot read the dict).
D_E1 = 0
D_E2 = 1
D_E3 = 2
D_RHO1 = 3
D_RHO2 = 4
D_RHO3 = 5
D_Z1 = 6
D_Z2 = 7
D_Z3 = 8
D_E1S = 9
D_E2S = 10
D_E3S = 11
D_PSI_A = 12
D_U_E = 13
D_V_E = 14
D_R_E = 15
D_ALPHA_U = 16
D_ALPHA_V = 17
D_ALPHA_R = 18
D_W_U_NORM = 19
D_W_V_NORM = 20
D_W_R_NORM = 21
D_S2 = 22
D_S2_CLAMPED = 23
assert [D_E1, D_S2_CLAMPED] == [DIAG['e1'], DIAG['s2_clamped']] and N_DIAG == 24


class Controller(Protocol):
    """The controller interface (see the module docstring)."""

    name: str
    diagnostic_fields: tuple[str, ...]
    # optional: "forces" (the default: tau_u [N], tau_r [N m]), "any" or "rudder" (usv_mj.builder.commands_error)
    commands: str

    def reset(self) -> None: ...

    def __call__(self, t: float, state: np.ndarray, reference: np.ndarray) -> tuple[float, float, np.ndarray]: ...
