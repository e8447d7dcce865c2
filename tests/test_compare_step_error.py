"""compare's closed-loop bound: each plant's own integration error, estimated by step halving.

Independent numbers: a high-accuracy integration (the same closed loop with the plant at 16
substeps, whose own RK4 error is 16^4 times smaller) gives each plant's true error; a hull 1 %
heavier (another model, not another step) must fall outside the bound.
"""

import pytest

from usv_mj import load_scenario
from usv_mj.jobs import compare
from usv_mj.loop.simulate import simulate


def _cs2(duration=20.0, **vessel):
    return load_scenario(preset="paper", overrides={"vessel": {"kind": "cybership2", **vessel}, "duration": duration})


def test_step_halving_estimates_the_true_integration_error():
    s = _cs2()
    run = simulate(s, plant_kind="analytic")
    est = compare.step_errors(s, {"analytic": run})
    ref = simulate(s.with_overrides({"plant": {"substeps": 16}}), plant_kind="analytic")
    true = compare.state_differences(compare._record_states(run), compare._record_states(ref))["max_position_m"]
    assert true > 1e-6                                   # the paper's gains on a 24 kg hull: a visible error
    assert est["analytic_m"] == pytest.approx(true, rel=0.1)
    assert est["bound_m"] == est["analytic_m"] and est["substeps"] == [1, 2]


def test_another_model_is_outside_the_bound_and_the_other_plant_inside():
    s = _cs2()
    runs = {k: simulate(s, plant_kind=k) for k in ("analytic", "mujoco")}
    err = compare.step_errors(s, runs)
    same = compare.state_differences(compare._record_states(runs["mujoco"]), compare._record_states(runs["analytic"]))
    assert compare.closed_loop_agrees({**same, "step_error": err})
    heavy = simulate(_cs2(m=23.8 * 1.01), plant_kind="analytic")
    other = compare.state_differences(compare._record_states(heavy), compare._record_states(runs["analytic"]))
    assert other["max_position_m"] > err["bound_m"]
    assert other["max_position_m"] > 1e-3 and not compare.closed_loop_agrees({**other, "step_error": err})
