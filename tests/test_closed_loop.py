"""The paper's closed loop end to end on the analytic plant (SPEC §5)."""

import json
import math

import numpy as np
import pytest

from usv_mj import load_scenario, simulate, summarize
from usv_mj.record.run_record import COLUMNS


@pytest.fixture(scope="module")
def paper_run():
    return simulate(load_scenario(preset="paper", overrides={"plant": {"kind": "analytic"}}))


def test_paper_preset_stays_in_the_funnels_for_300_s(paper_run):
    s = summarize(paper_run)
    assert s["status"] == "completed" and s["simulated_s"] == pytest.approx(300.0)
    assert s["funnel_violations"] == 0 and s["first_violation_s"] is None
    assert max(s["max_abs_error_after_20s"]["x"], s["max_abs_error_after_20s"]["y"]) < 0.5
    assert s["max_abs_error_after_20s"]["psi"] < 0.3
    z = np.stack([paper_run[f"z{i}"] for i in (1, 2, 3)])
    assert np.all(np.abs(z) < 1)
    assert np.all(np.isfinite(paper_run.data[: len(paper_run)]))


def test_plant_received_exactly_the_quantized_inputs(paper_run):
    """Every applied input is on the quantizer's ladder and within Lemma 1 of the law's output."""
    for ch, delta, umin in (("u", 0.3, 0.003), ("r", 0.15, 0.002)):
        tau, q, k = paper_run[f"tau_{ch}"], paper_run[f"q_tau_{ch}"], paper_run[f"k_{ch}"].astype(int)
        rho = (1 - delta) / (1 + delta)
        n = np.abs(k)
        i = (n + 1) // 2
        ladder = np.where(n == 0, 0.0, umin * rho ** (1.0 - i) * np.where(n % 2 == 1, 1.0, 1 + delta))
        assert np.allclose(np.abs(q), ladder, rtol=1e-12)
        big = np.abs(tau) > umin
        assert np.all(np.abs(q - tau)[big] <= delta * np.abs(tau)[big] * (1 + 1e-12))


def test_errors_match_the_pose_columns(paper_run):
    s = summarize(paper_run)
    k = int(round(10.0 / 1e-3))
    assert s["errors_at"]["10"]["x"] == paper_run["x"][k] - paper_run["x_d"][k]
    assert set(COLUMNS) >= {"q_tau_u", "z3", "w_r_norm"}


def test_paper_printed_stops_with_a_recorded_reason_and_no_nan():
    rec = simulate(load_scenario(preset="paper-printed", overrides={"plant": {"kind": "analytic"}, "duration": 30.0}))
    s = summarize(rec)
    assert rec.status in ("completed", "diverged")
    if rec.status == "diverged":
        assert rec.events[-1].kind == "divergence" and "limits" in rec.stop_reason
    text = json.dumps(s, allow_nan=False)  # raises on NaN or inf
    assert "NaN" not in text
    assert np.all(np.isfinite(rec.data[: len(rec), : COLUMNS.index("k_r")]))


def test_pi_baseline_runs_through_the_same_loop():
    rec = simulate(load_scenario(preset="paper", overrides={"plant": {"kind": "analytic"}, "duration": 60.0}),
                   controller_kind="pi")
    s = summarize(rec)
    assert rec.metadata["controller"] == "pi" and s["status"] == "completed"
    assert math.isfinite(s["errors_at"]["20"]["x"])


def test_a_controller_that_raises_is_recorded_and_reraised():
    class Broken:
        name = "broken"
        diagnostic_fields = ("n",)

        def reset(self):
            self.n = 0

        def __call__(self, t, state, ref):
            self.n += 1
            if self.n > 50:
                raise RuntimeError("boom")
            return 0.0, 0.0, np.array([float(self.n)])

    scenario = load_scenario(preset="paper", overrides={"plant": {"kind": "analytic"}, "duration": 1.0})

    class Sink:
        finished = None

        def start(self, record): pass

        def rows(self, record, lo, hi): pass

        def finish(self, record):
            Sink.finished = record

    with pytest.raises(RuntimeError, match="boom"):
        simulate(scenario, controller=Broken(), sinks=[Sink()])
    assert Sink.finished.status == "failed" and "boom" in Sink.finished.stop_reason
    assert len(Sink.finished) == 50
