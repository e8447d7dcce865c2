"""Issue 38, cause 8: attaching the water twice to one MjData and detaching the first handle took
the water away from both (the hull then reached MuJoCo's vacuum speed tau t / m11 = 7.05 m/s with
the second handle alive). An MjData holds one attachment, the latest: an earlier handle on it is
superseded, and its detach (or its garbage collection) leaves the later one's water in place."""

from __future__ import annotations

import gc
import math

import mujoco
import pytest

import usv_mj
from usv_mj.plants.mujoco_callback import MODELS_DIR

M11 = 141.85        # the paper's ship: rigid + added surge mass [kg] (the vacuum speed uses the rigid part alone)


def _speed_after(model, data, seconds):
    data.ctrl[:2] = (100.0, 0.0)
    while data.time < seconds - 1e-9:
        mujoco.mj_step(model, data)
    return math.hypot(data.qvel[0], data.qvel[1])


def _model():
    model = mujoco.MjModel.from_xml_path(f"{MODELS_DIR}/usv.xml")
    return model, mujoco.MjData(model)


def _with_water(seconds):
    model, data = _model()
    water = usv_mj.attach_hydrodynamics(model, data)
    v = _speed_after(model, data, seconds)
    water.detach()
    return v


def test_detaching_a_superseded_handle_keeps_the_later_water():
    expected = _with_water(2.0)                       # one attachment: the water's speed
    vacuum = 100.0 * 2.0 / M11                        # 1.41 m/s: no water at all
    assert expected < 0.8 * vacuum

    model, data = _model()
    first = usv_mj.attach_hydrodynamics(model, data)
    second = usv_mj.attach_hydrodynamics(model, data)
    assert second.attached and not first.attached
    first.detach()
    assert second.attached
    assert _speed_after(model, data, 2.0) == pytest.approx(expected, rel=1e-12)
    second.detach()
    assert not second.attached


def test_a_superseded_handle_does_not_point_the_callback_at_its_sea():
    model, data = _model()
    sea = usv_mj.load_scenario(overrides={"sea": {"current": {"speed": 0.2}}})
    old = usv_mj.attach_hydrodynamics(model, data, scenario=sea, horizon=5.0)
    new = usv_mj.attach_hydrodynamics(model, data, scenario=sea, horizon=5.0)
    try:
        with pytest.raises(ValueError, match="no longer in its MjData"):
            old.extend(10.0)
        new.extend(10.0)
        assert new.horizon >= 10.0
    finally:
        new.detach()


def test_a_superseded_handle_collected_leaves_the_water():
    expected = _with_water(1.0)
    model, data = _model()
    first = usv_mj.attach_hydrodynamics(model, data)
    second = usv_mj.attach_hydrodynamics(model, data)
    del first
    gc.collect()
    assert _speed_after(model, data, 1.0) == pytest.approx(expected, rel=1e-12)
    second.detach()
    data2 = mujoco.MjData(model)                      # detached: MuJoCo alone again, the vacuum speed
    assert _speed_after(model, data2, 1.0) == pytest.approx(100.0 * 1.0 / model.body_mass[1], rel=1e-9)
