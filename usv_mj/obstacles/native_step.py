"""The obstacle hook's step as a kernel of the compiled loop (:mod:`usv_mj.compiled_loop`, role "hook").

:class:`usv_mj.obstacles.hooks.ObstacleHook` hands one of these when its obstacles stand still and
no guidance re-times the reference (moving obstacles and guidance stay Python). A kernel measures
the clearance natively, exactly as the monitor's ``update`` does, and stores the row of the
:class:`~usv_mj.obstacles.sink.ObstacleLog` as ``record_step`` would, as long as the step is
uneventful. It answers True ("Python, please") and leaves the step to the Python hook, which
measures again (the same numbers: the state has not changed) and does the bookkeeping, when:

- a near miss starts (a clearance falls under the margin where it was not): its event;
- a contact episode is on (the log's contact flags), or could be: on the MuJoCo plant, when a
  clearance is under ``CONTACT_WATCH`` (contacts are read from ``d.contact`` in Python; MuJoCo
  makes one only below zero distance, and the hull moves a few mm a step), on the analytic plant
  when a clearance reaches zero (its "collision");
- the row is past the log's end.

So records, obstacle logs and events are bit for bit those of the Python loop (tests/test_compiled_loop.py).
Signature (usv_mj.kernels, hook): ``fn(k, t, x, *args) -> python``.
"""

from __future__ import annotations

from numba import njit

from .clearance import footprint_clearances, mujoco_clearance_kernel, scatter_clearances

#: [m] on the MuJoCo plant, a step whose least clearance is under this goes to Python (contacts)
CONTACT_WATCH = 0.05


@njit(cache=True)
def _store(k, clearance, log_clearance, near, margin, rows):
    """The uneventful rest of ``ObstacleLog.record_step``; True when Python must do the step."""
    m = clearance.shape[0]
    if k >= log_clearance.shape[0]:
        return True
    for i in range(m):
        if clearance[i] < margin and not near[i]:
            return True
    for i in range(m):
        log_clearance[k, i] = clearance[i]
        near[i] = clearance[i] < margin
    rows[0] = k + 1
    return False


@njit(cache=True)
def mujoco_obstacle_step(k, t, x, m_addr, d_addr, kinematics, geom_distance, hull, obstacles, bound, exact_within,
                         prefilter, distmax, qpos, geom_xpos, clearance, exact, witness, fromto, normal_force,
                         in_contact, min_only, order, log_clearance, near, contact, margin, watch, rows):
    """MuJoCoClearance.update (its kernel; the contacts only when Python does the step) and the log's row."""
    for i in range(contact.shape[0]):
        if contact[i]:
            return True
    mujoco_clearance_kernel(m_addr, d_addr, kinematics, geom_distance, hull, obstacles, bound, exact_within,
                            prefilter, distmax, qpos, geom_xpos, clearance, exact, witness, fromto, normal_force,
                            in_contact, min_only, order)
    for i in range(clearance.shape[0]):
        if not clearance[i] >= watch:
            return True
    return _store(k, clearance, log_clearance, near, margin, rows)


@njit(cache=True)
def geometric_obstacle_step(k, t, x, body, body_radius, centers, radius, boxes, box_radii, exact_within, out_c,
                            out_b, circles, box_index, clearance, in_contact, log_clearance, near, contact, margin,
                            rows):
    """GeometricClearance.update of standing obstacles (its numba kernel and scatter) and the log's row."""
    for i in range(contact.shape[0]):
        if contact[i]:
            return True
    footprint_clearances(body, body_radius, x[0], x[1], x[2], centers, radius, boxes, box_radii, exact_within,
                         out_c, out_b)
    if scatter_clearances(out_c, out_b, circles, box_index, clearance, in_contact):
        return True
    return _store(k, clearance, log_clearance, near, margin, rows)
