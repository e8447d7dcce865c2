"""The compiled loop (usv_mj.loop.compiled) against the Python loop: the same record bit for bit.

The reference is the Python loop of usv_mj.loop.simulate (``simulate(..., loop="python")``), run on
the same scenario: every column of every row, the events, the status and stop reason, the sinks'
blocks and the progress counts must be equal, on the composition matrix of tests/test_build.py
(sea x obstacles x plant x controller), with saturated actuators (``paper-limited``), on every
reference kind with a kernel, and on every way a run stops (force limit, state limit, Ctrl-C).
Runs are short and blocks small (many block boundaries per run).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from usv_mj import build, load_scenario, simulate
from usv_mj.controllers.ppc import PPCController

from test_build import OBSTACLES, _scenario

BLOCK = 397  # not a divisor of the row count: the last block is partial
ROOT = Path(__file__).resolve().parents[1]

TIMING = ("wall_time_s", "realtime_factor", "loop", "loop_reason")


class RecordingSink:
    def __init__(self):
        self.calls = []

    def start(self, record):
        self.calls.append(("start", record.n_rows))

    def rows(self, record, lo, hi):
        self.calls.append(("rows", lo, hi, record.data[lo:hi].copy()))

    def finish(self, record):
        self.calls.append(("finish", record.n_rows, record.status))


def _run(scenario, loop, **kw):
    sink, progress = RecordingSink(), []
    rec = simulate(scenario, loop=loop, sinks=[sink], block=BLOCK, progress=progress.append, **kw)
    return rec, sink.calls, progress


def assert_same_run(a, b):
    (ra, sa, pa), (rb, sb, pb) = a, b
    assert ra.n_rows == rb.n_rows and ra.status == rb.status and ra.stop_reason == rb.stop_reason
    assert ra.column_names == rb.column_names
    da, db = ra.data[: ra.n_rows], rb.data[: rb.n_rows]
    same = (da == db) | (np.isnan(da) & np.isnan(db))
    if not same.all():
        r, c = np.argwhere(~same)[0]
        raise AssertionError(f"records differ first at row {r}, column {ra.column_names[c]}: {da[r, c]!r} != {db[r, c]!r}")
    assert [(e.t, e.kind, e.message, e.values) for e in ra.events] == [(e.t, e.kind, e.message, e.values)
                                                                        for e in rb.events]
    ma = {k: v for k, v in ra.metadata.items() if k not in TIMING}
    mb = {k: v for k, v in rb.metadata.items() if k not in TIMING}
    assert ma == mb
    assert len(sa) == len(sb) and pa == pb
    for ca, cb in zip(sa, sb):
        assert ca[:3] == cb[:3]
        if ca[0] == "rows":
            assert np.array_equal(ca[3], cb[3], equal_nan=True)


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
@pytest.mark.parametrize("obstacles", list(OBSTACLES))
@pytest.mark.parametrize("controller", ["ppc", "pi"])
@pytest.mark.parametrize("sea", [False, True], ids=["calm", "sea"])
def test_both_loops_give_the_same_record_on_the_composition_matrix(plant, obstacles, controller, sea):
    sc = _scenario(obstacles, sea, duration=1.5)
    compiled = _run(sc, "auto", plant_kind=plant, controller_kind=controller)
    python = _run(sc, "python", plant_kind=plant, controller_kind=controller)
    meta = compiled[0].metadata
    if obstacles != "moving":     # standing obstacles: the hook's kernel (usv_mj.obstacles.native_step)
        assert meta["loop"] == "compiled", meta.get("loop_reason")
    else:  # moving obstacles and the guidance that re-times around them are Python
        assert meta["loop"] == "python" and "hook" in meta["loop_reason"]
    assert python[0].metadata["loop"] == "python"
    assert_same_run(compiled, python)
    if obstacles != "none":
        assert_same_obstacle_log(compiled[0], python[0])


def assert_same_obstacle_log(ra, rb):
    la, lb = ra.statics.obstacle_log, rb.statics.obstacle_log
    assert la.n_rows == lb.n_rows == ra.n_rows
    for name in ("clearance", "normal_force", "obstacle_xy"):
        assert np.array_equal(getattr(la, name).view(np.uint64), getattr(lb, name).view(np.uint64)), name
    assert la.summary() == lb.summary()


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_a_near_miss_and_a_contact_go_through_python_and_back_alike(plant):
    """ramming_pier: the hull comes within the margin (near_miss), touches the pier (MuJoCo's
    contact, the analytic plant's collision) and leaves: those rows' hook work is done by Python
    inside the compiled loop's blocks; records, events, sinks' blocks and the obstacle log equal
    the Python loop's."""
    sc = load_scenario(ROOT / "examples" / "scenarios" / "ramming_pier.toml", overrides={"duration": 31.0})
    compiled = _run(sc, "auto", plant_kind=plant)
    python = _run(sc, "python", plant_kind=plant)
    assert compiled[0].metadata["loop"] == "compiled"
    kinds = [e.kind for e in python[0].events]
    assert "near_miss" in kinds and ("contact" in kinds or "collision" in kinds), kinds
    assert_same_run(compiled, python)
    assert_same_obstacle_log(compiled[0], python[0])


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
@pytest.mark.parametrize("controller", ["ppc", "pi"])
def test_saturated_actuators_give_the_same_record(plant, controller):
    sc = load_scenario(preset="paper-limited", overrides={"duration": 3.0, "initial": {"eta": [3.0, -4.0, 1.0]}})
    compiled = _run(sc, "auto", plant_kind=plant, controller_kind=controller)
    assert compiled[0].metadata["loop"] == "compiled"
    assert np.any(compiled[0]["sat_u"] > 0) or np.any(compiled[0]["sat_r"] > 0)  # the limits did act
    assert_same_run(compiled, _run(sc, "python", plant_kind=plant, controller_kind=controller))


@pytest.mark.parametrize("trajectory", [
    {"kind": "line", "heading_deg": 30.0},
    {"kind": "circle", "radius": 6.0, "clockwise": True},
    {"kind": "waypoints", "points": [[0.0, 0.0], [1.5, 0.0], [1.5, 1.5], [4.0, 1.0]], "turn_radius": 0.4},
])
def test_every_reference_kernel_gives_the_same_record(trajectory):
    sc = load_scenario(preset="paper", overrides={"duration": 4.0, "trajectory": trajectory,
                                                  "plant": {"kind": "analytic"}})
    compiled = _run(sc, "auto")
    assert compiled[0].metadata["loop"] == "compiled"
    assert_same_run(compiled, _run(sc, "python"))


def test_no_quantizer_gives_the_same_record():
    sc = load_scenario(preset="paper", overrides={"duration": 2.0, "quantizer": {"enabled": False}})
    compiled = _run(sc, "auto", plant_kind="analytic")
    assert compiled[0].metadata["loop"] == "compiled"
    assert_same_run(compiled, _run(sc, "python", plant_kind="analytic"))


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
@pytest.mark.parametrize("limits", [{"max_force": 30.0}, {"max_distance": 2.0}, {"max_yaw_rate": 0.2}])
def test_a_run_stops_at_the_same_row_with_the_same_event(plant, limits):
    sc = load_scenario(preset="paper", overrides={"duration": 3.0, "limits": limits,
                                                  "initial": {"eta": [1.0, -1.0, 0.5]}})
    compiled = _run(sc, "auto", plant_kind=plant)
    assert compiled[0].metadata["loop"] == "compiled" and compiled[0].status == "diverged"
    assert compiled[0].n_rows < 3001
    assert_same_run(compiled, _run(sc, "python", plant_kind=plant))


class InterruptingSink(RecordingSink):
    """Raises KeyboardInterrupt once, in the second block's flush (where a signal lands between blocks)."""

    raised = False

    def rows(self, record, lo, hi):
        super().rows(record, lo, hi)
        if hi >= 2 * BLOCK and not self.raised:
            self.raised = True
            raise KeyboardInterrupt("SIGTERM")


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_ctrl_c_between_blocks_stops_both_loops_alike(plant):
    sc = load_scenario(preset="paper", overrides={"duration": 3.0})
    runs = []
    for loop in ("auto", "python"):
        sink = InterruptingSink()
        rec = simulate(sc, loop=loop, sinks=[sink], block=BLOCK, plant_kind=plant)
        runs.append((rec, sink.calls, []))
    assert runs[0][0].status == "interrupted" and "SIGTERM" in runs[0][0].stop_reason
    assert_same_run(*runs)


def test_a_part_without_a_kernel_runs_the_python_loop_and_says_why():
    sc = load_scenario(preset="paper", overrides={"duration": 0.5, "plant": {"kind": "analytic"}})

    class Tweaked(PPCController):  # overrides the law but not the kernel: must not run the kernel
        def __call__(self, t, state, reference):
            tau_u, tau_r, diag = super().__call__(t, state, reference)
            return 0.5 * tau_u, tau_r, diag

    parts = build(sc)
    base = parts.controller
    tweaked = Tweaked(base.gains, base.nominal, *_funnels(sc), sc.quantizer.delta_u, sc.quantizer.delta_r,
                      sc.control_period)
    rec = simulate(sc, controller=tweaked)
    parts.close()
    assert rec.metadata["loop"] == "python"
    assert rec.metadata["loop_reason"] == ("the controller: PPCController subclass Tweaked overrides __call__ "
                                           "(and has no kernel of its own)")
    assert simulate(sc, hooks=(lambda t, k, plant: None,)).metadata["loop"] == "python"
    assert simulate(sc, loop="python").metadata["loop_reason"] == "asked for (loop='python')"
    with pytest.raises(ValueError, match="loop must be"):
        simulate(sc, loop="fast")


def _funnels(sc):
    from usv_mj.controllers.performance_funnel import funnels_of

    return funnels_of(sc)


def test_the_parts_are_left_where_the_python_loop_leaves_them():
    sc = load_scenario(preset="paper", overrides={"duration": 1.2, "plant": {"kind": "analytic"}})
    ends = []
    for loop in ("auto", "python"):
        parts = build(sc)
        rec = simulate(parts, loop=loop, block=BLOCK)
        qu, qr = parts.quantizers
        ends.append((parts.plant.state.tolist(), parts.plant.time, qu.k, qu.switches, qr.k, qr.output,
                     parts.controller.weights.copy().tolist(), parts.controller.s2, rec.metadata["quantizer_switches"]))
    assert ends[0] == ends[1]
    assert math.isclose(ends[0][1], 1.2)
