"""Issue 38, cause 10: a subclass of a built-in controller that shrinks ``diagnostic_fields`` ran
its parent's kernel, whose law writes its own 13 diagnostics into a buffer the subclass sized 2:
a segfault or heap corruption (exit 139 / 134), or on MuJoCo a silent out-of-bounds write.

The mechanism, fixed at three places: (1) the built-in controllers size their diagnostics buffer
by what their law writes, never by what a subclass declares; (2) the kernel rule
(usv_mj.core.kernels.kernel_blocker) keeps the Python loop for a part whose class (or the object)
gives a data attribute of the kernel's class another value: the kernel was made for the kernel
class's; (3) both loops check the diag's length against the declared fields, before the run when
the kernel stands for ``__call__`` and declares ``n_diag``, and at every row before writing it."""

from __future__ import annotations

import dataclasses
import textwrap

import numpy as np
import pytest

import usv_mj
from usv_mj.builder import build_fleet
from usv_mj.controllers.los import DIAGNOSTIC_FIELDS, LOSController
from usv_mj.controllers.ppc import PPCController
from usv_mj.core.errors import PluginContractError
from usv_mj.core.kernels import kernel_blocker
from usv_mj.scenario.spec import load_scenario

N_LOS = len(DIAGNOSTIC_FIELDS)


def _scenario(**over):
    return load_scenario(preset="paper", overrides={"duration": 0.5, "baseline": {"enabled": False},
                                                    "controller": {"kind": "los"}, **over})


class ShortLOS(LOSController):
    diagnostic_fields = ("e_ct", "e_psi")


class SameLOS(LOSController):
    diagnostic_fields = tuple(DIAGNOSTIC_FIELDS)     # the same value: the kernel holds


class OwnFieldsLOS(LOSController):
    """Shrinks the fields and returns its own vector: a valid controller (the Python loop)."""
    diagnostic_fields = ("e_ct", "e_psi")

    def __call__(self, t, state, reference):
        tau_u, tau_r, diag = super().__call__(t, state, reference)
        self._mine = np.array([diag[0], diag[6]])
        return tau_u, tau_r, self._mine


def _controller(cls, sc):
    from usv_mj.controllers.los import LOSGains
    return cls.from_scenario(LOSGains(), sc)


def test_the_buffer_is_the_laws_whatever_a_subclass_declares():
    c = _controller(ShortLOS, _scenario())
    assert len(c._diag) == N_LOS and c.kernel().n_diag == N_LOS


def test_the_rule_keeps_the_python_loop_for_changed_data():
    sc = _scenario()
    assert kernel_blocker(_controller(ShortLOS, sc)) == (
        "LOSController subclass ShortLOS changes diagnostic_fields (the kernel was made for LOSController's; "
        "and has no kernel of its own)")
    assert kernel_blocker(_controller(SameLOS, sc)) is None
    named = type("Named", (LOSController,), {"name": "mine", "kind": "mine"})   # labels: the kernel holds
    assert kernel_blocker(_controller(named, sc)) is None
    c = _controller(LOSController, sc)
    c.diagnostic_fields = ("a",)                                                 # on the object
    assert kernel_blocker(c) == "LOSController object has its own diagnostic_fields (instance attribute)"
    ppc = type("ShortPPC", (PPCController,), {"diagnostic_fields": ("e1",)})
    assert "changes diagnostic_fields" in kernel_blocker(object.__new__(ppc))


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
@pytest.mark.parametrize("loop", ["auto", "python"])
def test_a_shrunk_subclass_is_refused_before_the_run(plant, loop):
    sc = _scenario()
    with pytest.raises(PluginContractError, match=rf"ShortLOS returns {N_LOS} diagnostics but declares 2 "
                                                  r"diagnostic_fields \('e_ct', 'e_psi'\)"):
        usv_mj.simulate(sc, plant_kind=plant, controller=_controller(ShortLOS, sc), loop=loop)


