"""The README's Conventions: the paper's NED-style ship is the same ship in our ENU/FLU frame.

The mirror S = diag(1, -1, -1) on (u, v, r) (and on the loads (X, Y, N)) leaves M, C(nu) and D(nu)
of usv_mj/physics/ship.py unchanged, m23 and the |v|, |r| damping terms included; the uncertainty Delta is
not mirror-symmetric (its even sway and yaw terms flip), which the README states.
"""

from __future__ import annotations

import numpy as np

from usv_mj.physics.ship import ShipParams, coriolis_matrix, damping_matrix, kinematics, mass_matrix, uncertainty_force

S = np.diag([1.0, -1.0, -1.0])
P = ShipParams().as_array()


def test_mirror_leaves_mass_coriolis_and_damping_unchanged():
    assert np.array_equal(S @ mass_matrix(P) @ S, mass_matrix(P))
    rng = np.random.default_rng(3)
    for nu in rng.normal(scale=1.5, size=(50, 3)):
        assert np.allclose(S @ coriolis_matrix(P, S @ nu) @ S, coriolis_matrix(P, nu), rtol=0, atol=1e-12)
        assert np.allclose(S @ damping_matrix(P, S @ nu) @ S, damping_matrix(P, nu), rtol=0, atol=1e-12)


def test_mirror_leaves_the_kinematics_unchanged():
    rng = np.random.default_rng(4)
    for eta, nu in zip(rng.normal(size=(20, 3)), rng.normal(size=(20, 3))):
        # (x, y, psi) -> (x, -y, -psi) is the same S on the pose
        assert np.allclose(S @ kinematics(S @ eta, S @ nu), kinematics(eta, nu), atol=1e-12)


def test_mirror_flips_the_even_sway_and_yaw_terms_of_delta():
    eta, nu = np.zeros(3), np.array([0.6, 0.0, 0.2])   # v = 0: only the even terms 0.2 u^2, 0.15 r^2
    d, d_mirror = uncertainty_force(P, eta, nu), S @ uncertainty_force(P, eta, S @ nu)
    assert d[0] == d_mirror[0]
    assert np.allclose(d_mirror[1:], -d[1:]) and np.all(d[1:] > 0)


def test_a_current_toward_north_moves_the_hull_north_in_the_record_the_log_and_foxglove(tmp_path, drift_scenario):
    """The convention by eye: an unpowered hull in a current setting toward the chart's north
    (compass 0 deg) drifts along +y (north) in the record, in the log's /usv/state and in Foxglove's
    map -> base_link transform; x does not change."""
    from usv_mj import simulate
    from usv_mj.outputs.log import RunLogWriter
    from usv_mj.outputs.log.reader import load_topic

    sc = drift_scenario(20.0, 0.5, 0.0)
    path = tmp_path / "north.mcap"
    with RunLogWriter(path, sc) as writer:
        rec = simulate(sc, sinks=[writer.sink("main")])
    assert rec.status == "completed"
    assert rec["y"][-1] > 2.0 and abs(rec["x"][-1]) < 0.05 * rec["y"][-1]   # north is +y
    state = load_topic(path, "/usv/state")
    assert state["y"][-1] == rec["y"][-1] and state["x"][-1] == rec["x"][-1]
    tf = load_topic(path, "/usv/tf/hull")
    assert tf["parent_frame_id"][0] == "map" and tf["child_frame_id"][0] == "base_link"
    assert tf["translation.y"][-1] > 2.0 and abs(tf["translation.x"][-1]) < 0.1
