"""From a finished :class:`~usv_mj.record.run_record.RunRecord` to the list of frames of a video (no GL, no mujoco).

Time mapping: a run of duration T [s] played ``speedup`` times faster at ``fps`` frames per second
gives N = round(T fps / speedup) frames; frame j shows the record row nearest to
t_j = t_0 + T j / (N - 1), so the first frame is the start and the last frame the end of the run
(the played speed-up is T fps / (N - 1), within 1/N of the requested one). The default speed-up is
max(1, T / 30 s): a 300 s run becomes a 30 s video, a run shorter than 30 s plays in real time.

Per frame the planner gathers (all in world metres / radians): the hull pose (x, y, psi), the
reference pose (x_d, y_d, psi_d), the funnel box (centre at the Do & Pan reference point, half-widths
rho1, rho2, "ok" while |z1| < 1 and |z2| < 1), the wake trail (hull positions over the last
``trail_s`` seconds), the path ahead ((x_d, y_d) over the next ``ahead_s`` seconds), the top camera's
view (:class:`TopView`) and the values of the heads-up overlay.

Only rows whose state (x, y, psi) is finite are played: a diverged run ends at its last finite row.

What is read: only the rows drawn (:func:`frame_rows`): every column at the frame rows, (x, y) at
the trail's samples and (x_d, y_d) at the path's, found by a search that reads a few values of
``t`` per sample (:func:`search_rows`), never whole columns, so the video of a ten-hour run stored
on disk (:meth:`usv_mj.record.run_record.RunRecord.take`) costs what its frames cost. The Do & Pan offset and
the control bars' scale are fitted over the frame rows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from usv_mj.physics.channels import RunChannels

#: Colours (RGBA, 0..1) of the 3-D layers, shared with the overlay's legend.
TRAIL_RGBA = (1.0, 1.0, 1.0, 0.85)
PATH_RGBA = (1.0, 0.84, 0.10, 0.95)
GHOST_RGBA = (0.35, 0.95, 1.0, 0.38)
FUNNEL_OK_RGBA = (0.25, 0.95, 0.45, 0.95)
FUNNEL_BAD_RGBA = (1.0, 0.25, 0.2, 0.95)
FUNNEL_FILL_ALPHA = 0.12
#: an obstacle's inflated safety boundary: magenta, apart from the path's yellow (they shared it: issue 34)
SAFETY_LINE_RGBA = (1.0, 0.3, 0.85, 0.9)

#: What can be drawn: 3-D layers, then the 2-D overlay ("hud" panel, "legend").
LAYERS = ("trail", "path", "ghost", "funnel", "hud", "legend")

#: The part of the image the top camera keeps the ship, the reference and the funnel in, as
#: fractions of (width, height): right of the overlay panel, which takes the top-left corner.
CONTENT_X = (0.40, 0.97)
CONTENT_Y = (0.05, 0.95)
MIN_HALF_HEIGHT = 6.0   # m of water above and below the centre at the closest zoom (a 2 m boat = 1/6 of the height)


@dataclass
class TopView:
    """The top-down free camera: look at (cx, cy) [m] on the water and see +-half_height [m] vertically."""

    cx: float
    cy: float
    half_height: float


@dataclass
class FrameSpec:
    """Everything one frame needs (built by the planner in the parent process, drawn by a worker).

    Positions are world metres, angles radians. ``trail`` (n, 2) oldest first, ``path`` (m, 2)
    nearest first. ``hud`` is the dict :func:`usv_mj.outputs.render.overlay.draw_hud` reads.
    """

    index: int
    t: float
    pose: tuple[float, float, float]                 # x, y, psi of the hull
    ref_pose: tuple[float, float, float]             # x_d, y_d, psi_d
    funnel_center: tuple[float, float]               # Do & Pan reference point (x_bar_d, y_bar_d)
    funnel_half: tuple[float, float]                 # rho1, rho2
    funnel_ok: bool
    trail: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    view: TopView | None = None
    hud: dict = field(default_factory=dict)
    world: object = None                             # usv_mj.outputs.render.world.RenderWorld (sea, obstacles) or None
    # the other vessels of a fleet (add_fleet): (name, pose (x, y, psi), trail (n, 2), rgba, (L, B) [m])
    others: tuple = ()
    own_name: str = ""                               # the own ship's name (a fleet's; "" for a single run)
    domain: float = 0.0                              # the own ship's safety domain radius [m] (0: none drawn)


@dataclass
class Plan:
    """The frames of a video and how time was mapped."""

    frames: list[FrameSpec]
    rows: np.ndarray            # record row of each frame
    t_start: float
    t_end: float
    speedup: float              # requested
    played_speedup: float       # (t_end - t_start) fps / (N - 1)
    fps: float
    eps: float                  # Do & Pan offset used for the funnel centre [m]


def default_speedup(duration: float, video_seconds: float = 30.0) -> float:
    """max(1, duration / video_seconds): the run's duration maps to 30 s of video, never slow motion."""
    return max(1.0, float(duration) / video_seconds)


