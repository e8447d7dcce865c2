"""The Imazu suite of the benchmark (issue 35 item 5: usv_mj/jobs/bench/imazu.py, suites/imazu.toml,
metrics.encounter_metrics): its expansion against the published geometry, the vessel rule, the
encounter metrics on constructed records against hand calculations, and situations 1, 2 and 4 run as
the suite plans them at a shorter scale (R = 10 L, 1.25 T: about 40 s simulated, not the shipped
suite's 330 s; the placement and the episode are the same code): no avoidance collides, sbmpc and vo
keep the safety domain. The 1-vs-2-workers identity and the plug-in on the leaderboard:
tests/test_bench_imazu_run.py.

Independent numbers: the situations' counts of targets (1-4 one, 5-11 two, 12-22 three: Imazu,
as the issue states them), the published start of every target (Sawada et al. 2021, Table 4: the
relative bearing and range / R stored beside each case, which the placement does not use), the
paper hull's L = 1.98 m and its 0.6 m/s (so R = 50 L = 99 m, T = R / U = 165 s), Froude scaling of
that speed to every other hull (U = 0.6 sqrt(L / 1.98)).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from usv_mj import load_scenario
from usv_mj.core.registry import VESSELS
from usv_mj.jobs.bench.imazu import PAPER_FROUDE, situation_speed, suits
from usv_mj.jobs.bench.metrics import encounter_metrics
from usv_mj.jobs.bench.suite import load_suite, plan_suite, shipped_suite_path
from usv_mj.jobs.sweep.runner import run_one
from usv_mj.record.fleet import FleetRecord
from usv_mj.record.run_record import CORE_COLUMNS, RunRecord
from usv_mj.scenario.imazu import imazu_case

TARGETS = {**{c: 1 for c in range(1, 5)}, **{c: 2 for c in range(5, 12)}, **{c: 3 for c in range(12, 23)}}
TASKS = {"one-target": list(range(1, 5)), "two-targets": list(range(5, 12)), "three-targets": list(range(12, 23))}


@pytest.fixture(scope="module")
def suite():
    return load_suite("imazu")


def test_imazu_is_a_shipped_suite_found_by_name(suite):
    assert suite.source == str(shipped_suite_path("imazu")) and suite.name == "imazu"
    assert [c.name for c in suite.controllers] == ["no-avoidance", "sbmpc", "vo"]
    assert suite.conditions == ["calm", "sea"] and suite.tasks == list(TASKS)


def test_the_vessels_are_the_ones_the_rule_picks(suite):
    """Every built-in vessel kind that takes forces and has a sea model, and no other."""
    picked = [k for k in VESSELS.builtin_kinds()
              if suits(load_scenario(preset="paper", overrides={"vessel": {"kind": k}}).vessel.model) is None]
    assert sorted(suite.vessels) == sorted(picked) == ["clarke83", "cybership2", "otter", "paper"]
    kvlcc2 = load_scenario(preset="paper", overrides={"vessel": {"kind": "kvlcc2"}}).vessel.model
    assert "not forces" in suits(kvlcc2)


def test_the_speed_is_the_paper_hulls_froude_scaled():
    assert situation_speed(1.98) == pytest.approx(0.6, rel=1e-12)
    assert PAPER_FROUDE == pytest.approx(0.6 / math.sqrt(9.81 * 1.98))
    for L in (1.255, 2.0, 7.0):
        assert situation_speed(L) == pytest.approx(0.6 * math.sqrt(L / 1.98), rel=1e-12)


def test_the_suite_expands_to_22_situations_x_conditions_x_vessels_x_controllers(suite):
    runs = suite.plan.runs
    assert len(runs) == 22 * 2 * 4 * 3
    cells: dict = {}
    for run in runs:
        v = run.values
        cells.setdefault((v["condition"], v["vessel"], v["controller"]), []).append((v["task"], v["situation"]))
        assert TASKS[v["task"]][v["episode"]] == v["situation"]
    assert len(cells) == 2 * 4 * 3
    for cases in cells.values():
        assert sorted(c for _, c in cases) == list(range(1, 23))
    # the sea condition's waves, the same seed for every controller and vessel of a situation
    seeds = {}
    for run in runs:
        hs = run.scenario.sea.waves.hs
        assert (hs > 0) == (run.values["condition"] == "sea")
        seeds.setdefault((run.values["task"], run.values["situation"]), set()).add(run.scenario.sea.waves.seed)
    assert all(len(s) == 1 for s in seeds.values())


@pytest.mark.parametrize("vessel", ["paper", "otter"])
def test_every_episode_has_the_published_geometry(suite, vessel):
    """The own ship at the origin heading north at U, every target the same hull keeping course at its
    speed ratio, at the published bearing and range, and every vessel at the collision point (0, R) at
    T = R / U; the episode lasts 2 T."""
    L = 1.98 if vessel == "paper" else load_scenario(preset="paper", overrides={"vessel": {"kind": "otter"}}) \
        .vessel.model.dimensions.L
    U = 0.6 * math.sqrt(L / 1.98)
    R, T = 50.0 * L, 50.0 * L / U
    if vessel == "paper":
        assert (R, T) == (pytest.approx(99.0), pytest.approx(165.0))
    seen = set()
    for run in suite.plan.runs:
        v = run.values
        if v["vessel"] != vessel or v["condition"] != "calm":
            continue
        sc, case = run.scenario, v["situation"]
        seen.add(case)
        assert sc.duration == pytest.approx(2.0 * T, rel=1e-12)
        assert len(sc.vessels) == 1 + TARGETS[case]
        own, targets = sc.vessels[0], sc.vessels[1:]
        assert own.own_ship and own.steer == "controller" and own.name == "own"
        assert own.scenario.controller.kind == {"no-avoidance": "los", "sbmpc": "sbmpc", "vo": "vo"}[v["controller"]]
        assert own.scenario.initial.eta == pytest.approx((0.0, 0.0, math.pi / 2), abs=1e-12)
        assert own.scenario.initial.nu == pytest.approx((U, 0.0, 0.0), rel=1e-12)
        assert run.options["encounter"]["situations"] == {str(i): t.situation
                                                          for i, t in enumerate(imazu_case(case).targets, start=1)}
        for entry, published in zip(targets, imazu_case(case).targets):
            assert entry.steer == "keep" and not entry.own_ship
            assert entry.scenario.vessel.kind == vessel
            x, y, psi = entry.scenario.initial.eta
            speed = entry.scenario.initial.nu[0]
            assert speed == pytest.approx(published.speed_ratio * U, rel=1e-12)
            assert math.hypot(x, y) == pytest.approx(published.range_R * R, abs=2e-4 * R)
            bearing = math.degrees(math.atan2(x, y))   # clockwise from north = from the own ship's bow
            assert bearing == pytest.approx(published.bearing_deg, abs=0.01)
            at_T = (x + speed * T * math.cos(psi), y + speed * T * math.sin(psi))
            assert at_T == (pytest.approx(0.0, abs=1e-9 * R), pytest.approx(R, rel=1e-12))
    assert seen == set(range(1, 23))


# --- the encounter metrics on constructed records ---------------------------------------------------

DT = 0.5
L = 2.0


def vessel_record(x, y, psi, t, *, speed, f_u=0.0, f_r=0.0, ref=None):
    """A record of a vessel at positions (x, y) and heading psi over t; its reference the straight line
    x_d = 0, y_d = speed t north (``ref``: another (x_d, y_d, x_d_dot, y_d_dot))."""
    n = len(t)
    cols = {name: np.zeros(n) for name in CORE_COLUMNS}
    cols.update(t=t, x=np.asarray(x, float), y=np.asarray(y, float), psi=np.broadcast_to(psi, (n,)).copy(),
                u=np.full(n, speed), f_u=np.broadcast_to(f_u, (n,)).copy(), f_r=np.broadcast_to(f_r, (n,)).copy())
    if ref is None:
        ref = (np.zeros(n), speed * t, np.zeros(n), np.full(n, speed))
    cols["x_d"], cols["y_d"], cols["x_d_dot"], cols["y_d_dot"] = ref
    cols["psi_d"] = np.full(n, math.pi / 2)
    cols["u_d"] = np.full(n, speed)
    return RunRecord.from_arrays(cols, metadata={"length_m": L, "criterion": {"kind": "not_judged", "reason": "-"}},
                                 diagnostic_fields=())


def head_on_fleet(offset: float, plant: str = "analytic", *, own_x=None, own_y=None, f_u=0.0, f_r=0.0):
    """Own ship north along x = 0 at 1 m/s from (0, 0); a target south along x = ``offset`` at 1 m/s
    from (offset, 100): they are abreast at t = 50 s, range |offset| there, the closest."""
    t = np.arange(0.0, 100.0 + DT / 2, DT)
    own = vessel_record(np.zeros_like(t) if own_x is None else own_x(t), t if own_y is None else own_y(t),
                        math.pi / 2, t, speed=1.0, f_u=f_u, f_r=f_r)
    target = vessel_record(np.full_like(t, offset), 100.0 - t, -math.pi / 2, t, speed=1.0)
    fleet = FleetRecord(["own", "ts1"], {"own": own, "ts1": target}, "own", len(t), metadata={"plant": plant})
    return fleet


def test_a_wide_straight_pass():
    """Passing port to port 12 m apart (more than the preferred 5 L = 10 m) on straight lines: no
    collision, the safety domain (3 L = 6 m) kept, S_safety = 1 (S_r = 1 beyond R_pref), S14 = 0 (no
    course change at all: the manoeuvre is not apparent, P_na_course = 1), zero path deviation and,
    against itself alone, zero time loss."""
    fleet = head_on_fleet(-12.0)
    m = encounter_metrics(fleet, fleet.own_record, {1: "head_on"})
    assert m["collision"] is False and m["domain_kept"] is True
    assert m["min_range_m"] == pytest.approx(12.0, abs=1e-12)
    assert m["S_safety"] == 1.0 and m["S14"] == 0.0 and m["S15"] is None and m["S17"] is None
    assert m["path_deviation_m"] == 0.0 and m["time_loss_s"] == 0.0


def test_collision_and_the_domain_on_each_plant():
    """Analytic: a collision is a range below (L + L) / 2 = 2 m: 1.5 m is one, 5 m is not (but 5 m is
    inside the 6 m domain). MuJoCo: a contact force between the own ship and the target is one,
    whatever the range; a contact between two targets is not the own ship's."""
    near = encounter_metrics(head_on_fleet(1.5), situations={1: "head_on"})
    assert near["collision"] is True and near["domain_kept"] is False and near["min_range_m"] == pytest.approx(1.5)
    assert near["S_safety"] == 0.0    # inside R_col = 1 L: S_r = 0, so S_safety = 0
    mid = encounter_metrics(head_on_fleet(5.0))
    assert mid["collision"] is False and mid["domain_kept"] is False
    touching = head_on_fleet(5.0, "mujoco")
    assert encounter_metrics(touching)["collision"] is False
    touching.contacts[100, 0] = 3.0   # N, the own ship and ts1
    assert encounter_metrics(touching)["collision"] is True
    t = np.arange(0.0, 100.0 + DT / 2, DT)
    three = FleetRecord(["own", "a", "b"], {"own": vessel_record(np.zeros_like(t), t, math.pi / 2, t, speed=1.0),
                                            "a": vessel_record(np.full_like(t, 50.0), t, math.pi / 2, t, speed=1.0),
                                            "b": vessel_record(np.full_like(t, 52.0), t, math.pi / 2, t, speed=1.0)},
                        "own", len(t), metadata={"plant": "mujoco"})
    three.contacts[10, three.pairs.index((1, 2))] = 5.0   # a and b touch, far from the own ship
    m = encounter_metrics(three)
    assert m["collision"] is False and m["min_range_m"] == pytest.approx(50.0)


