"""The public API names what is wrong with an argument (issue 27, item 5): a TypeError or a
ValueError whose message names the function, the argument and what it takes, never an
AttributeError from deep inside."""

from __future__ import annotations

import io
import subprocess
import sys

import pytest

from usv_mj import load_scenario, run_job, simulate, summarize
from usv_mj.core.errors import ArgumentTypeError, ScenarioError
from usv_mj.outputs.log import read_run


@pytest.mark.parametrize("value, got", [(None, "NoneType"), ({"duration": 5.0}, "dict"), (42, "int 42")])
def test_simulate_names_its_scenario_argument(value, got):
    with pytest.raises(TypeError, match=rf"^simulate: scenario must be a Scenario .* got {got}$"):
        simulate(value)


def test_simulate_takes_a_preset_name():
    record = simulate("paper", duration=0.05)
    assert record.metadata["preset"] == "paper"
    assert len(record) == 51  # 0.05 s at the paper's 1 ms, t = 0 included
    with pytest.raises(ScenarioError, match="nope"):
        simulate("nope")


def test_simulate_refuses_a_plant_that_is_not_one():
    sc = load_scenario(preset="paper", overrides={"duration": 0.1})
    with pytest.raises(TypeError, match=r"^build: plant must be a plant with name, control_period, reset, step, "
                                        r"state, close \(it has no name, control_period, reset, step, state, "
                                        r"close\), got object$"):
        simulate(sc, plant=object())
    with pytest.raises(TypeError, match=r"^build: controller must be .* \(it has no name, reset, __call__\)"):
        simulate(sc, controller=object())


def test_load_scenario_names_its_arguments():
    with pytest.raises(TypeError, match=r"^load_scenario: overrides must be a nested dict of scenario keys, "
                                        r"e\.g\. \{'duration': 5\.0\}, got str 'duration=5'$"):
        load_scenario(overrides="duration=5")
    with pytest.raises(TypeError, match=r"^load_scenario: preset must be a preset name \(.*paper.*\), got int 3$"):
        load_scenario(preset=3)
    with pytest.raises(TypeError, match=r"^load_scenario: path must be .*, got list"):
        load_scenario(["a.toml"])
    assert load_scenario(overrides={"duration": 5.0}).duration == 5.0


def test_summarize_names_its_record_argument():
    with pytest.raises(TypeError, match=r"^summarize: record must be a RunRecord .*, got NoneType$"):
        summarize(None)


def test_read_run_names_its_path_argument():
    with pytest.raises(TypeError, match=r"^read_run: path must be .* \(bytes: io\.BytesIO\(data\)\), got bytes"):
        read_run(b"\x89MCAP0\r\n")
    with pytest.raises(ValueError, match="not an MCAP stream"):
        read_run(io.BytesIO(b"not a log"))


def test_argument_errors_are_of_the_package_family():
    with pytest.raises(ArgumentTypeError):
        summarize("record")


def test_ppc_policy_names_its_env_argument():
    from usv_mj import envs

    with pytest.raises(TypeError, match=r"^PPCPolicy: env must be a usv_mj environment .*, got object$"):
        envs.PPCPolicy(object())


@pytest.mark.parametrize("distance", [-40.0, 0.0, 29.0, 501.0, 1e6, float("nan")])
def test_harbour_goal_distance_is_bounded(distance):
    from usv_mj import envs

    with pytest.raises(ValueError, match=r"goal_distance must be in \[30, 500\] m .*got "):
        envs.load("harbor", goal_distance=distance)


def test_the_far_end_of_goal_distance_loads_and_puts_the_goal_there():
    from usv_mj import envs

    env = envs.load("harbor", seed=0, goal_distance=500.0)
    try:
        env.reset()
        assert env.task.layout.goal[0] == 500.0
    finally:
        env.close()


def test_gymnasium_make_refuses_human_rendering_in_one_line():
    import gymnasium
    import usv_mj.envs  # noqa: F401 (registers the ids)

    with pytest.raises(ValueError, match=r"^USVGymEnv: render_mode must be None or 'rgb_array', got 'human'$"):
        gymnasium.make("usv_mj/Track-v0", render_mode="human")
    env = gymnasium.make("usv_mj/Track-v0", render_mode="rgb_array")
    try:
        assert env.metadata["render_modes"] == ["rgb_array"]
    finally:
        env.close()


def test_run_job_refuses_an_unknown_render_option_before_the_simulation(tmp_path, monkeypatch):
    import usv_mj.jobs.run

    def never(*args, **kwargs):
        raise AssertionError("the simulation ran")

    monkeypatch.setattr(usv_mj.jobs.run, "_simulate", never)
    sc = load_scenario(preset="paper", overrides={"duration": 1.0})
    with pytest.raises(ScenarioError, match=r"^render_options: unknown option\(s\) 'size'; known: width, height"):
        run_job(sc, tmp_path / "run", render_options={"size": (640, 360)})
    assert not (tmp_path / "run").exists()


def test_render_with_an_unknown_camera_says_so_before_any_progress_bar(tmp_path):
    sc = load_scenario(preset="paper", overrides={"duration": 0.5, "baseline": {"enabled": False}})
    run_job(sc, tmp_path / "run", video=False, progress=False, step_check=False)
    done = subprocess.run([sys.executable, "-m", "usv_mj.cli.main", "render", str(tmp_path / "run"), "--camera", "nope",
                           "--out", str(tmp_path / "v.mp4")], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.strip() == ("usv-mj render: error: camera 'nope' is not in the render model; choose one of "
                                   "top, overview, chart, chase")
