"""Issue 38, cause 5: a controller (or anyone) that edits the state it is handed moved the analytic
plant's hull (its ``state`` was the array the next step starts from) but not MuJoCo's, and in both
the record's row showed the edited value. Both plants hand out copies, and the loop gives the
controller its own copy, so an edit changes nothing: the run is the run of a controller that does
not edit, bit for bit."""

import dataclasses

import numpy as np
import pytest

import usv_mj
from usv_mj.scenario.spec import load_scenario


class Still:
    name = "still"
    diagnostic_fields = ()

    def reset(self):
        pass

    def __call__(self, t, state, ref):
        return 0.0, 0.0, np.zeros(0)


class Editing(Still):
    name = "editing"

    def __call__(self, t, state, ref):
        state[0] += 3.0          # 3 m east, every step
        state[3] = 0.0
        return super().__call__(t, state, ref)


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_editing_the_state_changes_nothing(plant):
    sc = load_scenario(preset="paper")
    still = usv_mj.simulate(sc, plant_kind=plant, controller=Still(), duration=0.5, loop="python")
    edited = usv_mj.simulate(sc, plant_kind=plant, controller=Editing(), duration=0.5, loop="python")
    assert edited["x"][0] == sc.initial.eta[0]          # the first row is the start, not the edit
    for col in ("x", "y", "psi", "u", "v", "r"):
        assert np.array_equal(edited[col], still[col]), col


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_the_plant_hands_out_a_copy(plant):
    parts = usv_mj.build(load_scenario(preset="paper"), plant_kind=plant, duration=0.1)
    try:
        p = parts.plant
        p.reset((1.0, 2.0, 0.3), (0.5, 0.0, 0.0))
        p.step(0.0, 0.0)
        before = p.state
        p.state[:] = 99.0
        assert np.array_equal(p.state, before)
        p.step(0.0, 0.0)
        assert abs(p.state[0] - before[0]) < 0.01            # moved by u dt = 0.5 mm, not to 99 m
    finally:
        parts.close()


# --- the loop over vessels (usv_mj.loop.fleet) and the fleet plants (usv_mj.plants.fleet) ------------------

FLEET = [{"name": "own", "steer": "keep", "initial": {"eta": [0.0, 0.0, 0.0], "nu": [0.5, 0.0, 0.0]}},
         {"name": "far", "steer": "keep", "initial": {"eta": [0.0, 300.0, 0.0], "nu": [0.5, 0.0, 0.0]}}]


def _fleet_run(plant, controller_class):
    """The two-vessel fleet with every vessel's controller replaced by ``controller_class()``."""
    from usv_mj.builder import build_fleet

    sc = load_scenario(preset="paper", overrides={"duration": 0.5, "plant": {"kind": plant}, "vessels": FLEET})
    parts = build_fleet(sc)
    parts.vessels = tuple(dataclasses.replace(v, controller=controller_class()) for v in parts.vessels)
    return usv_mj.simulate(parts)


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_editing_the_state_changes_nothing_in_a_fleet(plant):
    still, edited = _fleet_run(plant, Still), _fleet_run(plant, Editing)
    assert edited.status == still.status == "completed"
    for v in FLEET:
        assert edited[v["name"]]["x"][0] == v["initial"]["eta"][0]     # the start, not the edit
        for col in ("x", "y", "psi", "u", "v", "r"):
            assert np.array_equal(edited[v["name"]][col], still[v["name"]][col]), (v["name"], col)


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_the_fleet_plant_hands_out_a_copy(plant):
    from usv_mj.builder import build_fleet

    parts = build_fleet(load_scenario(preset="paper", overrides={"duration": 0.1, "plant": {"kind": plant},
                                                                 "vessels": FLEET}))
    try:
        p = parts.plant
        for i, v in enumerate(FLEET):
            p.reset_vessel(i, v["initial"]["eta"], v["initial"]["nu"])
        p.step_vessels(np.zeros((2, 2)))
        before = p.states
        p.states[:] = 99.0
        assert np.array_equal(p.states, before)
        p.step_vessels(np.zeros((2, 2)))
        assert np.all(np.abs(p.states[:, 0] - before[:, 0]) < 0.01)   # moved by u dt, not to 99 m
    finally:
        parts.close()