def frame_count(duration: float, fps: float, speedup: float) -> int:
    """N = max(1, round(duration fps / speedup)) frames (see the module docstring)."""
    return max(1, int(round(float(duration) * float(fps) / float(speedup))))


def do_pan_offset(record) -> float:
    """eps = m23/m22 [m] recovered from the record: e1 = (x - x_d) + eps (cos psi - cos psi_d), same for y.

    A least-squares fit over the rows (docs/model.md §1 transformed coordinates); 0 when the rows do not
    determine it (no heading error) or the errors are not Do & Pan's (fit residual not small).
    """
    try:
        x, y, psi = record["x"], record["y"], record["psi"]
        xd, yd, psid = record["x_d"], record["y_d"], record["psi_d"]
        e1, e2 = record["e1"], record["e2"]
    except (KeyError, IndexError):
        return 0.0
    a = np.concatenate([e1 - (x - xd), e2 - (y - yd)])
    b = np.concatenate([np.cos(psi) - np.cos(psid), np.sin(psi) - np.sin(psid)])
    ok = np.isfinite(a) & np.isfinite(b)
    a, b = a[ok], b[ok]
    bb = float(b @ b)
    if len(a) < 2 or bb < 1e-12:
        return 0.0
    eps = float(a @ b) / bb
    resid = a - eps * b
    if not (abs(eps) < 5.0 and float(np.sqrt(np.mean(resid ** 2))) <= 1e-6 + 1e-3 * float(np.sqrt(np.mean(a ** 2)))):
        return 0.0
    return eps


POSE = ("t", "x", "y", "psi")
#: the columns a frame reads at its row (a record without one of them: NaN)
FRAME_COLUMNS = ("t", "x", "y", "psi", "x_d", "y_d", "psi_d", "e1", "e2", "e3", "rho1", "rho2", "rho3",
                 "z1", "z2", "z3", "tau_u", "q_tau_u", "tau_r", "q_tau_r", "f_u", "f_r", "sat_u", "sat_r")


def _column(record, name):
    """Column ``name`` of the frame rows' record (NaN when the run has no such column)."""
    try:
        return np.asarray(record[name], dtype=float)
    except (KeyError, IndexError):
        return np.full(len(record), np.nan)


def valid_rows(record) -> int:
    """Number of leading rows with a finite hull pose (a diverged run may end in a non-finite row).

    A record stored on disk that completed (or was interrupted) with a finite last row is taken
    whole without reading its columns: the loop checks every state it records (a diverged or
    failed run's is scanned in chunks, bounded memory)."""
    n = len(record)
    if n == 0:
        return 0
    if getattr(record, "stored", False):
        last = [_take(record, c, [n - 1])[0] for c in POSE]
        if getattr(record, "status", "") in ("completed", "interrupted") and np.isfinite(last).all():
            return n
        lo = 0
        for chunks in zip(*(record.column_chunks(c) for c in POSE)):
            good = np.logical_and.reduce([np.isfinite(c) for c in chunks])
            if not good.all():
                return lo + int(np.argmin(good))
            lo += len(good)
        return n
    good = np.isfinite(record["x"]) & np.isfinite(record["y"]) & np.isfinite(record["psi"]) & np.isfinite(record["t"])
    if good.all():
        return n
    return int(np.argmin(good))   # the first non-finite row


def _take(record, name, rows) -> np.ndarray:
    """Column ``name`` at ``rows`` (NaN when the record has no such column): only those rows."""
    rows = np.asarray(rows, dtype=np.int64)
    try:
        take = getattr(record, "take", None)
        if take is not None:
            return take(name, rows.reshape(-1)).reshape(rows.shape)
        return np.asarray(record[name], dtype=float)[rows]
    except (KeyError, IndexError):
        return np.full(rows.shape, np.nan)