def test_a_subclass_returning_its_own_fields_runs():
    sc = _scenario()
    rec = usv_mj.simulate(sc, plant_kind="analytic", controller=_controller(OwnFieldsLOS, sc))
    full = usv_mj.simulate(sc, plant_kind="analytic", controller=_controller(LOSController, sc), loop="python")
    assert rec.metadata["loop"] == "python" and rec.status == "completed"
    assert np.array_equal(rec["e_ct"], full[DIAGNOSTIC_FIELDS[0]])
    assert np.array_equal(rec["e_psi"], full[DIAGNOSTIC_FIELDS[6]])


KERNEL_MODULE = textwrap.dedent('''
    import numpy as np
    from numba import njit


    @njit(cache=True)
    def short_kernel(t, x, ref, diag):
        return 0.0, 0.0, diag


    class Short:
        """Its own kernel, which returns 1 diagnostic where it declares 3 (and no n_diag)."""
        name = "short"
        diagnostic_fields = ("a", "b", "c")

        def __init__(self):
            self._diag = np.zeros(1)

        def reset(self):
            pass

        def kernel(self):
            from usv_mj.core.kernels import Kernel
            return Kernel(short_kernel, (self._diag,))

        def __call__(self, t, state, reference):
            return short_kernel(t, state, reference, self._diag)
''')


@pytest.mark.parametrize("loop", ["auto", "python"])
def test_a_kernel_that_returns_fewer_diagnostics_is_stopped_at_its_first_row(tmp_path, monkeypatch, loop):
    (tmp_path / "short_ctrl_kernel.py").write_text(KERNEL_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    import short_ctrl_kernel

    sc = _scenario()
    parts = usv_mj.build(sc, plant_kind="analytic", controller=short_ctrl_kernel.Short())
    with pytest.raises(PluginContractError, match=r"Short returns 1 diagnostics but declares 3"):
        usv_mj.simulate(parts, loop=loop)


def test_data_no_kernel_reads_keeps_the_kernel():
    from usv_mj.record.criteria import PathTolerance

    sc = _scenario()
    judged = type("Judged", (LOSController,), {"criterion": PathTolerance(settle_time_s=5.0, cross_track_m=1.0)})
    assert kernel_blocker(_controller(judged, sc)) is None
    c = _controller(LOSController, sc)
    c.criterion = PathTolerance(settle_time_s=1.0, cross_track_m=2.0)   # set on the object, as from_scenario may
    assert kernel_blocker(c) is None


# --- the loop over vessels (usv_mj.loop.fleet): the same contract, the vessel named ------------------------

FLEET = [{"name": "own", "steer": "keep", "initial": {"eta": [0.0, 0.0, 0.0], "nu": [0.5, 0.0, 0.0]}},
         {"name": "far", "steer": "keep", "initial": {"eta": [0.0, 300.0, 0.0], "nu": [0.5, 0.0, 0.0]}}]


class OneOfTwo:
    """A Python controller (no kernel) that declares 2 fields and returns 1: numpy would broadcast it."""
    name = "one_of_two"
    diagnostic_fields = ("a", "b")

    def reset(self):
        pass

    def __call__(self, t, state, reference):
        return 0.0, 0.0, np.array([7.0])


def _fleet_with(plant, make):
    """The two-vessel fleet with the vessel "far"'s controller replaced by ``make(its scenario)``."""
    sc = load_scenario(preset="paper", overrides={"duration": 0.5, "plant": {"kind": plant}, "vessels": FLEET})
    parts = build_fleet(sc)
    parts.vessels = tuple(dataclasses.replace(v, controller=make(v.scenario)) if v.name == "far" else v
                          for v in parts.vessels)
    return parts


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_a_shrunk_subclass_in_a_fleet_is_refused_before_the_run(plant):
    parts = _fleet_with(plant, lambda sc: _controller(ShortLOS, sc))
    with pytest.raises(PluginContractError, match=rf"^vessel 'far': controller .*ShortLOS returns {N_LOS} "
                                                  r"diagnostics but declares 2 diagnostic_fields"):
        usv_mj.simulate(parts)


def test_a_short_diag_in_a_fleet_is_stopped_at_its_first_row():
    parts = _fleet_with("analytic", lambda sc: OneOfTwo())
    with pytest.raises(PluginContractError, match=r"^vessel 'far': controller .*OneOfTwo returns 1 diagnostics "
                                                  r"but declares 2 diagnostic_fields \('a', 'b'\)"):
        usv_mj.simulate(parts)
