"""usv-mj compare (issue 3): structure of compare.json, the tolerances, and RK4's order."""

from __future__ import annotations

import argparse
import json
import os

import numpy as np
import pytest

from usv_mj.cli import compare as compare_command
from usv_mj.jobs import compare
from usv_mj.scenario.spec import ScenarioError, load_scenario

KEYS = ("max_position_m", "max_heading_rad", "max_velocity", "convergence")


@pytest.fixture(scope="module")
def short_compare(tmp_path_factory):
    out = tmp_path_factory.mktemp("compare")
    scenario = load_scenario(preset="paper", overrides={"duration": 8.0})
    result = compare.compare_plants(scenario, str(out), progress=False)
    return out, result


def test_compare_json_structure_and_files(short_compare):
    out, result = short_compare
    with open(out / "compare.json") as fh:
        written = json.load(fh)
    assert written["open_loop"]["max_position_m"] == result["open_loop"]["max_position_m"]
    for part in ("open_loop", "closed_loop"):
        for key in KEYS:
            assert key in written[part], (part, key)
        rows = written[part]["convergence"]
        assert len(rows) >= 3
        assert all(set(row) >= {"dt", "max_position_m"} for row in rows)
        assert [row["dt"] for row in rows] == sorted((row["dt"] for row in rows), reverse=True)
    for name in ("open_loop.png", "closed_loop.png", "convergence.png"):
        assert (out / name).stat().st_size > 10_000


def test_compare_tolerances_and_funnels(short_compare):
    _, result = short_compare
    assert result["open_loop"]["max_position_m"] < 1e-6
    assert result["open_loop"]["max_heading_rad"] < 1e-6
    assert result["closed_loop"]["max_position_m"] < 1e-3
    assert result["closed_loop"]["inside_funnels"] == {"analytic": True, "mujoco": True}
    assert result["closed_loop"]["status"] == {"analytic": "completed", "mujoco": "completed"}
    assert result["passed"] is True


def test_compare_in_a_sea_checks_the_hull_adrift_and_the_driven_hull(tmp_path, capsys):
    """In a sea compare adds the unpowered hull (calm tolerance) beside the sensitivity check."""
    scenario = load_scenario(preset="paper", overrides={"duration": 4.0, "sea": {"preset": "moderate",
                                                        "current": {"speed": 0.3}, "wind": {"speed": 5.0}}})
    result = compare.compare_plants(scenario, str(tmp_path), progress=False)
    ad = result["open_loop"]["adrift"]
    assert set(result["checks"]) >= {"open_loop_adrift_position_below_1e-6_m",
                                     "open_loop_difference_within_sea_sensitivity"}
    assert ad["max_position_m"] < 1e-9 and ad["path_length_m"] > 0.1
    assert result["checks"]["open_loop_adrift_position_below_1e-6_m"] is True
    assert result["scenario"]["sea"]["waves"]["hs"] == 0.2


def test_convergence_at_rk4_order(short_compare):
    _, result = short_compare
    ol = result["open_loop"]
    # the plants' difference shrinks at RK4's order: a factor ~16 per halving of dt
    rows = ol["convergence"]
    for coarse, fine in zip(rows, rows[1:]):
        assert 8.0 < coarse["max_position_m"] / fine["max_position_m"] < 32.0
    assert 3.5 < ol["convergence_order"]["plants_difference"] < 4.5
    # with one-signed inputs (smooth damping along the solution) each plant converges to the
    # fine-step reference at order 4 too
    smooth = ol["convergence_one_signed_inputs"]
    assert smooth["zero_crossings_of_reference"] == {"u": 0, "v": 0, "r": 0}
    assert 3.5 < smooth["order"]["mujoco_vs_reference"] < 4.5
    assert 3.5 < smooth["order"]["analytic_vs_reference"] < 4.5
    cl = result["closed_loop"]
    assert cl["convergence"][-1]["max_position_m"] < cl["convergence"][0]["max_position_m"] / 8
    assert 3.0 < cl["convergence_order"]["plants_difference"] < 5.0


def test_open_loop_inputs_are_the_same_signal_at_every_dt():
    coarse = compare.open_loop_inputs(20.0, 0.04)
    fine = compare.open_loop_inputs(20.0, 0.001)
    assert coarse.shape == (500, 2) and fine.shape == (20000, 2)
    np.testing.assert_array_equal(fine[::40], coarse)
    np.testing.assert_array_equal(fine[39::40], coarse)  # constant within each coarse step
    assert np.ptp(fine[:, 0]) > 100 and np.ptp(fine[:, 1]) > 5  # rich: large, two-signed swings
    assert (fine[:, 0] < 0).any() and (fine[:, 1] < 0).any()
    with pytest.raises(ValueError, match="0.003"):
        compare.open_loop_inputs(1.0, 0.003)


