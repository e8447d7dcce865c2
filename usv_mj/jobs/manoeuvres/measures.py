"""The measures of the standard manoeuvres, from a track and a heading (ITTC 7.5-04-02-01, IMO MSC.137(76)).

Pure functions of arrays, so that they can be checked on constructed records with closed-form
answers (tests/test_manoeuvres.py) and used on any run's record. Conventions (README, Conventions):
world x east, y north, heading psi counter-clockwise from +x [rad], unwrapped; the execute (the
"rudder" put over) is at the first sample unless ``t_execute`` says otherwise; the original course
is the heading at the execute.

- **Turning circle**: with p0 the position at the execute and e the original course's unit vector,
  n = e turned 90 deg towards the turn: *advance* = (p - p0) . e and *transfer* = (p - p0) . n at the
  first sample where the heading change reaches 90 deg (linear interpolation between the samples);
  *tactical diameter* = (p - p0) . n where it reaches 180 deg; the *steady turning diameter* from the
  circle fitted (least squares, Kasa's algebraic fit) to the track after the heading change reached
  ``steady_after_deg`` (360 by default), and from the steady speed and yaw rate, 2 V / |r| with
  V = sqrt(u^2 + v^2) (the two agree when the turn is steady).
- **Zig-zag**: the executes are the start and every sign change of the command; the *n-th
  overshoot* is the largest |heading change| between execute n + 1 and n + 2 beyond the switching
  angle; the *initial turning time* is the time from the first execute to the second (the time to
  the second execute).
- **Spiral**: per hold of the stepped command, the steady yaw rate is the mean of r over the hold's
  last ``settle_fraction`` part.
- **Stopping**: from the execute, the *track reach* is the path length until the speed over ground
  falls below a threshold; the *head reach* and the *lateral deviation* are the displacement along
  and across the original course at that moment.

Angles in the results are in degrees, lengths in metres, times in seconds, yaw rates in rad/s.
"""

from __future__ import annotations

import math

import numpy as np


def _crossing(t, s, level):
    """The first time where the increasing-in-magnitude signal ``s`` reaches ``level`` (linear
    interpolation between samples), its fractional index, or (None, None)."""
    idx = np.flatnonzero(s >= level)
    if len(idx) == 0:
        return None, None
    k = int(idx[0])
    if k == 0:
        return float(t[0]), 0.0
    f = (level - s[k - 1]) / (s[k] - s[k - 1])
    return float(t[k - 1] + f * (t[k] - t[k - 1])), k - 1 + f


def _at(a, fi):
    """``a`` at fractional index ``fi`` (linear interpolation)."""
    k = int(math.floor(fi))
    if k >= len(a) - 1:
        return float(a[-1])
    f = fi - k
    return float(a[k] + f * (a[k + 1] - a[k]))


