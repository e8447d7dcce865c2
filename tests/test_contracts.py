"""One contract per registry, held against every kind the registry lists (issue 33, What to build 5).

Each test is parametrised over its registry's own kinds (``REGISTRY.kinds()``), never over a list
of ours: a kind registered by a plug-in's entry point, or a built-in added tomorrow, is held to
the same contract the day it appears. The contracts:

- controllers: a short episode of the paper scenario with each controller on each vessel it can
  drive (the build refuses the others in one line); the compiled and the Python loop give the same
  record bit for bit; the declared criterion exists, is in the record and evaluates it; the
  ``diagnostic_fields`` are unique, not core columns and are the record's columns after the core;
  the record's metadata declares its channels (the command's and the applied ones, the vessel's own,
  each with its unit) and the actuators' columns are in those units (within the actuators' limits);
- trajectories: the reference is the 7-vector layout at t = 0 and after (its velocities and yaw
  rate the time derivatives of its pose, by central differences), its kernel (if any) gives
  ``evaluate`` bit for bit, and both loops give the same record;
- plants: an open-loop episode of each vessel, in its own channels (usv_mj.jobs.compare's signal),
  from the same state: both loops give the same record, and each plant agrees with the analytic
  plant (the model's own integration) within the compare tolerance (usv_mj.jobs.compare);
- disturbances: its options make a finite ``as_array()``, a scenario names it, and a run in it
  gives the same record in both loops on every plant, the plants within the closed-loop tolerance;
- vessels: its factory makes a :class:`usv_mj.vessels.Vessel` with a positive rigid body and
  dimensions, and the scenario that names it goes to a table and back (the runs above are each
  vessel's too);
- manoeuvres: each kind's options default to valid values, its ``[manoeuvre]`` table loads, the
  manoeuvre's scenario runs (to 2 s past its execute) alike in both loops and is measured;
- environment tasks (:data:`usv_mj.core.registry.TASKS`): the task's typed options are what
  ``envs.load`` takes (their defaults give the task's default episode, bit for bit), its tags are
  words, an episode keeps its observation spec and rewards in [0, 1]; it has a Gymnasium id and is
  a choice of ``usv-mj env``; a task of the user's own registered by the decorator is all of that;
- environments beside the tasks (:data:`usv_mj.envs.ENV_IDS`: ``usv_mj/Encounter-v0``; and the
  PettingZoo traffic environment, which has no id): not kinds of ``TASKS``, so not held to the task
  contract (a task is a dm_control environment of one hull on the MuJoCo plant, rewards in [0, 1],
  made by ``envs.load``; these are their own ``gymnasium.Env`` / ``ParallelEnv`` of a fleet on either
  plant, with penalties below 0). Their ids are registered with Gymnasium beside the tasks' and no
  task's id shadows them; their libraries' own API checks are tests/test_traffic_env.py's;
- commands: every command of the program answers ``--help`` (exit 0) naming each of its flags.

Runs are short (1-2 s of simulated time) and each scenario is run once per loop for every test
that reads it (the fixture :func:`runs`).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math

import numpy as np
import pytest

from usv_mj import load_scenario, simulate
from usv_mj.builder import channels_of, make_controller
from usv_mj.core.errors import ScenarioError
from usv_mj.core.registry import (CONTROLLERS, DISTURBANCES, MANOEUVRES, PLANTS, TASKS, TRAJECTORIES,
                                  VESSELS)
from usv_mj.record.run_record import CORE_COLUMNS

PRESET = "paper"
PAPER = load_scenario(preset=PRESET)
#: the paper scenario's own kinds: a run names only the sections it changes
DEFAULTS = {"controller": PAPER.controller.kind, "trajectory": PAPER.trajectory.kind, "plant": PAPER.plant.kind,
            "vessel": PAPER.vessel.kind}
#: the plant every other plant is held to: the analytic plant integrates the model itself (docs/model.md)
REFERENCE_PLANT = "analytic"
SHORT = 1.0        # s of a closed-loop episode
OPEN_LOOP = 2.0    # s of an open-loop episode
TIMING = ("wall_time_s", "realtime_factor", "loop", "loop_reason")


# --- the runs, each made once per loop for every test that reads it ---------------------------------


def scenario_of(duration: float = SHORT, extra: dict | None = None, **kinds):
    """The paper scenario with ``kinds`` (section -> kind) and the ``extra`` tables."""
    over = {"duration": duration}
    over.update({section: {"kind": kind} for section, kind in kinds.items() if DEFAULTS.get(section) != kind})
    for section, table in (extra or {}).items():
        over[section] = {**over.get(section, {}), **table}
    return load_scenario(preset=PRESET, overrides=over)


@pytest.fixture(scope="module")
def runs():
    """``runs(duration, extra, **kinds)``: (record of the default loop, record of the Python loop) of
    :func:`scenario_of`'s scenario, each run once in this module (the MuJoCo runs are shared by the
    controllers', the trajectories', the plants' and the disturbances' contracts)."""
    made = {}

    def get(duration: float = SHORT, extra: dict | None = None, **kinds):
        key = json.dumps([duration, extra, {**DEFAULTS, **kinds}], sort_keys=True)
        if key not in made:
            sc = scenario_of(duration, extra, **kinds)
            made[key] = (simulate(sc), simulate(sc, loop="python"))
        return made[key]

    return get


def assert_same_record(a, b):
    assert (a.n_rows, a.status, a.stop_reason) == (b.n_rows, b.status, b.stop_reason)
    assert a.column_names == b.column_names
    da, db = a.data[: a.n_rows], b.data[: b.n_rows]
    same = (da == db) | (np.isnan(da) & np.isnan(db))
    if not same.all():
        r, c = np.argwhere(~same)[0]
        raise AssertionError(f"the loops differ first at row {r}, column {a.column_names[c]}: {da[r, c]!r} != {db[r, c]!r}")
    assert [(e.t, e.kind, e.message, e.values) for e in a.events] == [(e.t, e.kind, e.message, e.values)
                                                                      for e in b.events]
    assert {k: v for k, v in a.metadata.items() if k not in TIMING} == \
        {k: v for k, v in b.metadata.items() if k not in TIMING}
    assert b.metadata["loop"] == "python"


def drivable(controller: str, vessel: str) -> str | None:
    """None when ``controller`` can drive ``vessel`` (the build takes the pair), else the one line
    the build refuses it with."""
    try:
        sc = scenario_of(controller=controller, vessel=vessel)
        from usv_mj.builder import commands_error

        return commands_error(sc, make_controller(sc), controller)
    except ScenarioError as exc:
        return str(exc)


PAIRS = [(c, v) for c in CONTROLLERS.kinds() for v in VESSELS.kinds()]


# --- controllers -----------------------------------------------------------------------------------


@pytest.mark.parametrize("controller,vessel", PAIRS)
def test_controller_contract(controller, vessel, runs):
    problem = drivable(controller, vessel)
    if problem is not None:   # the build refuses the pair in one line naming both
        with pytest.raises(ScenarioError, match=f"{controller}.*{vessel}|{vessel}.*{controller}"):
            simulate(scenario_of(controller=controller, vessel=vessel))
        assert "\n" not in problem
        return
    auto, python = runs(controller=controller, vessel=vessel)
    assert_same_record(auto, python)
    sc = scenario_of(controller=controller, vessel=vessel)
    ctrl = make_controller(sc)

    # the diagnostics: unique names after the core columns
    fields = tuple(ctrl.diagnostic_fields)
    assert len(set(fields)) == len(fields), f"{controller}: repeated diagnostic_fields"
    assert not set(fields) & set(CORE_COLUMNS), f"{controller}: diagnostic_fields name core columns"
    assert auto.column_names == tuple(CORE_COLUMNS) + fields
    assert list(auto.metadata["diagnostic_fields"]) == list(fields)

    # the declared criterion: in the record, read back from it, and it judges the record
    from usv_mj.record.criteria import criterion_from_dict, criterion_of, criterion_of_record

    criterion = criterion_of(ctrl)
    assert auto.metadata["criterion"] == criterion.to_dict()
    assert criterion_of_record(auto).to_dict() == criterion_from_dict(criterion.to_dict()).to_dict()
    verdict = criterion.evaluate(auto)
    assert verdict["kind"] == criterion.kind and verdict["passed"] in (True, False, None)
    assert isinstance(criterion.describe(), str) and criterion.describe()
    json.dumps(verdict, allow_nan=False)   # JSON-ready: no inf, no NaN

    # the channels the record declares: the command's (tau, Q(tau)) and the applied ones (f), the
    # latter the vessel's own, each named with its unit, read back as they were written
    from usv_mj.physics.channels import RunChannels

    declared = auto.metadata["channels"]
    assert declared == channels_of(sc, getattr(ctrl, "commands", "forces")).to_metadata()
    read = RunChannels.from_metadata(declared)
    assert [(c.symbol, c.unit) for c in read.applied] == [(c.symbol, c.unit) for c in sc.vessel.model.channels]
    assert all(c.symbol and c.unit for c in (*read.command, *read.applied))
    assert read.allocated == declared["allocated"]
    # the actuators' columns in the applied channels' units: within the actuators' limits, which are
    # given in the vessel's own channels (a force, or n_P and a rudder angle)
    u_lo, u_hi, r_lo, r_hi = sc.actuators.generalized_limits()
    tol = 1e-9
    assert np.all(np.isfinite(auto["f_u"])) and np.all(np.isfinite(auto["f_r"]))
    assert np.all((auto["f_u"] >= u_lo - tol) & (auto["f_u"] <= u_hi + tol))
    assert np.all((auto["f_r"] >= r_lo - tol) & (auto["f_r"] <= r_hi + tol))
    assert auto.status == "completed" and auto["t"][-1] == pytest.approx(SHORT)


# --- trajectories ----------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", TRAJECTORIES.kinds())
def test_trajectory_contract(kind, runs):
    from usv_mj.core.kernels import kernel_of
    from usv_mj.core.layouts import N_REF, REF_RDOT, REF_XDDOT, REF_YDDOT
    from usv_mj.loop.simulate import make_reference

    sc = scenario_of(duration=30.0, trajectory=kind)
    ref = make_reference(sc)
    h = 1e-6
    for t in (0.0, 0.37, 4.1, 17.9):
        # the 7 recorded entries and the accelerations a controller receives (REF_VECTOR_FIELDS, issue 37)
        r = np.array(ref.evaluate(t), dtype=float)
        assert r.shape == (N_REF,) and np.all(np.isfinite(r[:7]))
        assert -math.pi <= r[2] <= math.pi
        # the velocities and the yaw rate are the time derivatives of the pose, the accelerations those
        # of the velocities and the yaw rate (central differences, one-sided at t = 0)
        lo = max(t - h, 0.0)
        a, b = np.array(ref.evaluate(t + h)), np.array(ref.evaluate(lo))
        d = (a[:3] - b[:3]) / (t + h - lo)
        d[2] = math.remainder(a[2] - b[2], 2 * math.pi) / (t + h - lo)
        assert np.allclose(d, r[[3, 4, 5]], rtol=1e-5, atol=1e-5), (kind, t, d, r)
        acc = r[[REF_XDDOT, REF_YDDOT, REF_RDOT]]
        if kind in TRAJECTORIES.builtin_kinds() or not np.all(np.isnan(acc)):   # a plug-in may leave them NaN
            dd = (a[[3, 4, 5]] - b[[3, 4, 5]]) / (t + h - lo)
            assert np.allclose(dd, acc, rtol=1e-5, atol=1e-5), (kind, t, dd, acc)
    make_kernel = kernel_of(ref)
    if make_kernel is not None:   # the compiled loop's reference is evaluate() bit for bit
        kernel = make_kernel()
        for t in (0.0, 0.37, 4.1, 17.9, 29.0):
            assert np.array_equal(np.array(kernel.fn(t, *kernel.args)), np.array(ref.evaluate(t))), (kind, t)
    auto, python = runs(trajectory=kind)
    assert_same_record(auto, python)
    assert np.array_equal(auto["x_d"], [ref.evaluate(t)[0] for t in auto["t"]])


# --- plants ----------------------------------------------------------------------------------------


def open_loop_table(scenario, duration: float) -> dict:
    """An open-loop controller table of usv_mj.jobs.compare's input signal in the scenario's vessel's
    own channels (forces scaled to its hull, or n_P and a rudder angle), held step-wise."""
    from usv_mj.jobs.compare import vessel_inputs

    dt = scenario.control_period
    u = vessel_inputs(scenario, duration, dt)
    starts = np.concatenate([[0], np.flatnonzero(np.any(np.diff(u, axis=0) != 0.0, axis=1)) + 1])
    return {"kind": "open_loop", "times": [float(k * dt) for k in starts], "tau_u": [float(v) for v in u[starts, 0]],
            "tau_r": [float(v) for v in u[starts, 1]], "interpolation": "step"}


def open_loop_runs(runs, plant: str, vessel: str):
    table = open_loop_table(scenario_of(OPEN_LOOP, vessel=vessel), OPEN_LOOP)
    controller = table.pop("kind")
    return runs(OPEN_LOOP, {"controller": table, "quantizer": {"enabled": False}}, controller=controller,
                plant=plant, vessel=vessel)


@pytest.mark.parametrize("vessel", VESSELS.kinds())
@pytest.mark.parametrize("plant", PLANTS.kinds())
def test_plant_contract(plant, vessel, runs):
    from usv_mj.jobs.compare import OPEN_LOOP_TOLERANCE_M

    auto, python = open_loop_runs(runs, plant, vessel)
    assert_same_record(auto, python)
    assert auto.status == "completed" and auto.metadata["plant"] == plant
    reference, _ = open_loop_runs(runs, REFERENCE_PLANT, vessel)
    # the same inputs reached both plants, from the same state, and moved the hull
    for col in ("f_u", "f_r"):
        assert np.array_equal(auto[col], reference[col])
    assert np.array_equal(auto.data[0, 1:7], reference.data[0, 1:7])
    assert np.max(np.abs(reference["u"])) > 0.0 and np.max(np.abs(reference["r"])) > 0.0
    dp = np.hypot(auto["x"] - reference["x"], auto["y"] - reference["y"])
    assert np.max(dp) < OPEN_LOOP_TOLERANCE_M, f"{plant} is {np.max(dp):.3g} m from the {REFERENCE_PLANT} plant"
    assert np.max(np.abs(auto["psi"] - reference["psi"])) < OPEN_LOOP_TOLERANCE_M


# --- disturbances ----------------------------------------------------------------------------------


@pytest.mark.parametrize("plant", PLANTS.kinds())
@pytest.mark.parametrize("kind", DISTURBANCES.kinds())
def test_disturbance_contract(kind, plant, runs):
    from usv_mj.jobs.compare import CLOSED_LOOP_TOLERANCE_M

    from usv_mj.physics.disturbances import D_MAX_WORDS, check_disturbance

    entry = DISTURBANCES.get(kind)
    options = entry.options_class()
    packed = np.asarray(options.as_array(), dtype=float)
    assert packed.ndim == 1 and 0 < packed.size <= D_MAX_WORDS and np.all(np.isfinite(packed))
    check_disturbance(options, kind)   # a numba.njit kernel(dp, t), no force(t) of its own beside it
    sc = scenario_of(disturbance=kind)
    assert isinstance(sc.disturbance, entry.options_class)
    assert np.array_equal(np.asarray(sc.disturbance.as_array(), dtype=float), packed)   # the defaults
    auto, python = runs(disturbance=kind, plant=plant)
    assert_same_record(auto, python)
    reference, _ = runs(disturbance=kind, plant=REFERENCE_PLANT)
    dp = np.hypot(auto["x"] - reference["x"], auto["y"] - reference["y"])
    assert np.max(dp) < CLOSED_LOOP_TOLERANCE_M


# --- vessels ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", VESSELS.kinds())
def test_vessel_contract(kind):
    from usv_mj.vessels import Vessel

    entry = VESSELS.get(kind)
    options = entry.options_class() if entry.options_class is not None else None
    vessel = entry.make(options, None)
    assert isinstance(vessel, Vessel) and vessel.kind == kind
    m, x_g, i_z = vessel.rigid_body()
    assert m > 0 and i_z > 0 and math.isfinite(x_g)
    dims = vessel.dimensions
    assert dims.L > 0 and dims.B > 0 and dims.T > 0
    sc = scenario_of(vessel=kind)
    # the scenario that names it runs what the factory made: its hull and its rigid body
    assert sc.vessel.kind == kind and sc.vessel.model.rigid_body() == (m, x_g, i_z)
    assert sc.ship == vessel.ship and sc.vessel.model.dimensions == dims


# --- manoeuvres ------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", MANOEUVRES.kinds())
def test_manoeuvre_contract(kind):
    from usv_mj.jobs.manoeuvres import measure, vessel_length
    from usv_mj.jobs.manoeuvres.trial import execute_time, manoeuvre_scenario

    entry = MANOEUVRES.get(kind)
    cls = entry.options_class
    assert dataclasses.is_dataclass(cls) and entry.obj is cls
    defaults = cls()   # every option has a valid default
    sc = load_scenario(preset=PRESET, overrides={"manoeuvre": {"kind": kind}})
    assert sc.manoeuvre.kind == kind and sc.manoeuvre.options == defaults
    ms = manoeuvre_scenario(sc)
    assert ms.manoeuvre.kind == kind and ms.controller.kind in CONTROLLERS
    short = ms.with_overrides({"duration": execute_time(ms.manoeuvre) + OPEN_LOOP})   # to just past the execute
    auto, python = simulate(short), simulate(short, loop="python")
    assert_same_record(auto, python)
    result = measure(auto, ms.manoeuvre, vessel_length(ms))
    assert result["kind"] == kind and isinstance(result["measures"], dict)


# --- environment tasks -----------------------------------------------------------------------------


def _episode(env, steps: int):
    """(observations, rewards, discounts) of ``steps`` zero actions after a reset."""
    ts = env.reset()
    obs, rewards, discounts = [ts.observation], [], []
    for _ in range(steps):
        if ts.last():
            break
        ts = env.step(np.zeros(2))
        obs.append(ts.observation)
        rewards.append(ts.reward)
        discounts.append(ts.discount)
    return obs, rewards, discounts


@pytest.mark.parametrize("kind", TASKS.kinds())
def test_task_contract(kind):
    from usv_mj import envs

    entry = TASKS.get(kind)
    assert all(isinstance(t, str) and t.isidentifier() for t in entry.tags)
    assert isinstance(entry.scenario, dict)
    if entry.options_class is not None:
        assert dataclasses.is_dataclass(entry.options_class)
        defaults = dataclasses.asdict(entry.options_class())
    else:
        defaults = {}
    defaults["duration"] = 0.3
    plain, typed = envs.load(kind, seed=4, duration=0.3), envs.load(kind, seed=4, **defaults)
    try:
        spec = plain.observation_spec()
        first, rewards, discounts = _episode(plain, 1000)
        again, rewards2, _ = _episode(typed, 1000)
        # the options' defaults are the task's own: the same episode bit for bit
        assert len(first) == len(again) and rewards == rewards2
        for a, b in zip(first, again):
            assert all(np.array_equal(a[k], b[k]) for k in a)
        for ob in first:
            assert list(ob) == list(spec)
            for name, value in ob.items():
                assert value.shape == spec[name].shape and value.dtype == spec[name].dtype, name
        assert all(0.0 <= r <= 1.0 for r in rewards)
        assert discounts[-1] in (0.0, 1.0) and len(rewards) <= round(0.3 / plain.control_timestep())
        action = plain.action_spec()
        assert action.shape == (2,) and np.all(action.minimum <= 0.0) and np.all(action.maximum > 0.0)
    finally:
        plain.close()
        typed.close()
    # a Gymnasium id, and a choice of usv-mj env
    env_id = envs.gym_id(kind)
    assert envs.GYM_IDS[env_id] == kind
    gymnasium = pytest.importorskip("gymnasium")
    assert env_id in gymnasium.envs.registry
    from usv_mj.cli.main import build_parser

    assert build_parser().parse_args(["env", kind]).task == kind


def test_a_task_of_the_users_own_is_a_task_everywhere(capsys):
    """A task registered by the decorator, as the built-ins are: envs.load runs it with its options,
    gymnasium.make knows its id, usv-mj env rolls it out, the registry lists it with its tags."""
    from usv_mj import envs
    from usv_mj.cli.main import main
    from usv_mj.envs.suite import TrackOptions, track_environment

    @dataclasses.dataclass(frozen=True)
    class CircleOptions(TrackOptions):
        duration: float = 0.2          # [s]
        start_offset: tuple = (0.0, 0.0, 0.0)

    made = []

    @TASKS.register("test_circle_task", options=CircleOptions, tags=("circle",),
                    scenario={"trajectory": {"kind": "circle", "radius": 4.0}})
    def circle_task(options, scenario, *, random, environment_kwargs):
        made.append((options, scenario))
        return track_environment(options, scenario, random=random, environment_kwargs=environment_kwargs)

    gymnasium = pytest.importorskip("gymnasium")
    env_id = envs.gym_id("test_circle_task")
    try:
        assert env_id == "usv_mj/TestCircleTask-v0"
        assert "test_circle_task" in envs.ALL_TASKS and TASKS.tagged("circle") == ("test_circle_task",)
        env = envs.load("test_circle_task", seed=0, max_distance=20.0)
        try:
            options, scenario = made[-1]
            assert options == CircleOptions(max_distance=20.0)
            assert scenario.trajectory.kind == "circle" and scenario.trajectory.options.radius == 4.0
            ts = env.reset()
            # its start is the circle's pose at t = 0 (no offset), at rest
            assert np.array_equal(env.physics.state[:3], env.task.reference.evaluate(0.0)[:3])
            assert env.task.max_distance == 20.0 and not ts.last()
        finally:
            env.close()
        assert env_id in gymnasium.envs.registry
        g = gymnasium.make(env_id)
        try:
            obs, _ = g.reset(seed=0)
            assert g.observation_space.contains(obs)
        finally:
            g.close()
        assert main(["env", "test_circle_task", "--video", "none"]) == 0
        assert "test_circle_task / ppc: mean return" in capsys.readouterr().out
        with pytest.raises(ValueError, match="unknown options \\['goal_radius'\\]"):
            envs.load("test_circle_task", goal_radius=1.0)
    finally:
        TASKS.unregister("test_circle_task")
        gymnasium.envs.registry.pop(env_id, None)


def test_environments_beside_the_tasks_have_their_own_gymnasium_ids():
    """ENV_IDS (module docstring: no kinds of TASKS, their API checks in tests/test_traffic_env.py):
    each id is in Gymnasium's registry with its own entry point, which is a gymnasium.Env, and is
    no task's id (a task of that name would take the id from it)."""
    gymnasium = pytest.importorskip("gymnasium")
    from gymnasium.envs.registration import load_env_creator

    from usv_mj import envs

    assert envs.ENV_IDS
    for env_id, entry_point in envs.ENV_IDS.items():
        assert gymnasium.envs.registry[env_id].entry_point == entry_point
        assert issubclass(load_env_creator(entry_point), gymnasium.Env)
        assert env_id not in envs.GYM_IDS


# --- commands --------------------------------------------------------------------------------------


def _commands() -> dict:
    """name -> parser of every command of the program (its own table: the parser's subcommands)."""
    from usv_mj.cli.main import build_parser

    parser = build_parser()
    return dict(next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices)


@pytest.mark.parametrize("name", list(_commands()))
def test_command_contract(name, capsys):
    from usv_mj.cli.main import main

    try:
        code = main([name, "--help"])
    except SystemExit as exc:
        code = exc.code
    assert code in (0, None)
    out = capsys.readouterr().out
    assert out.startswith(f"usage: usv-mj {name}")
    flags = [o for a in _commands()[name]._actions if a.help != argparse.SUPPRESS   # a hidden alias is not named
             for o in a.option_strings if o not in ("-h", "--help")]
    for flag in flags:
        assert flag in out, f"usv-mj {name} --help does not name {flag}"
