"""The standard manoeuvres (usv_mj.jobs.manoeuvres): their measures against closed forms and high-accuracy
integrations of independent models, the IMO limits as the resolution states them, and one short run
per manoeuvre through `usv-mj manoeuvre` on the analytic plant."""

import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from usv_mj.cli.main import main
from usv_mj.core.errors import ScenarioError
from usv_mj.jobs.manoeuvres import imo
from usv_mj.jobs.manoeuvres.measures import spiral_measures, stopping_measures, turning_measures, zigzag_measures


# --- turning circle: an exact circular arc --------------------------------------------------------


def _arc(R, U, side, psi0, p0, approach_s=4.0, turns=2.5, n=200001):
    """A straight approach along heading psi0 to p0 at t = approach_s, then a circle of radius R [m]
    at speed U [m/s] to ``side`` (+1 port, -1 starboard): the record's columns."""
    e = np.array([math.cos(psi0), math.sin(psi0)])
    nrm = side * np.array([-e[1], e[0]])
    w = U / R
    t_turn = turns * 2 * math.pi / w
    t = np.linspace(0.0, approach_s + t_turn, n)
    s = np.clip(t - approach_s, 0.0, None)
    th = w * s
    along = np.where(t < approach_s, U * (t - approach_s), R * np.sin(th))
    across = np.where(t < approach_s, 0.0, R * (1 - np.cos(th)))
    x = p0[0] + along * e[0] + across * nrm[0]
    y = p0[1] + along * e[1] + across * nrm[1]
    psi = psi0 + side * th
    u = np.full_like(t, U)
    r = np.where(t < approach_s, 0.0, side * w)
    return t, x, y, psi, u, np.zeros_like(t), r, approach_s


@pytest.mark.parametrize("side,psi0,p0", [(-1, 0.0, (0.0, 0.0)), (1, 1.0, (3.0, -2.0)), (-1, -2.5, (-7.0, 4.0))])
def test_circle_arc_gives_advance_transfer_tactical_and_steady_diameter(side, psi0, p0):
    R, U = 7.5, 1.3
    t, x, y, psi, u, v, r, te = _arc(R, U, side, psi0, p0)
    m = turning_measures(t, x, y, psi, u, v, r, t_execute=te, length=3.0)
    assert m["turn"] == ("port" if side > 0 else "starboard")
    # on a circle from the execute: at 90 deg the ship is R ahead and R across, at 180 deg 2R across
    assert m["advance_m"] == pytest.approx(R, rel=1e-6)
    assert m["transfer_m"] == pytest.approx(R, rel=1e-6)
    assert m["tactical_diameter_m"] == pytest.approx(2 * R, rel=1e-6)
    assert m["steady_diameter_m"] == pytest.approx(2 * R, rel=1e-9)
    assert m["steady_diameter_from_rate_m"] == pytest.approx(2 * R, rel=1e-12)
    assert m["time_to_90_s"] == pytest.approx((math.pi / 2) * R / U, rel=1e-6)
    assert m["advance_L"] == pytest.approx(R / 3.0, rel=1e-6)
    assert m["tactical_diameter_L"] == pytest.approx(2 * R / 3.0, rel=1e-6)


def test_a_turn_short_of_90_degrees_has_no_advance():
    t, x, y, psi, u, v, r, te = _arc(5.0, 1.0, -1, 0.0, (0, 0), turns=0.2)
    m = turning_measures(t, x, y, psi, u, v, r, t_execute=te)
    assert m["advance_m"] is None and m["tactical_diameter_m"] is None and m["steady_diameter_m"] is None