def test_path_deviation_time_loss_and_effort_by_hand():
    """The own ship swings out A sin(pi t / 100) to starboard (east) and ends D = 3 m behind its
    reference, while alone it ends on it: path deviation A = 7 m, time loss D / U = 3 s; with f_u = 40 N
    and f_r = 2 N m held, effort_u = 40 x 100 s = 4000 N s and effort_r = 200 N m s (the zero-order
    hold: the last row's input is never applied), energy = |40 u| x 100 = 4000 J (r = 0)."""
    A, D = 7.0, 3.0
    fleet = head_on_fleet(-30.0, own_x=lambda t: A * np.sin(np.pi * t / 100.0), own_y=lambda t: t - D * t / 100.0,
                          f_u=40.0, f_r=2.0)
    t = fleet.own_record["t"]
    alone = vessel_record(np.zeros_like(t), t, math.pi / 2, t, speed=1.0)
    m = encounter_metrics(fleet, alone, {1: "head_on"})
    assert m["path_deviation_m"] == pytest.approx(A, rel=1e-12)
    assert m["time_loss_s"] == pytest.approx(D / 1.0, rel=1e-12)
    assert m["effort_u"] == pytest.approx(4000.0, rel=1e-12) and m["effort_r"] == pytest.approx(200.0, rel=1e-12)
    assert m["energy"] == pytest.approx(4000.0, rel=1e-12)
    assert encounter_metrics(fleet, None)["time_loss_s"] is None   # no no-traffic run, no time loss
    short = vessel_record(np.zeros(10), np.arange(10.0), math.pi / 2, np.arange(10) * DT, speed=1.0)
    assert encounter_metrics(fleet, short)["time_loss_s"] is None   # runs of other lengths are not compared


