"""The obstacle hook's step as a kernel of the compiled loop (:mod:`usv_mj.loop.compiled`, role "hook").

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
- the row is outside the log's window (past its end; a streamed log slides its window then).

So records, obstacle logs and events are bit for bit those of the Python loop (tests/test_compiled_loop.py).
Signature (usv_mj.core.kernels, hook): ``fn(k, t, x, *args) -> python``.
"""

from __future__ import annotations

from numba import njit

from usv_mj.obstacles.clearance import mujoco_clearance_kernel
from usv_mj.obstacles.footprint_kernels import footprint_clearances, footprint_clearances_broad, scatter_clearances

#: [m] on the MuJoCo plant, a step whose least clearance is under this goes to Python (contacts)
CONTACT_WATCH = 0.05


@njit(cache=True)
def _store(k, clearance, log_clearance, base, near, margin, rows):
    """The uneventful rest of ``ObstacleLog.record_step``; True when Python must do the step (a
    near miss starts, or row k is outside the log's window: rows base[0] ..)."""
    m = clearance.shape[0]
    j = k - base[0]
    if j < 0 or j >= log_clearance.shape[0]:
        return True
    for i in range(m):
        if clearance[i] < margin and not near[i]:
            return True
    for i in range(m):
        log_clearance[j, i] = clearance[i]
        near[i] = clearance[i] < margin
    rows[0] = k + 1
    return False


@njit(cache=True)
def mujoco_obstacle_step(k, t, x, m_addr, d_addr, kinematics, geom_distance, hull, obstacles, bound, exact_within,
                         prefilter, distmax, qpos, geom_xpos, clearance, exact, witness, fromto, normal_force,
                         in_contact, min_only, order, broad, grid_geometry, grid_shape, grid_start, grid_items, moving,
                         seen, stamp, active, n_active, touched, n_touched, log_clearance, base, near, contact, margin,
                         watch, rows):
    """MuJoCoClearance.update (its kernel; the contacts only when Python does the step) and the log's row."""
    for i in range(contact.shape[0]):
        if contact[i]:
            return True
    mujoco_clearance_kernel(m_addr, d_addr, kinematics, geom_distance, hull, obstacles, bound, exact_within,
                            prefilter, distmax, qpos, geom_xpos, clearance, exact, witness, fromto, normal_force,
                            in_contact, min_only, order, broad, grid_geometry, grid_shape, grid_start, grid_items,
                            moving, seen, stamp, active, n_active, touched, n_touched)
    if broad:   # the others are NaN: beyond reach
        for j in range(n_active[0]):
            if not clearance[active[j]] >= watch:
                return True
    else:
        for i in range(clearance.shape[0]):
            if not clearance[i] >= watch:
                return True
    return _store(k, clearance, log_clearance, base, near, margin, rows)


@njit(cache=True)
def geometric_obstacle_step(k, t, x, body, body_radius, centers, radius, boxes, box_radii, exact_within, out_c,
                            out_b, circles, box_index, clearance, in_contact, broad, kind, slot, grid_geometry,
                            grid_shape, grid_start, grid_items, moving, seen, stamp, scratch, active, n_active,
                            log_clearance, base, near, contact, margin, rows):
    """GeometricClearance.update of standing obstacles (its numba kernel and scatter, or the broad
    phase's kernel) and the log's row."""
    for i in range(contact.shape[0]):
        if contact[i]:
            return True
    if broad:
        hit = footprint_clearances_broad(body, body_radius, x[0], x[1], x[2], centers, radius, boxes, box_radii,
                                         exact_within, kind, slot, grid_geometry, grid_shape, grid_start, grid_items,
                                         moving, seen, stamp, scratch, active, n_active, clearance, in_contact)
    else:
        footprint_clearances(body, body_radius, x[0], x[1], x[2], centers, radius, boxes, box_radii, exact_within,
                             out_c, out_b)
        hit = scatter_clearances(out_c, out_b, circles, box_index, clearance, in_contact)
    if hit:
        return True
    return _store(k, clearance, log_clearance, base, near, margin, rows)