def test_estimated_order_closed_form():
    dts = np.array([0.04, 0.02, 0.01])
    assert compare.estimated_order(dts, 3.0 * dts**4) == pytest.approx(4.0, abs=1e-12)
    assert compare.estimated_order(dts, [1.0, 0.0, 1.0]) is None


def test_an_order_at_round_off_is_not_measurable():
    """Errors at round-off give no order (before: "order -0.00", the slope of noise): the slope is fitted
    over the errors above the round-off floor only, and with fewer than two there it is not measurable."""
    eps = np.finfo(float).eps
    # the floor: ROUNDOFF_ULPS ulps of the largest |x| or |y| (here 40 m), 1 m at least
    states = np.array([[3.0, -40.0, 9.0, 0.0, 0.0, 0.0], [1.0, 2.0, -99.0, 0.0, 0.0, 0.0]])
    floor = compare.roundoff_floor(states, states[:1] * 0.5)
    assert floor == compare.ROUNDOFF_ULPS * eps * 40.0
    assert compare.roundoff_floor(np.zeros((3, 6))) == compare.ROUNDOFF_ULPS * eps
    dts = np.array([0.004, 0.002, 0.001])
    # both plants at round-off: 3.2e-15 and 3.3e-15 m (the slope would be -0.04, printed "-0.04")
    at_roundoff = [3.2e-15, 3.3e-15, 3.1e-15]
    assert compare.estimated_order(dts, at_roundoff, floor) is None
    text = compare.order_text({"plants_difference": None, "roundoff_m": floor}, "plants_difference")
    assert text == f"not measurable (the errors are at round-off, below {floor:.0e} m)"
    # truncation down to the floor: the order of the errors above it (2e-9 * (dt / 4 ms)^4: 2e-9, 1.25e-10,
    # then 7.8e-12 m, taken; a fourth at 1e-15 m would not be)
    trunc = 2e-9 * (dts / 0.004) ** 4
    assert compare.estimated_order(dts, trunc, floor) == pytest.approx(4.0, abs=1e-12)
    assert compare.estimated_order(np.append(dts, 0.0005), np.append(trunc, 1e-15), floor) == pytest.approx(4.0, abs=1e-12)
    assert compare.order_text({"plants_difference": 3.987, "roundoff_m": floor}, "plants_difference") == "3.99"
    assert compare.order_text({"plants_difference": None}, "plants_difference") == "n/a"


def test_run_command_writes_and_rejects_bad_input(tmp_path, capsys):
    parser = argparse.ArgumentParser()
    compare_command.add_arguments(parser)
    args = parser.parse_args(["--duration", "2", "--out", str(tmp_path / "c"), "-q"])
    assert compare_command.run(args) == 0
    assert os.path.isfile(tmp_path / "c" / "compare.json")
    out = capsys.readouterr().out
    assert "closed loop" in out
    md = (tmp_path / "c" / "compare.md").read_text()      # what --help promises (issue 27)
    assert "closed loop (2 s): max position" in md and "![Closed loop](closed_loop.png)" in md
    assert next(line for line in out.splitlines() if line.startswith("closed loop (")) in md
    with pytest.raises(ScenarioError, match="duration"):
        compare_command.run(parser.parse_args(["--duration", "-1"]))
    with pytest.raises(ScenarioError):
        compare_command.run(parser.parse_args(["--preset", "no-such-preset"]))
    with pytest.raises(ScenarioError, match="disturbance"):
        compare_command.run(parser.parse_args(["--set", "disturbance.scale=-1"]))


def test_compare_saturated_closed_loop_case(short_compare):
    """issue 18: the closed loop again with saturating actuators (paper-limited's twin thrusters):
    the plants agree at the closed-loop tolerance while the limits act, with identical saturation."""
    _, result = short_compare
    sat = result["closed_loop_saturated"]
    assert result["checks"]["saturated_closed_loop_position_below_1e-3_m_or_step_error"]
    assert result["checks"]["saturated_closed_loop_saturates"]
    assert sat["max_position_m"] < compare.CLOSED_LOOP_TOLERANCE_M
    assert sat["saturated_steps_differ"] == 0 and "twin" in sat["actuators"]
    assert all(f["u"] > 0 for f in sat["saturated_fraction"].values())
    assert result["open_loop"]["saturated_fraction"] == {"u": 0.0, "r": 0.0}  # paper: unlimited