def search_rows(record, n: int, times) -> np.ndarray:
    """``np.searchsorted(record["t"][:n], times)`` (the left insertion points), reading only a few
    values of t per time: a guess from the mean step (the loop's rows are uniform in t), then
    steps until t[i - 1] < time <= t[i]; the whole column only if that does not settle."""
    times = np.asarray(times, dtype=float)
    if not getattr(record, "stored", False):
        return np.searchsorted(np.asarray(record["t"][:n], float), times)
    t0, t1 = _take(record, "t", [0, n - 1])
    step = (t1 - t0) / (n - 1) if n > 1 and t1 > t0 else 1.0
    flat = times.reshape(-1)
    guess = np.clip(np.ceil((flat - t0) / step), 0, n).astype(np.int64)
    for _ in range(8):
        below = _take(record, "t", np.clip(guess - 1, 0, n - 1))
        at = _take(record, "t", np.clip(guess, 0, n - 1))
        down = (guess > 0) & (below >= flat)
        up = (guess < n) & (at < flat) & ~down
        if not (down.any() or up.any()):
            return guess.reshape(times.shape)
        guess = guess - down + up
    return np.searchsorted(np.asarray(record["t"][:n], float), times)   # t is not uniform: the column


def frame_rows(record, n: int, rows, trail_s: float, ahead_s: float, segments: int) -> tuple:
    """The rows each frame draws: (trail rows (frames, segments + 1), path rows (same)): the
    samples uniform in time over the trail_s before and the ahead_s after each frame row."""
    t = _take(record, "t", rows)
    t0, t1 = _take(record, "t", [0, n - 1])
    i = np.arange(segments + 1)[None, :]

    def linspace(a, b):   # np.linspace(a, b, segments + 1) per row, its arithmetic exactly
        out = i * ((b - a) / segments)[:, None] + a[:, None]
        out[:, -1] = b
        return out

    ts = linspace(np.maximum(t0, t - trail_s), t)
    ta = linspace(t, np.minimum(t1, t + ahead_s))
    trail = np.clip(search_rows(record, n, ts), 0, np.asarray(rows)[:, None])
    path = np.clip(search_rows(record, n, ta), np.asarray(rows)[:, None], n - 1)
    return trail, path


def _actuator_limits(metadata):
    """((lo, hi) surge, (lo, hi) yaw) of the run's ``[actuators]`` for the control bars, None where
    a channel is unlimited (or the metadata has no scenario)."""
    table = ((metadata or {}).get("scenario") or {}).get("actuators")
    if not table:
        return None, None
    from usv_mj.physics.actuators import ActuatorSpec

    try:
        lo_u, hi_u, lo_r, hi_r = ActuatorSpec(**table).generalized_limits()
    except (TypeError, ValueError):
        return None, None
    pick = lambda lo, hi: (lo, hi) if (math.isfinite(lo) or math.isfinite(hi)) else None  # noqa: E731
    return pick(lo_u, hi_u), pick(lo_r, hi_r)


def _bar_scale(limits, *arrays) -> float:
    """The bars' half-range: 1.25 x the largest finite limit when the channel has one (the limit then
    shows as a tick), the 99th percentile of |tau| otherwise."""
    if limits is not None:
        finite = [abs(v) for v in limits if math.isfinite(v)]
        if finite:
            return 1.25 * max(finite)
    return _robust_scale(*arrays)


def _robust_scale(*arrays) -> float:
    v = np.abs(np.concatenate([np.asarray(a, float) for a in arrays]))
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 1.0
    s = float(np.percentile(v, 99.0))
    return s if s > 0 else (float(v.max()) if v.max() > 0 else 1.0)


def top_view(points: np.ndarray, aspect: float, min_half_height: float = MIN_HALF_HEIGHT) -> TopView:
    """Centre and half-height of the top camera that fit ``points`` (k, 2) into the content region.

    The content region (CONTENT_X, CONTENT_Y, fractions of the image) leaves the overlay panel free;
    a 15 % margin plus 1 m is kept around the points; ``aspect`` = width / height.
    """
    lo, hi = points.min(axis=0), points.max(axis=0)
    cx, cy = (lo + hi) / 2
    need_w, need_h = (hi - lo) * 1.15 + 2.0
    fx, fy = CONTENT_X[1] - CONTENT_X[0], CONTENT_Y[1] - CONTENT_Y[0]
    # visible height 2h, width 2h aspect; content spans fx of the width and fy of the height
    h = max(min_half_height, need_h / (2 * fy), need_w / (2 * fx * aspect))
    vis_w, vis_h = 2 * h * aspect, 2 * h
    # put the content centre at the centre of the content region
    ox = ((CONTENT_X[0] + CONTENT_X[1]) / 2 - 0.5) * vis_w
    oy = (0.5 - (CONTENT_Y[0] + CONTENT_Y[1]) / 2) * vis_h   # image y grows downward, world y upward
    return TopView(float(cx - ox), float(cy - oy), float(h))


