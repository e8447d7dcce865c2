"""Directions as marine users write them (docs/sea.md, "Directions"): wind and waves by where they
come FROM, the current by where it sets TOWARD, compass degrees clockwise from north (+y).

The expected numbers are physical statements, not the conversion formula: a wind from the north
pushes the hull south (-y), a current toward the east carries an unpowered hull along +x, waves from
the west travel toward +x; and the deprecated ``direction_deg`` (going-to, counter-clockwise from +x)
builds the same Environment as the new key.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from usv_mj.scenario.spec import ScenarioError, load_scenario
from usv_mj.physics.sea import Environment, SeaSettings, SeaSettingsError, sea_rk4_advance
from usv_mj.physics.sea.settings import compass_deg, going_to_deg
from usv_mj.physics.ship import PaperDisturbance, ShipParams
from usv_mj.jobs.sweep.spec import apply_values

BARE = ShipParams(uncertainty_scale=0.0).as_array()   # the hull alone: no Delta
NO_DIST = PaperDisturbance(scale=0.0).as_array()       # and no d(t)


def _env(table, **kwargs):
    return Environment(SeaSettings.from_table(table, "test"), **kwargs)


# --- the conversion, by the compass rose ----------------------------------------------------------


@pytest.mark.parametrize("compass, sense, expected", [
    (0.0, "from", 270.0),     # from north: toward -y
    (90.0, "from", 180.0),    # from east: toward -x
    (180.0, "from", 90.0),    # from south: toward +y
    (270.0, "from", 0.0),     # from west: toward +x
    (0.0, "toward", 90.0),    # toward north: +y
    (90.0, "toward", 0.0),    # toward east: +x
    (225.0, "toward", 225.0),  # toward south-west: (-1, -1) / sqrt 2
])
def test_compass_directions_map_to_the_world_axes(compass, sense, expected):
    got = going_to_deg(compass, sense)
    assert math.isclose(got, expected, abs_tol=1e-12)
    assert math.isclose(compass_deg(got, sense) % 360.0, compass % 360.0, abs_tol=1e-12)


# --- wind from north pushes south ---------------------------------------------------------------


@pytest.mark.parametrize("psi", [0.0, math.pi / 2, 0.7])
def test_wind_from_north_pushes_the_hull_toward_minus_y(psi):
    env = _env({"wind": {"speed": 5.0, "from_deg": 0.0}})
    tau = env.loads(1.0, [0.0, 0.0, psi], [0.0, 0.0, 0.0]).tau_wind
    c, s = math.cos(psi), math.sin(psi)
    fx, fy = c * tau[0] - s * tau[1], s * tau[0] + c * tau[1]   # body force in world axes
    assert fy < 0.0
    if psi == 0.0:  # beam wind on the port side: SEA check 11's 8.27 N, pushing to starboard (-y)
        assert abs(fy + 8.27) < 0.01 * 8.27 and abs(fx) < 1e-9 and abs(tau[2]) < 1e-9


def test_unpowered_hull_drifts_south_in_a_north_wind():
    env = _env({"wind": {"speed": 10.0, "from_deg": 0.0}}, t_max=40.0)
    ep, waves, cg, wg = env.packed
    x = sea_rk4_advance(BARE, NO_DIST, ep, waves, cg, wg, 0.0, np.zeros(6), 0.0, 0.0, 0.01, 3000)
    assert x[1] < -1.0                      # well south of the start after 30 s
    assert abs(x[0]) < 0.2 * abs(x[1])      # mostly south (the hull yaws a little: sway-yaw coupling)


# --- current toward east carries the hull along +x ----------------------------------------------


def test_current_toward_east_carries_an_unpowered_hull_along_plus_x():
    env = _env({"current": {"speed": 0.3, "toward_deg": 90.0}}, t_max=200.0)
    ep, waves, cg, wg = env.packed
    x = sea_rk4_advance(BARE, NO_DIST, ep, waves, cg, wg, 0.0, np.zeros(6), 0.0, 0.0, 0.01, 15_000)
    # from rest the hull is dragged up to the current speed: after 150 s it moves at 0.3 m/s east
    nu = x[3:]
    c, s = math.cos(x[2]), math.sin(x[2])
    velocity = np.array([c * nu[0] - s * nu[1], s * nu[0] + c * nu[1]])
    assert np.allclose(velocity, [0.3, 0.0], atol=1e-3)
    assert x[0] > 30.0 and abs(x[1]) < 1e-9


# --- waves from the west travel toward +x -------------------------------------------------------


def test_waves_from_west_travel_toward_plus_x():
    """One long-crested component, zeta = a cos(w t - k x + e): the crests move at the phase speed
    c = -zeta_t / zeta_x, which must be +g / w (deep water, toward +x), with w from zeta_tt = -w^2 zeta;
    and nothing changes along y."""
    env = _env({"waves": {"hs": 0.2, "tp": 2.0, "from_deg": 270.0, "spreading": False, "components": 1}},
               ramp_time=0.0)
    h, g = 1e-3, 9.81
    for x0, t0 in ((0.3, 5.0), (-2.0, 11.1), (4.0, 17.3)):
        z = env.elevation(x0, 0.0, t0)
        if abs(z) < 0.02:
            continue
        z_t = (env.elevation(x0, 0.0, t0 + h) - env.elevation(x0, 0.0, t0 - h)) / (2 * h)
        z_tt = (env.elevation(x0, 0.0, t0 + h) - 2 * z + env.elevation(x0, 0.0, t0 - h)) / h**2
        z_x = (env.elevation(x0 + h, 0.0, t0) - env.elevation(x0 - h, 0.0, t0)) / (2 * h)
        w = math.sqrt(-z_tt / z)
        assert math.isclose(-z_t / z_x, g / w, rel_tol=1e-3)
        assert abs(env.elevation(x0, 7.0, t0) - z) < 1e-9


# --- the deprecated alias -------------------------------------------------------------------------


OLD = {"waves": {"hs": 0.2, "tp": 2.0, "direction_deg": 0.0},
       "current": {"speed": 0.3, "direction_deg": 30.0, "sigma": 0.05},
       "wind": {"speed": 5.0, "direction_deg": 90.0, "gust_sigma": 1.0}}
NEW = {"waves": {"hs": 0.2, "tp": 2.0, "from_deg": 270.0},
       "current": {"speed": 0.3, "toward_deg": 60.0, "sigma": 0.05},
       "wind": {"speed": 5.0, "from_deg": 180.0, "gust_sigma": 1.0}}


def test_deprecated_direction_deg_builds_the_same_environment():
    old, new = SeaSettings.from_table(OLD), SeaSettings.from_table(NEW)
    assert old == new
    e_old, e_new = Environment(old, t_max=50.0), Environment(new, t_max=50.0)
    for t, eta, nu in ((3.0, [1.0, -2.0, 0.4], [0.5, 0.1, -0.2]), (40.0, [-5.0, 3.0, 2.0], [0.0, 0.0, 0.0])):
        a, b = e_old.loads(t, eta, nu), e_new.loads(t, eta, nu)
        for name in a._fields:
            assert np.array_equal(getattr(a, name), getattr(b, name))
        assert e_old.elevation(eta[0], eta[1], t) == e_new.elevation(eta[0], eta[1], t)
    assert (new.waves.from_deg, new.current.toward_deg, new.wind.from_deg) == (270.0, 60.0, 180.0)


@pytest.mark.parametrize("section, key", [("waves", "from_deg"), ("current", "toward_deg"), ("wind", "from_deg")])
def test_a_table_with_both_spellings_is_refused(section, key):
    table = copy.deepcopy(NEW)
    table[section]["direction_deg"] = 10.0
    with pytest.raises(SeaSettingsError, match=rf"sea\.{section}\] gives both {key}"):
        SeaSettings.from_table(table)
    with pytest.raises(ScenarioError, match="gives both"):
        load_scenario(overrides={"sea": table})


def test_a_scenario_direction_replaces_the_sea_preset_direction_in_either_spelling():
    # breeze writes from_deg = 180; an old scenario file writes direction_deg over it, a new one from_deg
    old = load_scenario(overrides={"sea": {"preset": "breeze", "wind": {"direction_deg": 45.0}}})
    assert old.sea.wind.direction_deg == 45.0
    new = load_scenario(overrides={"sea": {"preset": "breeze", "wind": {"from_deg": 0.0}}})
    assert new.sea.wind.direction_deg == 270.0
    assert load_scenario(overrides={"sea": {"preset": "breeze"}}).sea.wind.direction_deg == 90.0


def test_a_sweep_path_replaces_the_base_direction_in_either_spelling():
    base = load_scenario(overrides={"sea": {"current": {"speed": 0.3, "toward_deg": 60.0}}})
    run = apply_values(base, {"sea.current.direction_deg": 0.0}, "sweep.toml")
    assert run.sea.current.direction_deg == 0.0
    old = load_scenario(overrides={"sea": {"current": {"speed": 0.3, "direction_deg": 30.0}}})
    run = apply_values(old, {"sea.current.toward_deg": 180.0}, "sweep.toml")
    assert run.sea.current.direction_deg == 270.0 and run.sea.current.toward_deg == 180.0


def test_presets_keep_their_old_directions():
    from usv_mj.physics.sea import load_sea_preset

    assert load_sea_preset("moderate").waves.direction_deg == 0.0       # toward +x, as before
    assert load_sea_preset("breeze").wind.direction_deg == 90.0         # toward +y
    assert load_sea_preset("steady-current").current.direction_deg == 30.0
    assert load_sea_preset("varying-current").current.direction_deg == 30.0