def test_first_order_nomoto_steady_diameter_is_2U_over_K_delta():
    """T r' + r = K delta at constant speed U (Nomoto's first-order model), integrated to 1e-12: the
    steady turn has r = K delta, so the steady turning diameter is 2 U / |K delta| (closed form)."""
    T, K, delta, U = 2.0, 0.08, -3.0, 1.5       # s, 1/s per unit command, command, m/s
    def f(t, s):
        x, y, psi, r = s
        return [U * math.cos(psi), U * math.sin(psi), r, (K * delta - r) / T]
    t = np.linspace(0.0, 120.0, 120001)
    sol = solve_ivp(f, (0, 120), [0, 0, 0, 0], t_eval=t, rtol=1e-12, atol=1e-12, method="DOP853")
    x, y, psi, r = sol.y
    m = turning_measures(t, x, y, psi, np.full_like(t, U), None, r, steady_after_deg=360.0)
    D = 2 * U / abs(K * delta)
    # after 360 deg (about 28 s) the transient exp(-t / T) is below 1e-6
    assert m["steady_diameter_m"] == pytest.approx(D, rel=1e-5)
    assert m["steady_diameter_from_rate_m"] == pytest.approx(D, rel=1e-5)
    assert m["turn"] == "starboard"
    # the heading at the 90 deg point is the closed form psi(t) = K delta (t - T (1 - exp(-t/T)))
    t90 = m["time_to_90_s"]
    assert abs(K * delta * (t90 - T * (1 - math.exp(-t90 / T)))) == pytest.approx(math.pi / 2, rel=1e-6)
    # the first-order lag moves the 90 deg point ahead of the steady circle's: advance > D / 2
    assert m["advance_m"] > D / 2


# --- zig-zag: a sinusoidal heading -----------------------------------------------------------------


def _zigzag_logic(h, switch):
    """The command of the zig-zag switching logic (controllers/zigzag.py's rules) on heading ``h``."""
    c, out = -1.0, np.empty_like(h)
    for i, hi in enumerate(h):
        if (c < 0 and hi <= -switch) or (c > 0 and hi >= switch):
            c = -c
        out[i] = c
    return out


@pytest.mark.parametrize("amp_deg,switch_deg", [(18.0, 10.0), (31.0, 20.0)])
def test_sinusoidal_heading_overshoot_is_amplitude_minus_switch(amp_deg, switch_deg):
    A, s, w = math.radians(amp_deg), math.radians(switch_deg), 0.7
    t = np.linspace(0.0, 40.0, 400001)
    h = -A * np.sin(w * t)                      # a first turn to starboard
    U = 1.2                                     # m/s along a straight line: the track is U t
    m = zigzag_measures(t, h, _zigzag_logic(h, s), switch_deg, U * t, np.zeros_like(t), length=4.0)
    dt = t[1] - t[0]
    assert m["first_overshoot_deg"] == pytest.approx(amp_deg - switch_deg, abs=1e-6)
    assert m["second_overshoot_deg"] == pytest.approx(amp_deg - switch_deg, abs=1e-6)
    t1 = math.asin(s / A) / w                     # the second execute: -A sin(w t) = -s
    assert m["time_to_second_execute_s"] == pytest.approx(t1, abs=dt)
    assert m["track_to_second_execute_m"] == pytest.approx(U * t1, abs=U * dt)
    assert m["track_to_second_execute_L"] == pytest.approx(U * t1 / 4.0, abs=U * dt)
    assert m["time_to_first_overshoot_s"] == pytest.approx(math.pi / 2 / w, abs=dt)
    assert m["period_s"] == pytest.approx(2 * math.pi / w, abs=2 * dt)


# --- spiral: a cubic (Bech) model with a hysteresis loop -------------------------------------------


