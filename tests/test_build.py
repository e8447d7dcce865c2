"""One build for every run: registration of a user's controller, and the composition matrix.

References are independent of the code under test: a run in a sea must differ from the same run in
calm water (the sea pushes the hull), the summary's clearance must be the minimum of the per-step
clearances that the plant's own monitor measured, and the environment the outputs use must be the
very object the plant integrated.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from usv_mj import CONTROLLERS, build, load_scenario, simulate, summarize
from usv_mj.core.errors import ScenarioError, UnknownKindError

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "examples" / "scenarios"


# --- a controller defined here, registered here, run end to end through the public API ------------


@dataclasses.dataclass(frozen=True)
class LineGains:
    """Gains of a toy heading-and-speed law (defined in this test file only)."""

    k_u: float = 150.0   # N s/m
    k_psi: float = 60.0  # N m/rad
    k_r: float = 40.0    # N m s/rad

    def __post_init__(self):
        for f in dataclasses.fields(self):
            if not getattr(self, f.name) > 0:
                raise ValueError(f"controller.{f.name} must be > 0, got {getattr(self, f.name)!r}")


@CONTROLLERS.register("toy", gains=LineGains)
class ToyController:
    """tau_u = k_u (u_d - u), tau_r = -k_psi wrap(psi - psi_d) - k_r (r - r_d); no funnel."""

    name = "toy"
    diagnostic_fields = ("heading_error", "speed_error")

    def __init__(self, gains: LineGains):
        self.g = gains
        self.diag = np.zeros(2)

    @classmethod
    def from_scenario(cls, gains, scenario):
        return cls(gains)

    def reset(self):
        self.diag[:] = 0.0

    def __call__(self, t, x, ref):
        e_psi = math.remainder(x[2] - ref[2], 2 * math.pi)
        e_u = ref[6] - x[3]
        self.diag[0], self.diag[1] = e_psi, e_u
        return self.g.k_u * e_u, -self.g.k_psi * e_psi - self.g.k_r * (x[5] - ref[5]), self.diag


def test_a_registered_controller_runs_end_to_end(tmp_path):
    from usv_mj.jobs.run import run_job
    from usv_mj.outputs.log import read_run

    sc = load_scenario(preset="paper", overrides={
        "duration": 25.0, "plant": {"kind": "analytic"}, "controller": {"kind": "toy", "k_u": 120.0},
        "trajectory": {"kind": "line", "heading_deg": 0.0}, "initial": {"eta": [0.0, 0.0, 0.3]},
        "disturbance": {"scale": 0.0}})  # no d(t): the toy loop has no integral action to reject it
    assert isinstance(sc.controller.gains, LineGains) and sc.controller.gains.k_u == 120.0
    result = run_job(sc, tmp_path / "toy", video=False, progress=False, step_check=False)
    rec = result.record
    assert rec.status == "completed"
    assert rec.diagnostic_fields == ("heading_error", "speed_error") and not rec.has_funnel
    # the toy law converges: the heading error of a damped second-order loop decays from 0.3 rad
    assert abs(rec["heading_error"][0] - 0.3) < 1e-12 and abs(rec["heading_error"][-1]) < 0.01
    assert result.summary["controller"] == "toy" and "funnel_violations" not in result.summary
    assert result.summary["criterion"]["kind"] == "pose_tolerance"  # the default of a law without a funnel
    assert result.summary["s2_clamps"] is None
    figures = sorted(p.name for p in (tmp_path / "toy" / "figures").glob("*.png"))
    assert len(figures) == 7
    log = read_run(tmp_path / "toy" / "run.mcap")
    back = log.runs["main"]
    assert back.diagnostic_fields == rec.diagnostic_fields
    assert np.array_equal(back["heading_error"], rec["heading_error"])


def test_gains_are_validated_against_the_chosen_controller():
    with pytest.raises(ScenarioError, match=r"controller\.k_u.*did you mean|unknown key 'controller\.ku'"):
        load_scenario(preset="paper", overrides={"controller": {"kind": "toy", "ku": 1.0}})
    with pytest.raises(ScenarioError, match="k_psi must be > 0"):
        load_scenario(preset="paper", overrides={"controller": {"kind": "toy", "k_psi": -1.0}})
    # the PPC keys are not the toy's: the error lists the toy's own keys
    with pytest.raises(ScenarioError, match="k_psi, k_r, k_u"):
        load_scenario(preset="paper", overrides={"controller": {"kind": "toy", "k1": 1.0}})
    with pytest.raises(UnknownKindError, match="did you mean 'ppc'"):
        load_scenario(preset="paper", overrides={"controller": {"kind": "ppx"}})
    with pytest.raises(ScenarioError, match=r"\[baseline\] must be a table"):
        load_scenario(preset="paper", overrides={"baseline": 5})


# --- the composition matrix -----------------------------------------------------------------------

OBSTACLES = {"none": None, "static": "harbour_gap.toml", "moving": "crossing_boat.toml"}
SEA = {"sea": {"preset": "moderate", "current": {"speed": 0.3}}}


def _scenario(obstacles: str, sea: bool, duration: float = 3.0):
    over = {"duration": duration, "baseline": {"enabled": False}}
    if sea:
        over.update(SEA)
    name = OBSTACLES[obstacles]
    if name is None:
        return load_scenario(preset="paper", overrides=over)
    return load_scenario(SCENARIOS / name, overrides=over)


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
@pytest.mark.parametrize("obstacles", list(OBSTACLES))
@pytest.mark.parametrize("controller", ["ppc", "pi"])
def test_every_feature_composes_with_every_other(plant, obstacles, controller):
    from usv_mj.outputs.sea_figures import sea_summary

    calm, sea = _scenario(obstacles, False), _scenario(obstacles, True)
    runs = {}
    for label, sc in (("calm", calm), ("sea", sea)):
        parts = build(sc, plant_kind=plant, controller_kind=controller)
        env = parts.statics.environment
        assert (env is None) == (label == "calm")
        if env is not None:  # the outputs' sea is the one the plant integrates, not a rebuilt one
            assert parts.plant.environment is env
        assert (parts.hooks != ()) == (obstacles != "none")
        rec = simulate(parts)
        assert rec.status == "completed" or rec.stop_reason, rec.status
        assert rec.statics is parts.statics
        s = summarize(rec)
        if obstacles != "none":
            log = rec.statics.obstacle_log
            assert s["min_clearance_m"] == pytest.approx(float(np.min(log.clearance[: rec.n_rows])), abs=1e-12)
        if env is not None:
            hs = sea_summary(rec, env)["hs_at_hull_m"]
            assert 0.05 < hs < 0.6  # the moderate preset's Hs 0.2 m, seen at the moving hull
        runs[label] = rec
    n = min(len(runs["calm"]), len(runs["sea"]))
    dx = np.max(np.abs(runs["sea"]["x"][:n] - runs["calm"]["x"][:n]) + np.abs(runs["sea"]["y"][:n] - runs["calm"]["y"][:n]))
    assert dx > 1e-3, f"the sea did not move the hull ({dx:.2e} m)"


def test_compare_a_harbour_in_a_sea(tmp_path):
    """usv-mj compare of a harbour in a sea: the closed loop with the obstacles and the sea on both
    plants (the open-loop thrust sequence runs in open water: it would ram the piers); every check ok."""
    import json

    from usv_mj.cli.main import main

    out = tmp_path / "cmp"
    assert main(["compare", "--scenario", str(SCENARIOS / "harbour_gap.toml"), "--sea", "moderate",
                 "--duration", "4", "-q", "--out", str(out)]) == 0
    result = json.loads((out / "compare.json").read_text())
    assert all(result["checks"].values()) and result["closed_loop"]["max_position_m"] < 1e-3


def test_sweep_of_the_current_in_a_harbour(tmp_path):
    from usv_mj.jobs.sweep import load_sweep
    from usv_mj.jobs.sweep.runner import run_sweep

    path = tmp_path / "harbour_current.toml"
    path.write_text(f"""
