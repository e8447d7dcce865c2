"""A vessel's input channels are typed (usv_mj.physics.channels): what every consumer reads instead of
the vessel's kind (issue 33), and what keeps a ruddered vessel's commands out of the force quantizer
(issue 38, cause 6)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from usv_mj import load_scenario, simulate
from usv_mj.core.errors import ScenarioError
from usv_mj.physics.channels import (FORCES, PROPELLER, RUDDER_ANGLE, SURGE_FORCE, YAW_MOMENT, RunChannels,
                                     rudder_channels, run_channels)
from usv_mj.physics.mmg import N_MMG_PARAMS


def test_run_channels_follow_what_the_controller_commands():
    rudder = rudder_channels(np.ones(N_MMG_PARAMS))
    assert run_channels(FORCES, "forces") == RunChannels(FORCES, FORCES)
    allocated = run_channels(rudder, "forces")       # a force law on KVLCC2: allocated to n_P and delta
    assert allocated.allocated and allocated.command == FORCES and allocated.applied is rudder
    assert run_channels(rudder, "any") == RunChannels(rudder, rudder)
    assert run_channels(rudder, "rudder") == RunChannels(rudder, rudder)
    with pytest.raises(ValueError, match="commands the propeller's n_P and a rudder angle, but the vessel takes "
                                         r"surge force tau_u \[N\] and yaw moment tau_r \[N m\]"):
        run_channels(FORCES, "rudder", "the vessel")
    unallocated = rudder_channels(np.ones(N_MMG_PARAMS)).__class__(PROPELLER, RUDDER_ANGLE, quantized=False)
    with pytest.raises(ValueError, match="has no allocation from forces"):
        run_channels(unallocated, "forces")
    with pytest.raises(ValueError, match="commands must be one of 'forces', 'any', 'rudder', got 'bogus'"):
        run_channels(FORCES, "bogus")


@pytest.mark.parametrize("run", [RunChannels(), RunChannels(FORCES, rudder_channels(np.ones(N_MMG_PARAMS))),
                                 RunChannels(rudder_channels(np.zeros(N_MMG_PARAMS)),
                                             rudder_channels(np.zeros(N_MMG_PARAMS)))])
def test_a_record_s_channels_read_back_from_its_metadata(run):
    back = RunChannels.from_metadata(run.to_metadata())
    assert back.allocated == run.allocated
    assert [(c.symbol, c.unit, c.shown_unit, c.shown_factor) for c in back.command] == \
        [(c.symbol, c.unit, c.shown_unit, c.shown_factor) for c in run.command]
    assert [(c.symbol, c.unit) for c in back.applied] == [(c.symbol, c.unit) for c in run.applied]


def test_the_names_earlier_versions_wrote_still_read():
    assert RunChannels.from_metadata("forces") == RunChannels.from_metadata(None) == RunChannels()
    old_rudder = RunChannels.from_metadata("rudder")
    assert not old_rudder.allocated and (old_rudder.command.surge, old_rudder.command.yaw) == (PROPELLER, RUDDER_ANGLE)
    old_allocated = RunChannels.from_metadata("allocated")
    assert old_allocated.allocated and old_allocated.command == FORCES


def test_the_rudder_is_shown_in_degrees_and_limited_below_a_right_angle():
    assert RUDDER_ANGLE.shown_factor == pytest.approx(180 / math.pi) and RUDDER_ANGLE.display_unit == "deg"
    assert RUDDER_ANGLE.largest_limit == pytest.approx(math.pi / 2)
    assert (SURGE_FORCE.label(), YAW_MOMENT.label()) == ("surge force tau_u [N]", "yaw moment tau_r [N m]")
    with pytest.raises(ScenarioError, match=r"actuators.max_yaw_nm = 3 is the limit of the vessel 'kvlcc2''s "
                                            r"rudder angle \[rad\] and must be < 1.5708 rad"):
        load_scenario(preset="paper", overrides={"vessel": {"kind": "kvlcc2"}, "actuators": {"max_yaw_nm": 3}})


def _kvlcc2(controller: dict, duration=2.0):
    return load_scenario(preset="paper", overrides={
        "vessel": {"kind": "kvlcc2"}, "duration": duration, "control_period": 0.01, "plant": {"kind": "analytic"},
        "initial": {"nu": [1.179, 0.0, 0.0]}, "baseline": {"enabled": False}, "controller": controller})


def test_a_ruddered_vessel_s_own_channels_are_not_quantized_as_forces():
    """Issue 38, cause 6: KVLCC2's open-loop n_P and rudder angle went through the paper's force
    quantizer (n_P 21 % low, the rudder 13 % low). The command in the vessel's own channels is now
    transmitted as it is: Q(tau) = tau, row by row, with the scenario's quantizer on."""
    scenario = _kvlcc2({"kind": "open_loop", "tau_u": 11.85, "tau_r": math.radians(-10.0)})
    assert scenario.quantizer.enabled
    record = simulate(scenario)
    assert np.array_equal(record["q_tau_u"], record["tau_u"]) and np.array_equal(record["q_tau_r"], record["tau_r"])
    assert record["f_u"][0] == 11.85 and record.metadata["quantizer_switches"] == {"u": 1, "r": 1}


def test_a_force_command_on_a_ruddered_vessel_is_still_quantized_before_its_allocation():
    record = simulate(_kvlcc2({"kind": "pi"}))
    assert RunChannels.from_metadata(record.metadata["channels"]).allocated
    assert not np.array_equal(record["q_tau_u"], record["tau_u"])    # Eq. 3 on the force, then the allocation


def test_the_zigzag_s_force_defaults_are_refused_in_a_rudder_s_channels():
    """Issue 38, cause 6: --set controller.kind=zigzag on KVLCC2 took the defaults 53.73 N and 10 N m as
    53.73 rev/s and 10 rad (the rudder hard over the whole run, exit 0)."""
    with pytest.raises(ScenarioError, match=r"controller.tau_u: the 'zigzag' controller's default 53.73 is a force "
                                            r".* propeller revolutions n_P \[1/s\] there: give controller.tau_u in 1/s"):
        simulate(_kvlcc2({"kind": "zigzag"}))
    with pytest.raises(ScenarioError, match=r"controller.tau_r_amplitude: .* rudder angle delta \[rad\]"):
        simulate(_kvlcc2({"kind": "zigzag", "tau_u": 11.85}))
    record = simulate(_kvlcc2({"kind": "zigzag", "tau_u": 11.85, "tau_r_amplitude": math.radians(10.0)}))
    assert np.abs(record["tau_r"]).max() == pytest.approx(math.radians(10.0))
