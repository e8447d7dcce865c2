"""The hysteresis quantizer against SPEC §2's worked example, Lemma 1 and the printed case table."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from usv_mj.controllers.hysteresis_quantizer import HysteresisQuantizer, QuantizerParams


def run(q, inputs):
    return [q.step(x) for x in inputs]


def test_worked_example_of_spec_section_2():
    q = HysteresisQuantizer(QuantizerParams(delta=0.3, u_min=0.003))
    rising = [0.002, 0.0029, 0.0031, 0.004, 0.0043, 0.005, 0.0056, 0.006]
    falling = [0.005, 0.0043, 0.0042, 0.0035, 0.003, 0.0025, 0.0023]
    reversal = [0, -0.0035, -0.0045]
    u2 = 0.003 * 1.3 / 0.7  # u_2 = u_min / rho
    assert run(q, rising) == pytest.approx([0, 0, 0.003, 0.003, 0.0039, 0.0039, u2, u2], abs=1e-15)
    assert round(u2, 7) == 0.0055714
    assert run(q, falling) == pytest.approx([u2, u2, 0.0039, 0.0039, 0.003, 0.003, 0], abs=1e-15)
    assert run(q, reversal) == pytest.approx([0, -0.003, -0.0039], abs=1e-15)


def test_levels_follow_the_ladder():
    p = QuantizerParams(delta=0.3, u_min=0.003)
    rho = 0.7 / 1.3
    for i in range(1, 6):
        assert p.level(2 * i - 1) == pytest.approx(0.003 * rho ** (1 - i), rel=1e-14)
        assert p.level(2 * i) == pytest.approx(0.003 * rho ** (1 - i) * 1.3, rel=1e-14)


@settings(max_examples=300, deadline=None)
@given(delta=st.floats(0.01, 0.9), u_min=st.floats(1e-4, 10.0),
       inputs=st.lists(st.floats(-1e4, 1e4, allow_nan=False), min_size=1, max_size=60))
def test_lemma_1_holds_for_any_input_sequence(delta, u_min, inputs):
    """Lemma 1 (Eq. 5). At |tau| = u_min exactly the output is 0, as in the printed table (the dead
    zone is |tau| <= u_min), so the relative bound applies above u_min and the absolute one at or below."""
    q = HysteresisQuantizer(QuantizerParams(delta=delta, u_min=u_min))
    for tau in inputs:
        out = q.step(tau)
        err = abs(out - tau)
        if abs(tau) > u_min:
            assert err <= delta * abs(tau) * (1 + 1e-12), (tau, out)
        else:
            assert err <= u_min * (1 + 1e-12), (tau, out)
        assert out == 0 or math.copysign(1, out) == math.copysign(1, tau)


def printed_case_table(delta, u_min, inputs):
    """Eq. 3 read literally: the branch is chosen by the sign of tau_dot (finite difference)."""
    rho = (1 - delta) / (1 + delta)
    out, prev_tau, prev_q = [], None, 0.0
    for tau in inputs:
        direction = 0 if prev_tau is None else np.sign(tau - prev_tau)
        q = prev_q
        a = abs(tau)
        if direction != 0:
            if (u_min / (1 + delta) < a <= u_min and direction > 0) or (a < u_min / (1 + delta) and direction < 0):
                q = 0.0
            for i in range(1, 80):
                u_i = u_min * rho ** (1 - i)
                if (u_i / (1 - delta) < a <= u_i * (1 + delta) / (1 - delta) and direction > 0) or (
                        u_i < a <= u_i / (1 - delta) and direction < 0):
                    q = u_i * (1 + delta) * np.sign(tau)
                    break
                if (u_i < a <= u_i / (1 - delta) and direction > 0) or (u_i / (1 + delta) < a < u_i and direction < 0):
                    q = u_i * np.sign(tau)
                    break
        out.append(q)
        prev_tau, prev_q = tau, q
    return out


def test_state_machine_chatters_far_less_than_the_printed_table():
    rng = np.random.default_rng(3)
    t = np.arange(0, 20, 1e-3)
    tau = 50 + 20 * np.sin(0.3 * t) + rng.normal(0, 0.5, t.size)  # slow, noisy surge command [N]
    q = HysteresisQuantizer(QuantizerParams(delta=0.3, u_min=0.003))
    machine = np.array(run(q, tau))
    table = np.array(printed_case_table(0.3, 0.003, tau))
    n_machine = int(np.count_nonzero(np.diff(machine)))
    n_table = int(np.count_nonzero(np.diff(table)))
    print(f"output changes over {t.size} samples: state machine {n_machine}, printed table {n_table}")
    assert n_machine * 20 < n_table
    assert q.switches == n_machine + (machine[0] != 0)


def test_disabled_quantizer_is_identity_and_bad_parameters_are_named():
    q = HysteresisQuantizer(QuantizerParams(0.3, 0.003), enabled=False)
    assert q.step(1.2345) == 1.2345
    with pytest.raises(ValueError, match="delta"):
        QuantizerParams(delta=1.0, u_min=0.1)
    with pytest.raises(ValueError, match="u_min"):
        QuantizerParams(delta=0.3, u_min=0.0)