NEAR_OBSTACLE_M = 8.0   # m: an obstacle whose outline is this close to the hull is kept in the top view


def _bounding_radius(o: dict) -> float:
    if o.get("kind") == "box":
        return 0.5 * math.hypot(*o.get("size", (0.0, 0.0)))
    return float(o.get("radius", 0.0))


def _obstacles_near(table: np.ndarray, t: float, x: float, y: float) -> list:
    """Bounding-box corners of the obstacles (rows: cx, cy, vx, vy, r at t = 0) within NEAR_OBSTACLE_M of (x, y)."""
    cx, cy = table[:, 0] + table[:, 2] * t, table[:, 1] + table[:, 3] * t
    r = table[:, 4]
    near = np.hypot(cx - x, cy - y) - r < NEAR_OBSTACLE_M
    out = []
    for i in np.flatnonzero(near):
        out += [(cx[i] - r[i], cy[i] - r[i]), (cx[i] + r[i], cy[i] + r[i])]
    return out


def plan_frames(record, *, fps: float = 30.0, speedup: float | None = None, width: int = 1280, height: int = 720,
                trail_s: float | None = None, ahead_s: float | None = None, segments: int = 48,
                camera: str = "top", max_frames: int | None = None, rows=None) -> Plan:
    """The frames of the video of ``record`` (see the module docstring for the time mapping).

    ``trail_s`` / ``ahead_s``: seconds of run time in the wake trail and the path ahead (default
    max(10 s, 3 s of video)); ``segments``: line segments per polyline. ``max_frames`` caps N (tests).
    ``rows``: one frame per given record row instead of the time mapping (tests, stills).
    """
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
        raise ValueError(f"fps = {fps!r}: the frame rate must be a positive number")
    if speedup is not None and not (isinstance(speedup, (int, float)) and math.isfinite(speedup) and speedup > 0):
        raise ValueError(f"speedup = {speedup!r}: the playback speed-up must be a positive number")
    n = valid_rows(record)
    if n == 0:
        raise ValueError("the run has no row with a finite hull pose (x, y, psi): nothing to render")
    t0, t1 = (float(v) for v in _take(record, "t", [0, n - 1]))
    duration = t1 - t0
    sp = default_speedup(duration) if speedup is None else float(speedup)
    nf = frame_count(duration, fps, sp) if duration > 0 else 1
    if max_frames is not None:
        nf = max(1, min(nf, int(max_frames)))
    # the closest zoom keeps a hull longer than 2 m at the paper hull's share of the picture
    from usv_mj.outputs.render.world import hull_dimensions

    hull = hull_dimensions(record)
    min_half = MIN_HALF_HEIGHT * max(1.0, hull[0] / 2.0) if hull is not None else MIN_HALF_HEIGHT
    explicit_rows = rows is not None
    if explicit_rows:
        rows = np.asarray(rows, dtype=int).ravel()
        if rows.size == 0 or rows.min() < 0 or rows.max() >= n:
            raise ValueError(f"rows {rows.tolist()[:8]}: every row must be in 0..{n - 1} (the rows with a finite pose)")
        times = _take(record, "t", rows)
        nf = len(rows)
    else:
        times = np.array([t1]) if nf == 1 else t0 + duration * np.arange(nf) / (nf - 1)
        rows = np.clip(search_rows(record, n, times), 0, n - 1)
        prev = np.clip(rows - 1, 0, n - 1)
        rows = np.where(np.abs(_take(record, "t", prev) - times) < np.abs(_take(record, "t", rows) - times), prev, rows)
    played = duration * fps / (nf - 1) if nf > 1 and duration > 0 and not explicit_rows else sp
    span = max(10.0, 3.0 * sp)
    trail_s = span if trail_s is None else float(trail_s)
    ahead_s = span if ahead_s is None else float(ahead_s)

    # every column at the frame rows only (a record of those rows: the summaries' formulas apply)
    from usv_mj.record.run_record import RunRecord

    names = [c for c in getattr(record, "column_names", ()) if c in FRAME_COLUMNS] or list(FRAME_COLUMNS)
    sub = RunRecord.from_arrays({c: _take(record, c, rows) for c in names})
    t = sub["t"]
    x, y, psi = (sub[c] for c in ("x", "y", "psi"))
    xd, yd, psid = (_column(sub, c) for c in ("x_d", "y_d", "psi_d"))
    e = [_column(sub, f"e{i}") for i in (1, 2, 3)]
    rho = [_column(sub, f"rho{i}") for i in (1, 2, 3)]
    z = [_column(sub, f"z{i}") for i in (1, 2, 3)]
    funnel = bool(np.isfinite(rho[0]).any())
    if not funnel:  # a controller without a funnel: the HUD shows the pose errors, with no bound
        from usv_mj.record.summary import pose_errors

        e = [np.asarray(v, float) for v in pose_errors(sub).values()]
    tau = {k: _column(sub, k) for k in ("tau_u", "q_tau_u", "tau_r", "q_tau_r", "f_u", "f_r", "sat_u", "sat_r")}
    eps = do_pan_offset(sub)
    trail_rows, path_rows = frame_rows(record, n, rows, trail_s, ahead_s, segments)
    trail_xy = np.stack([_take(record, "x", trail_rows), _take(record, "y", trail_rows)], axis=-1)
    path_xy = np.stack([_take(record, "x_d", path_rows), _take(record, "y_d", path_rows)], axis=-1)
    md = getattr(record, "metadata", {}) or {}
    run = RunChannels.from_metadata(md.get("channels"))   # what tau and f hold (usv_mj.physics.channels)
    # the bars are the command's (tau, Q(tau)); the text beside them the applied f in its own unit
    channels = {"allocated": run.allocated,
                "rows": tuple((c.symbol, a.symbol, a.display_unit, a.shown_factor) for c, a in zip(run.command, run.applied))}
    # allocated: the actuators' limits are the applied channels' (n_P's, the rudder's), not the bars'
    lim_u, lim_r = _actuator_limits(md) if not run.allocated else (None, None)
    scale_u = _bar_scale(lim_u, tau["tau_u"], tau["q_tau_u"])
    scale_r = _bar_scale(lim_r, tau["tau_r"], tau["q_tau_r"])
    vessel = ((md.get("scenario") or {}).get("vessel") or {}).get("kind", "paper")
    title = " / ".join([str(md[k]) for k in ("preset",) if md.get(k)] + ([str(vessel)] if vessel != "paper" else [])
                       + [str(md[k]) for k in ("controller", "plant") if md.get(k)])
    aspect = width / height
    from usv_mj.outputs.render.world import render_world

    world = render_world(record)
    obstacle_table = None
    if world is not None and world.obstacles:
        import json

        obstacle_table = np.array([(*o["center"], *o["velocity"], _bounding_radius(o))
                                   for o in json.loads(world.obstacles)], float).reshape(-1, 5)

    # the legend names the safety boundary when one is drawn (an obstacle with an inflation > 0)
    safety = world is not None and any(math.isfinite(v) and v > 0 for v in world.inflation or ())
    frames = []
    for j in range(len(rows)):
        k = j   # the frame's row in ``sub``
        has_ref = math.isfinite(xd[k]) and math.isfinite(yd[k])
        ref = (float(xd[k]), float(yd[k]), float(psid[k]) if math.isfinite(psid[k]) else 0.0) if has_ref else \
            (float("nan"),) * 3
        if has_ref:
            fc = (ref[0] + eps * math.cos(ref[2]), ref[1] + eps * math.sin(ref[2]))
        else:
            fc = (float("nan"), float("nan"))
        fh = (float(rho[0][k]), float(rho[1][k]))
        zk = [z[i][k] if math.isfinite(z[i][k]) else (e[i][k] / rho[i][k] if rho[i][k] else float("nan"))
              for i in (0, 1)]
        ok = bool(abs(zk[0]) < 1.0 and abs(zk[1]) < 1.0)
        # wake trail and path ahead, sampled uniformly in time (frame_rows)
        trail = trail_xy[j]
        path = path_xy[j]
        path = path[np.all(np.isfinite(path), axis=1)]
        # top camera: hull, reference, funnel corners
        pts = [(x[k], y[k])]
        if has_ref:
            pts.append(ref[:2])
            if math.isfinite(fh[0]) and math.isfinite(fh[1]):
                pts += [(fc[0] - fh[0], fc[1] - fh[1]), (fc[0] + fh[0], fc[1] + fh[1])]
        if obstacle_table is not None:                # obstacles close to the hull stay in the picture
            pts += _obstacles_near(obstacle_table, float(t[k]), float(x[k]), float(y[k]))
        view = top_view(np.array(pts, float), aspect, min_half)
        hud = {"t": float(t[k]), "t_end": t1, "speedup": played, "title": title, "camera": camera, "funnel": funnel,
               "safety_boundary": safety,
               "view_half_m": view.half_height if camera == "top" else None,
               "e": tuple(float(e[i][k]) for i in range(3)), "rho": tuple(float(rho[i][k]) for i in range(3)),
               "tau_u": float(tau["tau_u"][k]), "q_tau_u": float(tau["q_tau_u"][k]),
               "tau_r": float(tau["tau_r"][k]), "q_tau_r": float(tau["q_tau_r"][k]),
               "tau_u_scale": scale_u, "tau_r_scale": scale_r,
               "f_u": float(tau["f_u"][k]), "f_r": float(tau["f_r"][k]),
               "sat_u": float(tau["sat_u"][k]), "sat_r": float(tau["sat_r"][k]),
               "tau_u_limits": lim_u, "tau_r_limits": lim_r, "channels": channels}
        frames.append(FrameSpec(j, float(t[k]), (float(x[k]), float(y[k]), float(psi[k])), ref, fc, fh, ok,
                                trail, path, view, hud, world))
    return Plan(frames, rows, t0, t1, sp, played, float(fps), eps)