def fit_circle(x, y) -> tuple[float, float, float]:
    """Least-squares circle through points (Kasa's algebraic fit): (xc [m], yc [m], radius [m])."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    A = np.column_stack([x, y, np.ones_like(x)])
    b = x * x + y * y
    (a0, a1, a2), *_ = np.linalg.lstsq(A, b, rcond=None)
    xc, yc = a0 / 2, a1 / 2
    return float(xc), float(yc), float(math.sqrt(max(a2 + xc * xc + yc * yc, 0.0)))


def turning_measures(t, x, y, psi, u=None, v=None, r=None, *, t_execute: float | None = None,
                     steady_after_deg: float = 360.0, length: float | None = None) -> dict:
    """Advance, transfer, tactical and steady turning diameters of a turning circle (module docstring).

    Arrays are samples of one run; ``length`` L [m] adds each measure in ship lengths (``*_L``). A
    measure the run did not reach (the heading never turned 90 / 180 / ``steady_after_deg`` deg) is None."""
    t, x, y, psi = (np.asarray(a, float) for a in (t, x, y, psi))
    k0 = 0 if t_execute is None else int(np.searchsorted(t, t_execute))
    t, x, y, psi = t[k0:], x[k0:], y[k0:], psi[k0:]
    dpsi = psi - psi[0]
    turn = 1.0 if dpsi[-1] >= 0 else -1.0           # +1 to port (counter-clockwise), -1 to starboard
    change = turn * dpsi
    e = np.array([math.cos(psi[0]), math.sin(psi[0])])
    n = turn * np.array([-e[1], e[0]])
    along = (x - x[0]) * e[0] + (y - y[0]) * e[1]
    across = (x - x[0]) * n[0] + (y - y[0]) * n[1]
    out = {"turn": "port" if turn > 0 else "starboard", "heading_change_deg": float(math.degrees(change[-1]))}
    t90, f90 = _crossing(t, change, math.pi / 2)
    t180, f180 = _crossing(t, change, math.pi)
    out["time_to_90_s"] = t90 - t[0] if t90 is not None else None
    out["time_to_180_s"] = t180 - t[0] if t180 is not None else None
    out["advance_m"] = _at(along, f90) if f90 is not None else None
    out["transfer_m"] = _at(across, f90) if f90 is not None else None
    out["tactical_diameter_m"] = _at(across, f180) if f180 is not None else None
    out["position_90_m"] = [_at(x, f90), _at(y, f90)] if f90 is not None else None     # world x, y
    out["position_180_m"] = [_at(x, f180), _at(y, f180)] if f180 is not None else None
    ts, fs = _crossing(t, change, math.radians(steady_after_deg))
    out["steady_from_s"] = ts
    out["steady_diameter_m"] = out["steady_diameter_from_rate_m"] = None
    out["steady_yaw_rate"] = out["steady_speed"] = None
    if fs is not None and len(t) - int(fs) >= 5:
        k = int(math.ceil(fs))
        xc, yc, radius = fit_circle(x[k:], y[k:])
        out["steady_diameter_m"] = 2 * radius
        out["steady_centre_m"] = [xc, yc]
        if u is not None and r is not None:
            u_, v_, r_ = (np.asarray(a, float)[k0:][k:] for a in (u, v if v is not None else np.zeros_like(u), r))
            speed, rate = float(np.mean(np.hypot(u_, v_))), float(np.mean(r_))
            out["steady_speed"], out["steady_yaw_rate"] = speed, rate
            out["steady_diameter_from_rate_m"] = 2 * speed / abs(rate) if rate != 0 else None
    if length:
        for key in ("advance", "transfer", "tactical_diameter", "steady_diameter", "steady_diameter_from_rate"):
            value = out[f"{key}_m"]
            out[f"{key}_L"] = value / length if value is not None else None
    return out


def execute_times(t, command) -> list[float]:
    """The executes of a zig-zag: the first sample, then every sign change of ``command`` (the time
    of the first sample with the new sign)."""
    t, c = np.asarray(t, float), np.sign(np.asarray(command, float))
    changes = np.flatnonzero((c[1:] != c[:-1]) & (c[1:] != 0)) + 1
    return [float(t[0])] + [float(t[k]) for k in changes]


def zigzag_measures(t, heading_change, command, switch_deg: float, x=None, y=None,
                    length: float | None = None) -> dict:
    """Overshoot angles [deg] and the initial turning time [s] of a zig-zag (module docstring).

    ``heading_change`` [rad]: psi - psi_0, unwrapped; ``command`` the "rudder" (its sign is the turn);
    ``switch_deg`` the switching angle (10 for the 10/10 test). With the track ``x``, ``y`` [m]:
    ``track_to_second_execute_m``, the path length until the heading has changed by the switching
    angle (IMO's initial turning ability, in L with ``length``)."""
    t, dpsi = np.asarray(t, float), np.asarray(heading_change, float)
    ex = execute_times(t, command)
    overshoots, times = [], []
    for i in range(1, len(ex) - 1):
        w = (t >= ex[i]) & (t <= ex[i + 1])
        k = np.flatnonzero(w)
        j = k[int(np.argmax(np.abs(dpsi[k])))]
        overshoots.append(float(math.degrees(abs(dpsi[j]))) - switch_deg)
        times.append(float(t[j]))
    track = None
    if x is not None and y is not None and len(ex) > 1:
        k = int(np.searchsorted(t, ex[1]))
        track = float(np.sum(np.hypot(np.diff(np.asarray(x, float)[:k + 1]), np.diff(np.asarray(y, float)[:k + 1]))))
    out = {
        "switch_deg": float(switch_deg),
        "executes_s": ex,
        "initial_turning_time_s": ex[1] - ex[0] if len(ex) > 1 else None,   # = the time to the second execute
        "time_to_second_execute_s": ex[1] - ex[0] if len(ex) > 1 else None,
        "first_overshoot_deg": overshoots[0] if overshoots else None,
        "second_overshoot_deg": overshoots[1] if len(overshoots) > 1 else None,
        "time_to_first_overshoot_s": times[0] - ex[0] if times else None,
        "overshoots_deg": overshoots,
        "period_s": ex[3] - ex[1] if len(ex) > 3 else None,
        "track_to_second_execute_m": track,
    }
    if length:
        out["track_to_second_execute_L"] = track / length if track is not None else None
    return out


def spiral_measures(t, r, holds, settle_fraction: float = 0.25, r_tol: float = 0.01) -> dict:
    """The spiral's steady yaw rate per hold of the command. ``holds`` is a list of (t_start, t_end,
    command value, branch) with branch "down" or "up"; the steady r is the mean over the hold's last
    ``settle_fraction`` [rad/s] (``spread``: its peak-to-peak there, small when the turn is steady).
    The *loop* is where the two branches turn to opposite sides at the same command, each faster
    than ``r_tol`` [rad/s] (a slower yaw rate counts as a straight course, or a decay not yet
    over): ``loop_commands`` are those commands, ``loop_width`` their span (a lower bound of the
    loop's width, 0 when only one command is inside) and ``loop_width_upper`` the span to the next
    held commands outside it (an upper bound; None at the ends of the steps)."""
    t, r = np.asarray(t, float), np.asarray(r, float)
    points = []
    for t0, t1, value, branch in holds:
        w = (t >= t1 - settle_fraction * (t1 - t0)) & (t <= t1)
        if not np.any(w):
            continue
        seg = r[w]
        points.append({"command": float(value), "branch": branch, "yaw_rate": float(np.mean(seg)),
                       "spread": float(np.ptp(seg))})
    down = {p["command"]: p["yaw_rate"] for p in points if p["branch"] == "down"}
    up = {p["command"]: p["yaw_rate"] for p in points if p["branch"] == "up"}
    both = sorted(set(down) & set(up))
    split = [c for c in both if down[c] * up[c] < 0 and min(abs(down[c]), abs(up[c])) > r_tol]
    upper = None
    if split:
        below = [c for c in both if c < min(split)]
        above = [c for c in both if c > max(split)]
        upper = (min(above) - max(below)) if below and above else None
    return {"points": points,
            "loop_commands": split,
            "loop_width": (max(split) - min(split)) if split else 0.0,
            "loop_width_upper": upper,
            "hysteresis": bool(split),
            "yaw_rate_at_zero": {"down": down.get(0.0), "up": up.get(0.0)}}


def stopping_measures(t, x, y, psi, u, v, *, stop_speed: float, t_execute: float | None = None,
                      length: float | None = None) -> dict:
    """Track reach, head reach and lateral deviation of a stopping test (module docstring); the stop
    is the first sample after the execute where sqrt(u^2 + v^2) < ``stop_speed`` [m/s] (None if never)."""
    k0 = 0 if t_execute is None else int(np.searchsorted(np.asarray(t, float), t_execute))
    t, x, y, psi, u, v = (np.asarray(a, float)[k0:] for a in (t, x, y, psi, u, v))
    speed = np.hypot(u, v)
    ds = np.hypot(np.diff(x), np.diff(y))
    path = np.concatenate([[0.0], np.cumsum(ds)])
    below = np.flatnonzero(speed < stop_speed)
    out = {"stop_speed": float(stop_speed), "initial_speed": float(speed[0])}
    if len(below) == 0:
        out.update(time_to_stop_s=None, track_reach_m=None, head_reach_m=None, lateral_deviation_m=None)
    else:
        k = int(below[0])
        e = np.array([math.cos(psi[0]), math.sin(psi[0])])
        dx, dy = x[k] - x[0], y[k] - y[0]
        out.update(time_to_stop_s=float(t[k] - t[0]), track_reach_m=float(path[k]),
                   head_reach_m=float(dx * e[0] + dy * e[1]), lateral_deviation_m=float(-dx * e[1] + dy * e[0]),
                   heading_change_deg=float(math.degrees(psi[k] - psi[0])))
    if length:
        for key in ("track_reach", "head_reach", "lateral_deviation"):
            value = out[f"{key}_m"]
            out[f"{key}_L"] = value / length if value is not None else None
    return out