base = "{(SCENARIOS / 'harbour_gap.toml').as_posix()}"
duration = 3.0
plant = "analytic"
transient = 1.0
[vary]
"sea.current.speed" = [0.0, 0.4]
""")
    result = run_sweep(load_sweep(path), tmp_path / "out", workers=1, progress=False, echo=None, report=False)
    rows = sorted(result.rows, key=lambda r: r["vary.sea.current.speed"])
    assert [r["status"] for r in rows] == ["ok", "ok"]
    assert rows[0]["min_clearance_m"] is not None
    key = "max_abs_error_after_transient.y"
    assert rows[0][key] != rows[1][key]  # the current pushed the hull: the runs saw the sea


@pytest.mark.parametrize("obstacles", ["none", "static"])
def test_saturated_actuators_compose_with_the_sea_obstacles_and_both_plants(obstacles):
    """The matrix's saturated case: paper-limited's twin thrusters in a sea (and a harbour): both
    plants receive the same saturated forces, every applied force is inside the thrusters' box."""
    limited = {"actuators": load_scenario(preset="paper-limited").to_dict()["actuators"]}
    sc = _scenario(obstacles, True, duration=3.0).with_overrides(limited)
    lo_u, hi_u, lo_r, hi_r = sc.actuators.generalized_limits()
    recs = {k: simulate(sc, plant_kind=k) for k in ("analytic", "mujoco")}
    for rec in recs.values():
        assert rec.status == "completed"
        assert np.all(rec["f_u"] <= hi_u + 1e-9) and np.all(rec["f_u"] >= lo_u - 1e-9)
        assert np.all(np.abs(rec["f_r"]) <= hi_r + 1e-9)
        assert np.mean(rec["sat_u"] + rec["sat_r"] > 0) > 0.0  # the start saturates the thrusters
    a, m = recs["analytic"], recs["mujoco"]
    assert np.array_equal(a["sat_u"], m["sat_u"]) and np.array_equal(a["sat_r"], m["sat_r"])
    assert np.max(np.abs(a["x"] - m["x"]) + np.abs(a["y"] - m["y"])) < 1e-6