#: the other vessels' colours in a fleet's video (the own ship is the model's hull)
VESSEL_RGBA = ((0.95, 0.55, 0.10, 0.95), (0.55, 0.35, 0.85, 0.95), (0.15, 0.70, 0.45, 0.95),
               (0.90, 0.25, 0.45, 0.95), (0.30, 0.60, 0.95, 0.95), (0.75, 0.75, 0.20, 0.95))


def add_fleet(plan: Plan, fleet, width: int, height: int, trail_s: float | None = None, segments: int = 48,
              domain: float = 0.0) -> Plan:
    """The frames of ``plan`` (made from the own ship's record of ``fleet``, a
    :class:`usv_mj.record.fleet.FleetRecord`) with every other vessel at the frame's row: its pose,
    its wake trail, its colour (:data:`VESSEL_RGBA`) and size, the own ship's safety domain
    (``domain`` [m]) and a top view that holds every vessel."""
    own = fleet.own_record
    n = valid_rows(own)
    trail_s = max(10.0, 3.0 * plan.played_speedup) if trail_s is None else float(trail_s)
    aspect = width / height
    others = [name for name in fleet.names if name != fleet.own]
    dims = {}
    for name in fleet.names:
        from usv_mj.outputs.render.world import hull_dimensions

        hull = hull_dimensions(fleet[name])
        dims[name] = (hull[0], hull[1]) if hull is not None else (1.98, 0.76)
    for j, spec in enumerate(plan.frames):
        k = int(plan.rows[j])
        items, pts = [], [spec.pose[:2]]
        trail_rows, _ = frame_rows(own, n, np.array([k]), trail_s, 0.0, segments)
        for c, name in enumerate(others):
            rec = fleet[name]
            pose = tuple(float(rec[col][k]) for col in ("x", "y", "psi"))
            trail = np.stack([_take(rec, "x", trail_rows[0]), _take(rec, "y", trail_rows[0])], axis=-1)
            items.append((name, pose, trail, VESSEL_RGBA[c % len(VESSEL_RGBA)], dims[name]))
            if all(math.isfinite(v) for v in pose[:2]):
                pts.append(pose[:2])
        if spec.view is not None and len(pts) > 1:
            # every vessel in the picture, never closer than the own ship's own view
            spec.view = top_view(np.array(pts + [(spec.view.cx, spec.view.cy)], float), aspect,
                                 spec.view.half_height)
        spec.others = tuple(items)
        spec.own_name = fleet.own
        spec.domain = float(domain)
        spec.hud["title"] = f"{len(fleet.names)} vessels / " + spec.hud.get("title", "")
    return plan