def test_spiral_of_an_unstable_cubic_model_shows_its_loop():
    """T r' = K delta + r - a r^3 (directionally unstable at r = 0): the steady states solve
    r - a r^3 = -K delta; the branch r > 0 exists down to the fold K delta = -2 / (3 sqrt(3 a)), so a
    command between the folds keeps the sign of the branch it came from."""
    T, K, a = 1.0, 0.1, 4.0
    fold = 2 / (3 * math.sqrt(3 * a)) / K        # |delta| of the folds: 1.9245
    levels = [3.0, 2.0, 1.0, 0.0, -1.0, -2.0, -3.0]
    cmds = [(c, "down") for c in levels] + [(c, "up") for c in levels[::-1][1:]]
    hold = 40.0                                  # s: 30 s to settle, the slowest decay 1.2 s
    def f(t, s):
        c = cmds[min(int(t // hold), len(cmds) - 1)][0]
        return [(K * c + s[0] - a * s[0] ** 3) / T]
    t = np.linspace(0.0, hold * len(cmds), 52001)
    sol = solve_ivp(f, (0, t[-1]), [0.6], t_eval=t, rtol=1e-11, atol=1e-12, max_step=0.05)
    r = sol.y[0]
    holds = [(i * hold, (i + 1) * hold, c, b) for i, (c, b) in enumerate(cmds)]
    m = spiral_measures(t, r, holds)
    inside = sorted(c for c in set(levels) if abs(c) < fold)
    assert m["hysteresis"] and m["loop_commands"] == inside and m["loop_width"] == pytest.approx(2.0)
    assert m["loop_width_upper"] == pytest.approx(4.0)   # the fold lies between the held 1 and 2
    for p in m["points"]:       # every steady r is a root of the cubic on its branch
        assert p["yaw_rate"] - a * p["yaw_rate"] ** 3 == pytest.approx(-K * p["command"], abs=1e-8)
    assert m["yaw_rate_at_zero"]["down"] == pytest.approx(1 / math.sqrt(a), rel=1e-8)
    assert m["yaw_rate_at_zero"]["up"] == pytest.approx(-1 / math.sqrt(a), rel=1e-8)


def test_spiral_of_a_stable_model_has_no_loop():
    t = np.linspace(0, 60, 6001)
    holds = [(0, 20, 1.0, "down"), (20, 40, -1.0, "down"), (40, 60, 1.0, "up")]
    r = np.where(t < 20, 0.1, np.where(t < 40, -0.1, 0.1))
    m = spiral_measures(t, r, holds)
    assert not m["hysteresis"] and m["loop_width"] == 0.0


# --- stopping: an exponential decay ----------------------------------------------------------------


def test_stopping_with_linear_drag_reaches_U_tau_minus_threshold():
    """m u' = -d u: u = U exp(-t / tau), x = U tau (1 - exp(-t / tau)); the speed falls below s at
    tau ln(U / s), when the ship has run tau (U - s) (closed form)."""
    U, tau, s, psi0 = 0.8, 3.0, 0.02, 0.4
    t = np.linspace(0, 40, 400001)
    d = U * tau * (1 - np.exp(-t / tau))
    x, y = 1.0 + d * math.cos(psi0), 2.0 + d * math.sin(psi0)
    m = stopping_measures(t, x, y, np.full_like(t, psi0), U * np.exp(-t / tau), np.zeros_like(t),
                          stop_speed=s, length=2.0)
    dt = t[1] - t[0]
    assert m["time_to_stop_s"] == pytest.approx(tau * math.log(U / s), abs=dt)
    assert m["track_reach_m"] == pytest.approx(tau * (U - s), abs=U * dt)
    assert m["head_reach_m"] == pytest.approx(tau * (U - s), abs=U * dt)
    assert m["lateral_deviation_m"] == pytest.approx(0.0, abs=1e-9)
    assert m["track_reach_L"] == pytest.approx(m["track_reach_m"] / 2.0)


# --- IMO MSC.137(76) --------------------------------------------------------------------------------


def test_imo_overshoot_limits_as_the_resolution_states():
    # 10 deg below L/V = 10 s, 20 deg from 30 s, 5 + 0.5 L/V between; the second 15 deg more
    assert imo.first_overshoot_limit_10(50.0, 10.0) == 10.0
    assert imo.first_overshoot_limit_10(200.0, 10.0) == pytest.approx(15.0)
    assert imo.first_overshoot_limit_10(400.0, 10.0) == 20.0
    assert imo.second_overshoot_limit_10(50.0, 10.0) == 25.0
    assert imo.second_overshoot_limit_10(200.0, 10.0) == pytest.approx(32.5)
    assert imo.second_overshoot_limit_10(400.0, 10.0) == 40.0
    c = imo.criteria("turning", {"advance_L": 4.0, "tactical_diameter_L": 5.5}, 150.0, 8.0)
    assert c["applies"] and [r["met"] for r in c["rows"]] == [True, False]
    assert not imo.criteria("stopping", {"track_reach_L": 1.0}, 2.0, 0.6)["applies"]


# --- the options and the command ------------------------------------------------------------------


def test_manoeuvre_table_is_validated():
    from usv_mj import load_scenario

    with pytest.raises(ScenarioError, match="manoeuvre.yaw_moment must be > 0"):
        load_scenario(overrides={"manoeuvre": {"kind": "turning", "yaw_moment": -1.0}})
    with pytest.raises(ScenarioError, match="unknown key 'manoeuvre.angle_deg'"):
        load_scenario(overrides={"manoeuvre": {"kind": "turning", "angle_deg": 20.0}})
    with pytest.raises(ScenarioError, match="manoeuvre.kind must be one of"):
        load_scenario(overrides={"manoeuvre": {"kind": "crash-stop"}})
    s = load_scenario(overrides={"manoeuvre": {"kind": "spiral", "steps": 2}})
    assert [c for c, _ in s.manoeuvre.options.commands()] == [10, 5, 0, -5, -10, -5, 0, 5, 10]


def test_approach_force_holds_the_approach_speed():
    """The paper's hull: d11(U) U (docs/model.md §1, the closed form), with Delta's 0.6 N when it is on."""
    from usv_mj import load_scenario
    from usv_mj.jobs.manoeuvres.trial import approach_force

    U = 0.6
    d11 = 45.6 + 67.26 * U + 10.0 * U * U
    # found on the plant by secant iteration, to round-off (the paper preset's d(t) is left out)
    assert approach_force(load_scenario(overrides={"ship": {"uncertainty_scale": 0.0}}), U) == \
        pytest.approx(d11 * U, rel=1e-9)
    assert approach_force(load_scenario(), U) == pytest.approx(d11 * U - 0.6, rel=1e-9)
    assert approach_force(load_scenario(), 1.5) == pytest.approx((45.6 + 67.26 * 1.5 + 22.5) * 1.5 - 0.6, rel=1e-9)


CLI_RUNS = [
    ("turning", ["--duration", "25"], ("advance_m", "transfer_m", "tactical_diameter_m", "steady_diameter_m")),
    ("zigzag", ["--duration", "15"], ("first_overshoot_deg", "second_overshoot_deg", "time_to_second_execute_s")),
    ("spiral", ["--set", "manoeuvre.steps=1", "--set", "manoeuvre.hold_s=8"], ("loop_width",)),
    ("stopping", ["--duration", "20"], ("track_reach_m", "head_reach_m", "lateral_deviation_m")),
]


@pytest.mark.parametrize("kind,extra,keys", CLI_RUNS)
def test_cli_manoeuvre_writes_its_outputs(kind, extra, keys, tmp_path):
    out = tmp_path / kind
    code = main(["manoeuvre", kind, "--plant", "analytic", "-q", "--out", str(out), *extra])
    assert code == 0
    for name in ("manoeuvre.json", "report.md", "run.mcap", "summary.json", "figures/manoeuvre_track.png",
                 "figures/manoeuvre_time.png"):
        assert (out / name).is_file(), name
    result = json.loads((out / "manoeuvre.json").read_text())
    assert result["kind"] == kind and result["plant"] == "analytic" and result["status"] == "completed"
    for key in keys:
        assert isinstance(result["measures"][key], float) and math.isfinite(result["measures"][key]), key
    assert not result["imo"]["applies"]            # the paper's 2 m hull: for orientation only
    assert f"## Manoeuvre: {kind}" in (out / "report.md").read_text()
    if kind == "spiral":
        assert (out / "figures/manoeuvre_spiral.png").is_file()
        assert result["measures"]["hysteresis"]    # the paper's hull is directionally unstable
    if kind == "turning":   # usv-mj plot remakes the manoeuvre's outputs from the log alone
        assert main(["plot", str(out / "run.mcap"), "--out", str(tmp_path / "replot")]) == 0
        again = json.loads((tmp_path / "replot" / "manoeuvre.json").read_text())
        scalars = {k: v for k, v in result["measures"].items() if isinstance(v, float)}
        assert {k: again["measures"][k] for k in scalars} == pytest.approx(scalars, rel=1e-12)
        assert f"## Manoeuvre: {kind}" in (tmp_path / "replot" / "report.md").read_text()


def test_cli_manoeuvre_bad_input_is_one_line(tmp_path, capsys):
    assert main(["manoeuvre", "turning", "--set", "manoeuvre.side=left", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("usv-mj manoeuvre: error:") and "manoeuvre.side" in err and len(err.splitlines()) == 1
    from usv_mj.scenario.spec import Scenario

    if "vessel" not in Scenario.__dataclass_fields__:
        assert main(["manoeuvre", "turning", "--vessel", "otter", "--out", str(tmp_path / "y")]) == 2
        assert "no vessel registry yet" in capsys.readouterr().err


def test_turning_circle_from_the_api_agrees_on_both_plants():
    """The same manoeuvre on the MuJoCo plant and the analytic plant (the other plant as the
    independent number): the measures within 1e-9 m (they differ by about 2e-11 m, as compare's open
    loop does), and the tactical diameter found at all."""
    from usv_mj import load_scenario
    from usv_mj.jobs.manoeuvres import turning_circle

    scenario = load_scenario(preset="paper")
    a = turning_circle(scenario, plant_kind="analytic", duration=12.0)
    m = turning_circle(scenario, plant_kind="mujoco", duration=12.0)
    assert a["plant"] == "analytic" and m["plant"] == "mujoco"
    for key in ("advance_m", "transfer_m", "tactical_diameter_m"):
        assert isinstance(a["measures"][key], float)
        assert m["measures"][key] == pytest.approx(a["measures"][key], abs=1e-9), key
    assert a["measures"]["steady_diameter_m"] is None       # 7 s of turn: not yet 360 deg


def test_paper_hull_spiral_has_its_loop_above_0_2_m_s_only():
    """docs/model.md §8: the straight run of the paper's hull is unstable above 0.201 m/s (the
    eigenvalue of the linearized sway-yaw dynamics crosses zero there) and at 0.6 m/s it settles,
    with no yaw moment, in a steady turn of 0.376 rad/s. So its spiral at 0.6 m/s keeps that turn
    to the side it came from at zero command (the loop), and at 0.15 m/s it has no loop."""
    from usv_mj import load_scenario
    from usv_mj.jobs.manoeuvres import spiral

    scenario = load_scenario(preset="paper")
    fast = spiral(scenario, plant_kind="analytic", approach_speed=0.6, steps=1, hold_s=30.0)["measures"]
    assert fast["hysteresis"] and fast["loop_commands"] == [0.0]
    assert fast["yaw_rate_at_zero"]["down"] == pytest.approx(0.376, abs=5e-4)
    assert fast["yaw_rate_at_zero"]["up"] == pytest.approx(-0.376, abs=5e-4)
    slow = spiral(scenario, plant_kind="analytic", approach_speed=0.15, max_yaw_moment=2.0, steps=1,
                  hold_s=40.0)["measures"]
    assert not slow["hysteresis"] and abs(slow["yaw_rate_at_zero"]["down"]) < 0.01


def test_a_rudder_beyond_the_twin_thrusters_is_said():
    """paper-limited's twin thrusters give at most 0.395 m x (119.7 + 66.7) N = 73.6 N m of yaw: a
    "rudder" of 100 N m is cut from the execute on (15 of the 20 s), one of 50 N m is not."""
    from usv_mj import load_scenario
    from usv_mj.jobs.manoeuvres import turning_circle

    limited = load_scenario(preset="paper-limited")
    cut = turning_circle(limited, plant_kind="analytic", duration=20.0, yaw_moment=100.0)["saturated_fraction"]
    assert cut["r"] == pytest.approx(0.75, abs=1e-3)
    held = turning_circle(limited, plant_kind="analytic", duration=20.0, yaw_moment=50.0)["saturated_fraction"]
    assert held == {"u": 0.0, "r": 0.0}


def test_the_api_names_a_wrong_argument():
    from usv_mj.core.errors import ArgumentTypeError
    from usv_mj.jobs.manoeuvres import run_manoeuvre, turning_circle, zigzag

    with pytest.raises(ArgumentTypeError, match=r"^turning_circle: scenario must be a Scenario .* got NoneType$"):
        turning_circle(None)
    with pytest.raises(ArgumentTypeError, match=r"^zigzag: unknown option 'yaw'; the options are approach_speed, "):
        zigzag("paper", yaw=3.0)
    with pytest.raises(ScenarioError, match=r"manoeuvre.angle_deg must be > 0"):
        zigzag("paper", angle_deg=-10.0)
    with pytest.raises(ArgumentTypeError, match=r"^run_manoeuvre: spec must be a ManoeuvreSpec"):
        run_manoeuvre("paper", "turning")
    with pytest.raises(ScenarioError, match=r"no \[manoeuvre\] to run"):
        run_manoeuvre("paper")
