"""Signed distances between the hull's footprint and the obstacles' sections, natively.

The geometry of :class:`usv_mj.obstacles.clearance.GeometricClearance` (the analytic plant's
clearance) and of the compiled loop's obstacle hook (usv_mj.obstacles.native_step): a convex
polygon (the hull's collision footprint at the plant's pose) against circles (the distance to the
centre minus the radius, exactly) and boxes (the separating-axis distance of two convex polygons;
overlapping: minus the deepest vertex's depth). ``footprint_clearances`` measures every obstacle
within ``exact_within`` of a bounding-circle test and gives the others that bound;
``footprint_clearances_broad`` measures only the broad phase's candidates (usv_mj.obstacles.broad_phase).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from usv_mj.obstacles.broad_phase import grid_candidates


@njit(cache=True)
def _point_segment_distance(px, py, ax, ay, bx, by):
    dx, dy = bx - ax, by - ay
    den = dx * dx + dy * dy
    w = ((px - ax) * dx + (py - ay) * dy) / den if den > 0.0 else 0.0
    if w < 0.0:
        w = 0.0
    elif w > 1.0:
        w = 1.0
    qx, qy = ax + w * dx - px, ay + w * dy - py
    return math.sqrt(qx * qx + qy * qy)


@njit(cache=True)
def point_polygon_signed_distance(poly, px, py):
    """Signed distance [m] from (px, py) to the convex counter-clockwise polygon ``poly`` (n, 2),
    negative inside."""
    n = poly.shape[0]
    best = math.inf
    inside = True
    for i in range(n):
        j = (i + 1) % n
        ax, ay, bx, by = poly[i, 0], poly[i, 1], poly[j, 0], poly[j, 1]
        if (bx - ax) * (py - ay) - (by - ay) * (px - ax) < 0.0:
            inside = False
        d = _point_segment_distance(px, py, ax, ay, bx, by)
        if d < best:
            best = d
    return -best if inside else best


@njit(cache=True)
def _axis_overlap(a, b, nx, ny):
    amin, amax, bmin, bmax = math.inf, -math.inf, math.inf, -math.inf
    for i in range(a.shape[0]):
        p = a[i, 0] * nx + a[i, 1] * ny
        amin, amax = min(amin, p), max(amax, p)
    for i in range(b.shape[0]):
        p = b[i, 0] * nx + b[i, 1] * ny
        bmin, bmax = min(bmin, p), max(bmax, p)
    return min(amax - bmin, bmax - amin)


@njit(cache=True)
def convex_signed_distance(a, b):
    """Signed distance [m] between two convex counter-clockwise polygons (n, 2) and (m, 2):
    separated, the exact distance (min over vertex-edge pairs); overlapping, minus the
    penetration depth (the smallest overlap over the edge normals: separating-axis theorem)."""
    min_overlap = math.inf
    for poly in (a, b):
        n = poly.shape[0]
        for i in range(n):
            j = (i + 1) % n
            ex, ey = poly[j, 0] - poly[i, 0], poly[j, 1] - poly[i, 1]
            norm = math.sqrt(ex * ex + ey * ey)
            if norm == 0.0:
                continue
            ov = _axis_overlap(a, b, -ey / norm, ex / norm)
            if ov < min_overlap:
                min_overlap = ov
    if min_overlap <= 0.0:
        best = math.inf
        for p, q in ((a, b), (b, a)):
            m = q.shape[0]
            for i in range(p.shape[0]):
                for j in range(m):
                    k = (j + 1) % m
                    d = _point_segment_distance(p[i, 0], p[i, 1], q[j, 0], q[j, 1], q[k, 0], q[k, 1])
                    if d < best:
                        best = d
        return best
    return -min_overlap


@njit(cache=True)
def scatter_clearances(out_circles, out_boxes, circles, boxes, clearance, in_contact):
    """The circles' and boxes' clearances into the obstacles' order; in_contact = clearance <= 0.
    Returns whether any obstacle is reached (GeometricClearance.update and the loop's hook kernel)."""
    for j in range(circles.shape[0]):
        clearance[circles[j]] = out_circles[j]
    for j in range(boxes.shape[0]):
        clearance[boxes[j]] = out_boxes[j]
    hit = False
    for i in range(clearance.shape[0]):
        in_contact[i] = clearance[i] <= 0.0
        hit = hit or in_contact[i]
    return hit


@njit(cache=True)
def footprint_clearances(body, body_radius, x, y, psi, centers, radii, boxes, box_radii, exact_within,
                         out_circles, out_boxes):
    """Clearance of the hull footprint ``body`` (convex, CCW, body frame, within ``body_radius`` of
    its origin) at pose (x, y, psi) to circles (centres (k, 2), radii (k,)) and boxes (corners
    (m, 4, 2), CCW, half-diagonals ``box_radii``) [m]. Obstacles whose bounding-circle lower bound
    exceeds ``exact_within`` get that lower bound instead of the exact distance."""
    c, s = math.cos(psi), math.sin(psi)
    n = body.shape[0]
    hull = np.empty((n, 2))
    for i in range(n):
        hull[i, 0] = x + c * body[i, 0] - s * body[i, 1]
        hull[i, 1] = y + s * body[i, 0] + c * body[i, 1]
    for i in range(centers.shape[0]):
        lower = math.hypot(centers[i, 0] - x, centers[i, 1] - y) - body_radius - radii[i]
        if lower > exact_within:
            out_circles[i] = lower
        else:
            out_circles[i] = point_polygon_signed_distance(hull, centers[i, 0], centers[i, 1]) - radii[i]
    for i in range(boxes.shape[0]):
        bx = 0.25 * (boxes[i, 0, 0] + boxes[i, 1, 0] + boxes[i, 2, 0] + boxes[i, 3, 0])
        by = 0.25 * (boxes[i, 0, 1] + boxes[i, 1, 1] + boxes[i, 2, 1] + boxes[i, 3, 1])
        lower = math.hypot(bx - x, by - y) - body_radius - box_radii[i]
        if lower > exact_within:
            out_boxes[i] = lower
        else:
            out_boxes[i] = convex_signed_distance(hull, boxes[i])



@njit(cache=True)
def footprint_clearances_broad(body, body_radius, x, y, psi, centers, radii, boxes, box_radii, exact_within, kind,
                               slot, grid_geometry, grid_shape, grid_start, grid_items, moving, seen, stamp, scratch,
                               active, n_active, clearance, in_contact):
    """:func:`footprint_clearances` and :func:`scatter_clearances` with the broad phase (module
    docstring): the candidates of the grid and the ``moving`` obstacles (obstacle i is circle
    ``slot[i]`` when ``kind[i]`` is 0, box ``slot[i]`` otherwise) get the same bound test and the same
    distance; the last update's entries (``active``) become NaN first. Returns whether any
    obstacle is reached (clearance <= 0)."""
    for j in range(n_active[0]):
        i = active[j]
        clearance[i] = np.nan
        in_contact[i] = False
    count = grid_candidates(grid_geometry, grid_shape, grid_start, grid_items, x, y, seen, stamp, scratch)
    for j in range(moving.shape[0]):
        scratch[count] = moving[j]
        count += 1
    if count == 0:
        n_active[0] = 0
        return False
    c, s = math.cos(psi), math.sin(psi)
    n = body.shape[0]
    hull = np.empty((n, 2))
    for i in range(n):
        hull[i, 0] = x + c * body[i, 0] - s * body[i, 1]
        hull[i, 1] = y + s * body[i, 0] + c * body[i, 1]
    na = 0
    hit = False
    for j in range(count):
        i = scratch[j]
        q = slot[i]
        if kind[i] == 0:
            lower = math.hypot(centers[q, 0] - x, centers[q, 1] - y) - body_radius - radii[q]
            if lower > exact_within:
                continue
            value = point_polygon_signed_distance(hull, centers[q, 0], centers[q, 1]) - radii[q]
        else:
            bx = 0.25 * (boxes[q, 0, 0] + boxes[q, 1, 0] + boxes[q, 2, 0] + boxes[q, 3, 0])
            by = 0.25 * (boxes[q, 0, 1] + boxes[q, 1, 1] + boxes[q, 2, 1] + boxes[q, 3, 1])
            lower = math.hypot(bx - x, by - y) - body_radius - box_radii[q]
            if lower > exact_within:
                continue
            value = convex_signed_distance(hull, boxes[q])
        clearance[i] = value
        in_contact[i] = value <= 0.0
        hit = hit or in_contact[i]
        active[na] = i
        na += 1
    n_active[0] = na
    return hit
