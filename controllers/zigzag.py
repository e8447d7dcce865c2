"""The zig-zag manoeuvre (Kempf's test; IMO MSC.137(76) §5.3, ITTC 7.5-02-06-01): feedback on heading only.

The paper's hull has no rudder, so the "rudder angle" is a commanded yaw moment: at a constant surge
force ``tau_u`` [N] the law commands tau_r = +-``tau_r_amplitude`` [N m] and reverses it each time
the heading change from the start passes the switching angle, the 10/10 (or 20/20, ...) logic:

- the heading change is dpsi = psi - psi_0 [rad], unwrapped (psi_0: the heading at the first call);
- the first command turns to ``first_turn`` ("starboard": tau_r = -A, since positive r turns to
  port in the README's conventions; "port": +A);
- while the command turns to starboard (tau_r = -A) it switches to port (+A) at the first control
  step with dpsi <= -psi_switch; while it turns to port it switches to starboard at the first step
  with dpsi >= +psi_switch. The switch acts in the step where the threshold is passed (the command
  of that step is already the new one).

``[controller] kind = "zigzag"`` with the keys of :class:`ZigzagGains`; the run is not judged (a
manoeuvre); the record's ``heading_change`` and ``switches`` columns give the overshoots and periods.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np
from numba import njit

from usv_mj.record.criteria import NotJudged
from usv_mj.core.errors import ScenarioError
from usv_mj.core.registry import CONTROLLERS
from usv_mj.physics.ship import wrap_angle

TURNS = {"starboard": -1.0, "port": 1.0}


@dataclass(frozen=True)
class ZigzagGains:
    """The zig-zag's inputs (module docstring)."""

    # the surge and yaw channels' values (metadata "channel"): forces on a vessel that takes forces,
    # its own channels' units on one that does not (usv_mj.builder.check_channel_values)
    tau_u: float = field(default=53.73, metadata={"channel": "surge"})   # N: constant surge force (the drag at 0.6 m/s, d11(0.6) 0.6)
    tau_r_amplitude: float = field(default=10.0, metadata={"channel": "yaw"})   # N m: the "rudder": yaw moment +-A (> 0; 2 N m cannot break the hull's spiral)
    psi_switch_deg: float = 10.0     # deg: heading change at which the yaw moment reverses (> 0)
    first_turn: str = "starboard"    # "starboard" (tau_r = -A first) or "port"

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name == "first_turn":
                continue
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ScenarioError(f"controller.{f.name} must be a finite number, got {v!r}")
        for name in ("tau_r_amplitude", "psi_switch_deg"):
            if not getattr(self, name) > 0:
                raise ScenarioError(f"controller.{name} must be > 0, got {getattr(self, name)!r}")
        if not self.psi_switch_deg < 180:
            raise ScenarioError(f"controller.psi_switch_deg must be < 180, got {self.psi_switch_deg!r}")
        if self.first_turn not in TURNS:
            raise ScenarioError(f"controller.first_turn must be 'starboard' or 'port', got {self.first_turn!r}")


# the switching state: started (0/1), psi of the last call [rad], heading change [rad], turn (+-1), switches
S_STARTED, S_PSI_PREV, S_DPSI, S_TURN, S_SWITCHES = range(5)


@njit(cache=True)
def zigzag_kernel(t, x, ref, tau_u, amplitude, switch, st, diag):
    """The zig-zag's switching law (module docstring) on the state ``st``: ``__call__`` and the
    compiled loop's kernel (usv_mj.core.kernels). Returns (tau_u, tau_r, diag)."""
    psi = x[2]
    if st[S_STARTED] == 0.0:
        st[S_STARTED] = 1.0
    else:
        st[S_DPSI] += wrap_angle(psi - st[S_PSI_PREV])
    st[S_PSI_PREV] = psi
    dpsi, turn = st[S_DPSI], st[S_TURN]
    if (turn < 0 and dpsi <= -switch) or (turn > 0 and dpsi >= switch):
        st[S_TURN] = -turn
        st[S_SWITCHES] += 1.0
    diag[0], diag[1], diag[2] = st[S_DPSI], st[S_TURN], st[S_SWITCHES]
    return tau_u, st[S_TURN] * amplitude, diag


@CONTROLLERS.register("zigzag", gains=ZigzagGains)
class ZigzagController:
    """The zig-zag's switching logic on the heading (module docstring)."""

    commands = "any"   # its channels are numbers given as they are: a force, or a ruddered vessel's n_P and angle (usv_mj.builder.commands_error)

    name = "zigzag"
    diagnostic_fields = (
        "heading_change",  # dpsi = psi - psi_0, unwrapped [rad]
        "turn",            # sign of the commanded yaw moment: +1 port, -1 starboard
        "switches",        # reversals so far
    )
    diagnostic_units = {"heading_change": "rad", "turn": "-", "switches": "-"}
    criterion = NotJudged("manoeuvre")

    @classmethod
    def from_scenario(cls, gains: ZigzagGains, scenario) -> "ZigzagController":
        return cls(gains)

    def __init__(self, gains: ZigzagGains):
        self.gains = gains
        self._switch = math.radians(gains.psi_switch_deg)
        self._diag = np.zeros(len(ZigzagController.diagnostic_fields))   # what zigzag_kernel writes
        self._st = np.zeros(5)
        self.reset()

    def reset(self) -> None:
        self._st[:] = 0.0
        self._st[S_TURN] = TURNS[self.gains.first_turn]
        self._diag[:] = 0.0

    def kernel(self):
        """(zigzag_kernel, its gains and state) for the compiled loop."""
        from usv_mj.core.kernels import Kernel

        return Kernel(zigzag_kernel, (float(self.gains.tau_u), float(self.gains.tau_r_amplitude), self._switch,
                                      self._st, self._diag), n_diag=len(self._diag))

    def __call__(self, t, state, reference):
        return zigzag_kernel(float(t), np.asarray(state, float), reference, float(self.gains.tau_u),
                             float(self.gains.tau_r_amplitude), self._switch, self._st, self._diag)
