"""The reference's accelerations (issue 37, item 4): every built-in trajectory hands a controller
x_d_ddot, y_d_ddot and r_d_dot (usv_mj.core.layouts.REF_VECTOR_FIELDS) in closed form; here they are
checked against central second differences of the poses (x_d, y_d, psi_d) the same reference
returns, away from the instants where r_d jumps (a line meeting an arc, the paper's turn at 110 s,
where the acceleration is a Dirac the vector does not carry). The record keeps its 7 reference
columns: the loops write only those.

Second differences (f(t + h) - 2 f(t) + f(t - h)) / h^2 with h = 0.01 s: truncation h^2/12 |f''''|
(|f''''| <= u |r|^3 + ... well under 1e-3 m/s^4 for these paths, so under 1e-8) and rounding
4 eps |f| / h^2 (|f| <= 200 m: 2e-9); 1e-6 m/s^2 (rad/s^2) leaves room for the paper table's
Hermite interpolation (its second derivative differs from the unicycle's by far less).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from usv_mj.core.layouts import N_REF, REF_FIELDS, REF_RDOT, REF_VECTOR_FIELDS, REF_XDDOT, REF_YDDOT
from usv_mj.references.trajectories import (CircleReference, LineReference, PaperReference, Reference,
                                            WaypointReference)

H = 0.01
TOL = 1e-6


def _second_differences(ref, times, h=H):
    """(x_dd, y_dd, psi_dd) by central second differences of the poses at ``times``."""
    out = []
    for t in times:
        a, b, c = (ref.evaluate(float(t + k * h)).copy() for k in (-1, 0, 1))
        psi = np.unwrap([a[2], b[2], c[2]])
        out.append(((a[0] - 2 * b[0] + c[0]) / h**2, (a[1] - 2 * b[1] + c[1]) / h**2,
                    (psi[0] - 2 * psi[1] + psi[2]) / h**2))
    return np.array(out)


def _check(ref, times, h=H, tol=TOL):
    fd = _second_differences(ref, times, h)
    closed = np.array([ref.evaluate(float(t))[[REF_XDDOT, REF_YDDOT, REF_RDOT]] for t in times])
    np.testing.assert_allclose(closed, fd, atol=tol, rtol=0)
    return closed


def test_the_layout_grows_by_three_accelerations_and_the_record_keeps_seven():
    assert REF_VECTOR_FIELDS[:7] == REF_FIELDS and len(REF_FIELDS) == 7
    assert REF_VECTOR_FIELDS[7:] == ("x_d_ddot", "y_d_ddot", "r_d_dot")
    assert (REF_XDDOT, REF_YDDOT, REF_RDOT, N_REF) == (7, 8, 9, 10)
    assert LineReference().evaluate(1.0).shape == (N_REF,)


def test_line_and_circle():
    t = np.linspace(1.0, 60.0, 40)
    acc = _check(LineReference((1.0, 2.0), 30.0, 0.7), t)
    assert np.all(acc == 0.0)
    circle = CircleReference((3.0, 4.0), 7.0, 0.6, clockwise=True)
    acc = _check(circle, t)
    # the centripetal acceleration: |a| = u^2 / R toward the centre, r_d_dot = 0
    np.testing.assert_allclose(np.hypot(acc[:, 0], acc[:, 1]), 0.6**2 / 7.0, rtol=1e-12)
    assert np.all(acc[:, 2] == 0.0)
    for t0 in t[:5]:
        e = circle.evaluate(float(t0))
        inward = np.array([3.0 - e[0], 4.0 - e[1]])
        assert np.dot(inward, e[7:9]) > 0


def test_waypoints_inside_their_pieces():
    w = WaypointReference([[0, 0], [20, 0], [20, 15], [0, 30]], 0.6, 4.0)
    starts = np.append(w._starts, np.inf) / w.speed   # piece boundaries [s]
    t = np.linspace(0.5, 110.0, 400)
    away = np.array([np.min(np.abs(tt - starts)) > 2 * H for tt in t])
    acc = _check(w, t[away])
    on_arc = np.abs(np.array([w.evaluate(float(tt))[5] for tt in t[away]])) > 0
    assert on_arc.sum() > 20 and (~on_arc).sum() > 20
    np.testing.assert_allclose(np.hypot(acc[on_arc, 0], acc[on_arc, 1]), 0.6**2 / 4.0, rtol=1e-9)


def test_the_papers_reference_and_its_yaw_acceleration():
    p = PaperReference(duration=300.0)
    t = np.concatenate([np.linspace(5.0, 105.0, 20), np.linspace(115.0, 290.0, 60)])
    acc = _check(p, t)
    # r_d = -A sin(pi (t - 100)/500) from 110 s: r_d_dot = -A pi/500 cos(pi (t - 100)/500), by hand
    late = t > 110
    np.testing.assert_allclose(acc[late, 2], -0.006 * math.pi / 500 * np.cos(math.pi * (t[late] - 100) / 500),
                               rtol=1e-12)
    assert np.all(acc[~late] == 0.0)


def test_the_planned_harbour_reference():
    from usv_mj import load_scenario
    from usv_mj.obstacles.hooks import make_plan
    from usv_mj.support.example_files import resolve

    plan = make_plan(load_scenario(resolve("harbour_gap", "scenarios")))
    ref = plan.reference
    # inside the cells of the path table (ds = 0.02 m: kappa is linear per cell, so r_d_dot jumps at
    # the nodes), with a step h = 5 ms well inside one (a cell lasts 33 ms at 0.6 m/s); rounding
    # 4 eps |f| / h^2 <= 4e-16 * 60 / 2.5e-5 ~ 1e-9, the Hermite x, y's second derivative within a
    # cell off the unicycle's by O(ds^2 |kappa''|): 1e-5
    path, h = ref.path, 0.005
    t = np.linspace(1.0, 60.0, 2000)
    s = np.array([ref.profile.state(float(tt))[0] for tt in t])
    u = np.array([ref.profile.state(float(tt))[1] for tt in t])
    frac = (s / path.ds) % 1.0
    margin = 1.2 * h * u / path.ds
    keep = (frac > margin) & (frac < 1 - margin)
    assert keep.sum() > 100
    acc = _check(ref, t[keep], h, 1e-5)
    assert np.abs(acc[:, 2]).max() > 0   # it turns


def test_a_plugin_pose_without_accelerations_leaves_them_nan():
    class Old(Reference):
        def pose(self, t):
            return t, 0.0, 0.0, 0.0, 1.0

    e = Old().evaluate(2.0)
    assert e[:7].tolist() == [2.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0]
    assert np.isnan(e[7:]).all()


@pytest.mark.parametrize("loop", ["auto", "python"])
def test_the_record_keeps_seven_reference_columns_and_the_controller_sees_ten(loop):
    from usv_mj import load_scenario, simulate
    from usv_mj.record.run_record import CORE_COLUMNS

    seen = []

    class Spy:
        name, diagnostic_fields = "spy", ()

        def reset(self):
            pass

        def __call__(self, t, x, ref):
            seen.append(np.array(ref))
            return 0.0, 0.0, np.zeros(0)

    sc = load_scenario(overrides={"duration": 0.01, "baseline": {"enabled": False}, "plant": {"kind": "analytic"},
                                  "trajectory": {"kind": "circle"}})
    rec = simulate(sc, controller=Spy(), loop=loop)
    assert [c for c in rec.column_names if c.endswith(("_ddot", "_d_dot")) and c not in CORE_COLUMNS] == []
    assert all(r.shape == (N_REF,) for r in seen)
    np.testing.assert_array_equal(rec["x_d"], [r[0] for r in seen])
