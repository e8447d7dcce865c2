"""The baselines' gains derived from the vessel (issue 37, item 1; docs/gains.md, usv_mj.physics.design):

- on the paper hull every derived default is the paper's number to the last bit (so its records stay
  as they were: scripts/record_digest.py);
- on another hull the closed loops have the reference's damping ratios at the bandwidth scaled by
  sqrt(L_ref / L): checked on the characteristic polynomials built here from the hull's nominal
  M and D and the derived gains, against the reference's read off the paper hull;
- a gain the scenario sets is kept, only the others are derived, and the scenario says which;
- the nominal model (the vessel times model_mismatch) is what they are placed on.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from usv_mj import load_scenario

PAPER_PI = dict(k_at=0.2, kp_u=200.0, ki_u=40.0, kp_r=200.0, ki_r=20.0, kd_r=72.0, a1=1.0, integral_limit_u=5.0,
                integral_limit_r=5.0)
PAPER_LOS = dict(lookahead=3.0, ref_omega=3.0, kp_psi=1000.0, ki_psi=800.0, kd_psi=250.0, u_at=0.3, l_at=2.0,
                 kp_u=200.0, ki_u=40.0)


def test_the_paper_hull_keeps_the_papers_gains_to_the_bit():
    sc = load_scenario(overrides={"controller": {"kind": "los"}})
    for name, value in PAPER_LOS.items():
        assert getattr(sc.controller.gains, name) == value, name            # ==, not approx
    for name, value in PAPER_PI.items():
        assert getattr(sc.baseline.gains, name) == value, name
    assert set(sc.baseline.derived) == set(PAPER_PI) and set(sc.controller.derived) == set(PAPER_LOS)
    # the PPC law's gains are the preset's (the paper's design parameters): nothing derived
    assert load_scenario().controller.derived == ()


def _design(sc):
    ship, L = sc.nominal_ship, sc.vessel.model.dimensions.L
    U = 0.6 * math.sqrt(L / 1.98)                  # the paper's Froude number on this hull
    d_u = ship.d11[0] + 2 * ship.d11[1] * U + 3 * ship.d11[2] * U * U   # d(d11(u) u)/du at U
    return ship, L, U, d_u, ship.d33[0]


@pytest.mark.parametrize("vessel", ["otter", "cybership2", "clarke83", "examples/vessels/wamv.toml"])
def test_the_loops_are_placed_at_the_scaled_bandwidth_with_the_references_damping(vessel):
    paper = load_scenario()
    d_u_ref = _design(paper)[3]
    ref = paper.ship
    # the reference's loops, read off the paper gains: surge m s^2 + (d_u + kp) s + ki, heading
    # m33 s^3 + (d_r + kd) s^2 + kp s + ki
    w_u = math.sqrt(40.0 / ref.m11)
    z_u = (d_u_ref + 200.0) / (2 * w_u * ref.m11)
    w_r = math.sqrt(200.0 / ref.m33)
    z_r = (ref.d33[0] + 72.0) / (2 * w_r * ref.m33)
    sc = load_scenario(overrides={"vessel": {"kind": vessel}})
    ship, L, U, d_u, d_r = _design(sc)
    s = math.sqrt(1.98 / L)
    g = sc.baseline.gains
    assert math.sqrt(g.ki_u / ship.m11) == pytest.approx(w_u * s, rel=1e-12)
    assert (d_u + g.kp_u) / (2 * w_u * s * ship.m11) == pytest.approx(z_u, rel=1e-12) or g.kp_u == 0.0
    assert math.sqrt(g.kp_r / ship.m33) == pytest.approx(w_r * s, rel=1e-12)
    assert (d_r + g.kd_r) / (2 * w_r * s * ship.m33) == pytest.approx(z_r, rel=1e-12) or g.kd_r == 0.0
    assert g.ki_r / g.kp_r == pytest.approx(0.1 * s, rel=1e-12)          # the integral zero moves with omega
    assert g.k_at == pytest.approx(0.2 * s, rel=1e-12) and g.a1 == pytest.approx((L / 1.98) ** 2, rel=1e-12)
    # the anti-windup authority ki x limit keeps its share of the drag the surge loop holds at U
    drag = (ship.d11[0] + ship.d11[1] * U + ship.d11[2] * U * U) * U
    drag_ref = (ref.d11[0] + ref.d11[1] * 0.6 + ref.d11[2] * 0.36) * 0.6
    assert g.ki_u * g.integral_limit_u / drag == pytest.approx(40.0 * 5.0 / drag_ref, rel=1e-12)
    # LOS: the heading PID at the same scaled omega (reference 8 rad/s), lengths by L, speeds by U
    los = load_scenario(overrides={"vessel": {"kind": vessel}, "controller": {"kind": "los"}}).controller.gains
    w = math.sqrt(1000.0 / ref.m33)
    assert math.sqrt(los.kp_psi / ship.m33) == pytest.approx(w * s, rel=1e-12)
    assert los.lookahead == pytest.approx(3.0 * L / 1.98, rel=1e-12) and los.u_at == pytest.approx(0.3 * U / 0.6)
    assert los.ref_omega == pytest.approx(3.0 * s, rel=1e-12)
    # and its closed heading loop is stable: every root of m33 s^3 + (d_r + kd) s^2 + kp s + ki in the left half
    roots = np.roots([ship.m33, d_r + los.kd_psi, los.kp_psi, los.ki_psi])
    assert np.all(roots.real < 0)


def test_a_gain_the_scenario_sets_is_kept_and_the_others_derived():
    sc = load_scenario(overrides={"vessel": {"kind": "otter"}, "controller": {"kind": "los", "kp_psi": 777.0}})
    assert sc.controller.gains.kp_psi == 777.0 and "kp_psi" not in sc.controller.derived
    assert sc.controller.gains.kd_psi != 250.0 and "kd_psi" in sc.controller.derived
    assert sc.to_dict()["controller"]["gains"]["kp_psi"] == 777.0   # the metadata holds the gains the run used


def test_the_gains_are_placed_on_the_nominal_model():
    plain = load_scenario(overrides={"vessel": {"kind": "otter"}}).baseline.gains
    heavy = load_scenario(overrides={"vessel": {"kind": "otter", "model_mismatch": 2.0}}).baseline.gains
    assert heavy.kp_r == pytest.approx(2.0 * plain.kp_r, rel=1e-12) and heavy.ki_u == pytest.approx(2.0 * plain.ki_u)


def test_kinds_and_the_report_show_the_derived_gains():
    from usv_mj.cli.kinds import list_kinds
    from usv_mj.outputs.report import gains_section
    from usv_mj import simulate

    otter = load_scenario(overrides={"vessel": {"kind": "otter"}, "controller": {"kind": "los"}})
    rows = {r["kind"]: r for r in list_kinds(["controller"], vessel="otter")["controller"]["kinds"]}
    los = {o["name"]: o for o in rows["los"]["options"]}
    assert los["kp_psi"]["derived"] and los["kp_psi"]["default"] == otter.controller.gains.kp_psi
    assert "derived" not in los["ilos_sigma"]
    paper = {o["name"]: o for o in {r["kind"]: r for r in list_kinds(["controller"])["controller"]["kinds"]}["pi"]["options"]}
    assert paper["kp_r"]["default"] == 200.0 and paper["kp_r"]["derived"]
    rec = simulate(otter.with_overrides({"duration": 0.01, "plant": {"kind": "analytic"}}))
    text = gains_section(rec)
    assert "| kp_psi | 2706.73 | the vessel (derived) |" in text and "| ilos_sigma | 0 | the scenario or the default |" in text


def test_each_vessel_of_a_fleet_gets_the_gains_of_its_own_hull():
    """[[vessels]] (usv_mj.scenario.fleet): every vessel's scenario derives its controller's defaults
    from its own hull, as a single run on that hull does, and build_fleet's controllers use them
    (the top level's vessel, the paper hull, gives none of them its gains)."""
    from usv_mj.builder import build_fleet

    vessels = [
        {"name": "paper", "steer": "keep", "initial": {"eta": [0.0, 0.0, 0.0], "nu": [0.6, 0.0, 0.0]}},
        {"name": "otter", "steer": "keep", "vessel": {"kind": "otter"},
         "initial": {"eta": [0.0, 100.0, 0.0], "nu": [1.0, 0.0, 0.0]}},
        {"name": "wamv", "vessel": {"kind": "examples/vessels/wamv.toml"}, "controller": {"kind": "pi"},
         "trajectory": {"kind": "line", "start": [0.0, 200.0], "heading_deg": 0.0},
         "initial": {"eta": [0.0, 200.0, 0.0]}},
    ]
    sc = load_scenario(overrides={"duration": 1.0, "plant": {"kind": "analytic"}, "vessels": vessels})
    parts = {v.name: v for v in build_fleet(sc).vessels}
    alone = {
        "paper": load_scenario(overrides={"controller": {"kind": "los"}}).controller,
        "otter": load_scenario(overrides={"vessel": {"kind": "otter"}, "controller": {"kind": "los"}}).controller,
        "wamv": load_scenario(overrides={"vessel": {"kind": "examples/vessels/wamv.toml"},
                                         "controller": {"kind": "pi"}}).controller,
    }
    for v in sc.vessels:
        mine = v.scenario.controller
        assert mine.kind == alone[v.name].kind and mine.gains == alone[v.name].gains, v.name
        assert set(mine.derived) == set(alone[v.name].derived) != set(), v.name
        assert parts[v.name].controller.gains == mine.gains, v.name
    assert sc.vessels[0].scenario.controller.gains.kp_psi == PAPER_LOS["kp_psi"]
    assert sc.vessels[1].scenario.controller.gains.kp_psi != PAPER_LOS["kp_psi"]   # the Otter's own
    assert sc.vessels[2].scenario.controller.gains.kp_r != PAPER_PI["kp_r"]        # the WAM-V's own
    assert parts["otter"].controller.nominal == sc.vessels[1].scenario.nominal_ship