# --- situations 1, 2 and 4 as the suite plans them, at a shorter scale -------------------------------

K_R_SHORT, DURATION_T_SHORT = 10.0, 1.25
SHORT = {"name": "imazu-short", "seed": 7, "plant": "analytic",
         "controllers": [{"name": "no-avoidance", "kind": "los", "set": {"controller.crab_compensation": False}},
                         "sbmpc", "vo"],
         "conditions": {"calm": {}},
         "tasks": [{"name": "one-target", "base": "paper", "set": {"control_period": 0.02},
                    "imazu": {"cases": [1, 2, 4], "k_R": K_R_SHORT, "duration_T": DURATION_T_SHORT}}]}


@pytest.fixture(scope="module")
def short_rows():
    """Every episode of the short suite, run as a worker runs it: {(situation, controller): row}."""
    runs = plan_suite(SHORT).plan.runs
    assert len(runs) == 3 * 3
    return {(r.values["situation"], r.values["controller"]): run_one(r.run_id, r.scenario, r.values, r.options)
            for r in runs}


def test_the_short_scale_is_the_same_placement():
    """R = 10 L = 19.8 m, U = 0.6 m/s, T = R / U = 33 s, the episode 1.25 T = 41.25 s; the head-on
    target starts 2 R = 39.6 m ahead."""
    run = next(r for r in plan_suite(SHORT).plan.runs if r.values["situation"] == 1)
    assert run.scenario.duration == pytest.approx(1.25 * 19.8 / 0.6, rel=1e-12)
    x, y, _ = run.scenario.vessels[1].scenario.initial.eta
    assert (x, y) == (pytest.approx(0.0, abs=1e-9), pytest.approx(2 * 19.8, rel=1e-12))


