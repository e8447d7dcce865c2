"""Issue 38, cause 21: the Python API checks its arguments at its door (usv_mj.core.arguments).

Each bad argument below failed deep inside (AttributeError, a numpy cast error, "'int' object is
not iterable"), and ``duration=True`` / ``duration='1'`` were taken for numbers. Now each raises a
TypeError (ArgumentTypeError) or a ValueError (ArgumentValueError) whose one line names the
function, the argument, what it takes and what it got; nothing runs first."""

from __future__ import annotations

import mujoco
import pytest

import usv_mj
from usv_mj import attach_hydrodynamics, build, envs, load_scenario, run_job, simulate
from usv_mj.core.errors import ArgumentTypeError, ArgumentValueError
from usv_mj.plants.mujoco_callback import MODELS_DIR


@pytest.fixture(scope="module")
def sc():
    return load_scenario(preset="paper", overrides={"duration": 0.05, "baseline": {"enabled": False}})


@pytest.fixture
def nothing_runs(monkeypatch):
    """The checks come first: no loop may start."""
    import usv_mj.loop.simulate as simulation

    def never(*a, **k):
        raise AssertionError("the loop ran before the arguments were checked")
    monkeypatch.setattr(simulation, "_run", never)


def test_load_scenario_overrides_keys_are_scenario_keys():
    with pytest.raises(ArgumentTypeError, match=r"^load_scenario: overrides key must be a scenario key \(a string, "
                                                r"e\.g\. 'duration' or 'controller'\), got int 1$"):
        load_scenario(overrides={1: 2})
    with pytest.raises(TypeError, match=r"^load_scenario: overrides\['controller'\] key must be a scenario key .*"
                                        r"got tuple"):
        load_scenario(overrides={"controller": {("k1",): 2.0}})


@pytest.mark.parametrize("kwargs, message", [
    ({"reference": 5}, r"simulate: reference must be a reference trajectory \(with evaluate; it has no evaluate\), "
                       r"got int 5"),
    ({"sinks": [5]}, r"simulate: sinks\[0\] must be a run sink \(an object with start, rows, finish\), got int 5"),
    ({"sinks": 5}, r"simulate: sinks must be a list of run sinks \(objects with start, rows, finish\), got int 5"),
    ({"hooks": "h"}, r"simulate: hooks must be a list of hooks, callables hook\(t, k, plant\), got str 'h'"),
    ({"hooks": [5]}, r"simulate: hooks\[0\] must be a hook, a callable hook\(t, k, plant\), got int 5"),
    ({"progress": 5}, r"simulate: progress must be a callable progress\(n_new_steps\) or None, got int 5"),
    ({"block": "a"}, r"simulate: block must be the number of rows between the sinks' flushes, an integer >= 1, "
                     r"got str 'a'"),
    ({"block": 2.5}, r"simulate: block must be .* an integer >= 1, got float 2.5"),
    ({"duration": True}, r"simulate: duration must be a number of seconds > 0 or None, got bool True"),
    ({"duration": "1"}, r"simulate: duration must be a number of seconds > 0 or None, got str '1'"),
])
def test_simulate_names_a_bad_argument(sc, nothing_runs, kwargs, message):
    with pytest.raises(ArgumentTypeError, match="^" + message + "$"):
        simulate(sc, **kwargs)


@pytest.mark.parametrize("kwargs, message", [
    ({"block": 0}, r"simulate: block must be the number of rows between the sinks' flushes, an integer >= 1, got 0"),
    ({"duration": -1.0}, r"simulate: duration must be a number of seconds > 0 or None, got -1.0"),
    ({"duration": float("nan")}, r"simulate: duration must be a number of seconds > 0 or None, got nan"),
])
def test_simulate_names_a_bad_value(sc, nothing_runs, kwargs, message):
    with pytest.raises(ArgumentValueError, match="^" + message + "$"):
        simulate(sc, **kwargs)


@pytest.mark.parametrize("duration, got", [("x", "str 'x'"), (True, "bool True"), ("1", "str '1'")])
def test_build_takes_a_number_of_seconds(sc, duration, got):
    with pytest.raises(ArgumentTypeError, match=rf"^build: duration must be a number of seconds > 0 or None "
                                                rf"\(the scenario's\), got {got}$"):
        build(sc, duration=duration)
    with pytest.raises(ArgumentTypeError, match=r"^build: reference must be a reference trajectory"):
        build(sc, reference=object())


def test_a_number_of_any_kind_still_counts(sc):
    import numpy as np

    rec = simulate(sc, duration=np.float64(0.01), block=np.int64(5), progress=None, sinks=(), hooks=[])
    assert len(rec) == 11                            # 0.01 s at the paper's 1 ms, t = 0 included


def test_run_job_names_its_arguments(sc, tmp_path):
    with pytest.raises(ArgumentTypeError, match=r"^run_job: scenario must be a Scenario \(usv_mj.load_scenario\), "
                                                r"got int 5$"):
        run_job(5, tmp_path / "o")
    with pytest.raises(ArgumentTypeError, match=r"^run_job: out_dir must be the output folder's path \(str or "
                                                r"pathlib.Path\), got int 5$"):
        run_job(sc, 5)
    assert not (tmp_path / "o").exists()


def test_attach_names_its_arguments():
    with pytest.raises(ArgumentTypeError, match=r"^attach_hydrodynamics: model must be a mujoco.MjModel .*, got "
                                                r"NoneType$"):
        attach_hydrodynamics(None, None)
    model = mujoco.MjModel.from_xml_path(f"{MODELS_DIR}/usv.xml")
    with pytest.raises(ArgumentTypeError, match=r"^attach_hydrodynamics: data must be the model's mujoco.MjData, "
                                                r"or None \(a new one\), got str 'data'$"):
        attach_hydrodynamics(model, "data")
    with pytest.raises(ArgumentTypeError, match=r"^attach_hydrodynamics: body must be the hull body's name \(str\), "
                                                r"got int 1$"):
        attach_hydrodynamics(model, None, body=1)


@pytest.mark.parametrize("kwargs, message", [
    ({"seed": "a"}, r"seed must be an integer >= 0, a numpy.random.RandomState or None, got str 'a'"),
    ({"seed": 1.5}, r"seed must be an integer >= 0, a numpy.random.RandomState or None, got float 1.5"),
    ({"task_kwargs": 5}, r"task_kwargs must be a dict of task options or None, got int 5"),
    ({"environment_kwargs": [1]}, r"environment_kwargs must be a dict \(time_limit, flat_observation, "
                                  r"legacy_step\) or None, got list"),
    ({"duration": "30"}, r"duration must be a number of seconds > 0, got str '30'"),
])
def test_envs_load_names_a_bad_argument(kwargs, message):
    with pytest.raises(ArgumentTypeError, match=r"^usv_mj.envs.load: " + message + "$"):
        envs.load("track", **kwargs)
    with pytest.raises(ArgumentValueError, match=r"^usv_mj.envs.load: seed must be an integer >= 0.*got -1$"):
        envs.load("track", seed=-1)
