"""What every controller shares: the interface the simulation loop sees, and named array layouts.

A controller is any object with

- ``reset()``: back to its initial internal state;
- ``__call__(t, state, reference) -> (tau_u, tau_r, diagnostics)``: the continuous control law at
  time ``t`` [s] for the plant state ``state = (x, y, psi, u, v, r)`` and the reference vector
  (layout ``REF_*`` below: :data:`REF_VECTOR_FIELDS`, the record's 7 entries then the accelerations
  x_d_ddot, y_d_ddot, r_d_dot; index it, do not unpack it: docs/controllers.md); it returns the surge force tau_u [N], the yaw moment tau_r [N m] before
  quantization and a float64 diagnostics vector laid out as the controller's own
  ``diagnostic_fields``. The vector is the controller's own buffer, overwritten on the next call:
  copy it to keep it;
- ``diagnostic_fields``: the names of that vector, which become the run record's columns after the
  core every run has (time, state, reference, forces). A controller that tracks inside a funnel
  declares :data:`FUNNEL_FIELDS` among them, and the outputs then show funnel errors and
  violations; ``diagnostic_events`` (optional) maps a 0/1 field to the event kind its episodes
  are logged as (the PPC law's ``{"s2_clamped": "s2_clamp"}``);
- ``diagnostic_units`` (optional): a mapping from a diagnostic field to its unit, SI as the rest
  (``{"u_error": "m/s", "integral_psi": "rad s", "switches": "-"}``; "-" dimensionless). It goes
  into the run record's metadata, and figure 7 draws the fields one panel per unit with that unit
  on the axis; a field without a declared unit gets a panel of its own, marked "unit not declared";
- ``reaches_actuator_limits`` (optional, False by default): the law drives the actuators into their
  limits from the scenario's start, so ``usv-mj compare``'s saturated closed-loop case runs with it
  and requires that it saturated; a law that does not declare it is never failed for tracking within
  the limits (the case then runs with the paper's PPC law; docs/controllers.md);
- ``kernel()`` (optional): the law as a numba function for the compiled loop (usv_mj.core.kernels;
  docs/controllers.md, "The compiled path");
- ``from_scenario(gains, scenario)`` (a classmethod) when it is registered in
  :data:`usv_mj.core.registry.CONTROLLERS` with its typed gains dataclass.

The loop quantizes the outputs (the quantizer is the actuator channel, shared by every controller)
and holds them over the control period. Controllers import no plant, no MuJoCo and not the loop.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

# the shared layouts (usv_mj.core.layouts): the reference vector, the funnel block, the PPC law's diagnostics
from usv_mj.core.layouts import (DIAG_FIELDS, FUNNEL_FIELDS, N_REF, REF_FIELDS, REF_PSI, REF_R, REF_RDOT,  # noqa: F401
                                 REF_U, REF_VECTOR_FIELDS, REF_X, REF_XDDOT, REF_XDOT, REF_Y, REF_YDDOT, REF_YDOT,
                                 STATE_FIELDS)

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