@pytest.mark.parametrize("case", [1, 2, 4])
def test_without_avoidance_the_own_ship_collides(short_rows, case):
    """Every vessel keeps its line and reaches the collision point (0, R) at T: the analytic hulls pass
    through each other (range below one length), S_safety = 0 (inside R_col), and the own ship never
    left its route (no deviation, no time lost against its run alone)."""
    row = short_rows[(case, "no-avoidance")]
    assert row["status"] == "ok"
    assert row["m.collision"] is True and row["m.domain_kept"] is False and row["m.min_range_m"] < 1.98
    assert row["m.S_safety"] == 0.0
    assert row["m.path_deviation_m"] < 0.05 and abs(row["m.time_loss_s"]) < 0.05


@pytest.mark.parametrize("controller", ["sbmpc", "vo"])
@pytest.mark.parametrize("case", [1, 2, 4])
def test_the_built_in_avoidance_keeps_the_safety_domain(short_rows, case, controller):
    """Head-on (1), crossing give-way (2) and crossing stand-on (4, the target keeping course: the own
    ship acts from stage 3, 7.5 L): no collision, the own ship's safety domain (3 L = 5.94 m) kept, it
    left its route (by more than one length) and arrives later than alone."""
    row = short_rows[(case, controller)]
    assert row["status"] == "ok"
    assert row["m.collision"] is False and row["m.domain_kept"] is True and row["m.min_range_m"] > 3 * 1.98
    assert row["m.path_deviation_m"] > 1.98 and row["m.time_loss_s"] > 0.0
