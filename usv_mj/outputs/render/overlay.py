"""The heads-up overlay drawn onto a rendered RGB frame with numpy and Pillow (after MuJoCo rendered it).

What it shows (values of one record row, see :mod:`usv_mj.record.run_record`):

- time t [s] of the run, its end, and the playback speed-up;
- the tracking errors against their prescribed bounds (docs/model.md §3 steps 2-4, Eqs. 9, 14): one bar per
  axis spanning -rho_i..+rho_i with a marker at e_i, i.e. z_i = e_i / rho_i in [-1, 1]; green while
  |z_i| < 0.8, amber below 1, red at or beyond the funnel (|z_i| >= 1, a violation). e1, e2 in m,
  e3 in degrees;
- the controls: the law's output tau (outline), the quantized command Q(tau) (a thin marker) and
  the force the actuators realized, which the plant received (filled bar; red while saturated; its
  value printed after the bar as "applied"), for surge tau_u [N] and yaw tau_r [N m], on a
  symmetric scale ``tau_*_scale`` fixed for the whole video (the planner's 99th percentile of
  |tau|, or 1.25 x the actuators' limit when they have one; a clipped bar ends in a triangle); the
  actuators' limits ``tau_*_limits`` are red ticks;
  each row is named by its command channel and says the applied value f in the applied channel's
  unit (``values["channels"]``: the planner's rows from the record's channels,
  :class:`usv_mj.physics.channels.RunChannels`): on a ruddered vessel the propeller's n_P [1/s] and
  the rudder angle [deg]; a force command allocated to them (``allocated``) has bars of its force
  and moment, the text the n_P and delta they were allocated to;
- a legend of the 3-D layers (wake trail, reference path ahead, ghost hull, funnel box, and the
  obstacles' safety boundaries when the run has one: ``values["safety_boundary"]``);
- in the top view (``values["view_half_m"]``: the half height of the picture [m]) a scale bar,
  bottom right: a round length (1, 2 or 5 x 10^k m) near a fifth of the frame's width.

A run without a funnel (``values["funnel"]`` False) shows its pose errors x - x_d, y - y_d and
wrap(psi - psi_d) with no bound, and no funnel in the legend.

Only the two panel regions are converted to Pillow images, so the cost is about a millisecond a frame
at 1280x720. Everything scales with the frame height (designed at 720 px).
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from usv_mj.outputs.render.planner import FUNNEL_OK_RGBA, GHOST_RGBA, PATH_RGBA, SAFETY_LINE_RGBA, TRAIL_RGBA

TEXT = (235, 240, 245)
DIM = (150, 160, 170)
GOOD = (70, 220, 110)
WARN = (250, 190, 40)
BAD = (255, 70, 60)
LAW = (120, 190, 255)
QUANT = (255, 150, 40)


@lru_cache(maxsize=16)
def hud_font(size: int, bold: bool = False):
    """DejaVu Sans Mono (shipped with matplotlib) at ``size`` px; Pillow's default font otherwise."""
    size = max(6, int(size))
    try:
        import matplotlib

        name = "DejaVuSansMono-Bold.ttf" if bold else "DejaVuSansMono.ttf"
        path = Path(matplotlib.__file__).parent / "mpl-data" / "fonts" / "ttf" / name
        return ImageFont.truetype(str(path), size)
    except Exception:  # pragma: no cover - any font will do
        try:
            return ImageFont.load_default(size=size)
        except TypeError:
            return ImageFont.load_default()


def _rgb(rgba) -> tuple[int, int, int]:
    return tuple(int(round(255 * c)) for c in rgba[:3])


def _fmt(v, spec: str, unit: str = "") -> str:
    try:
        v = float(v)
    except (TypeError, ValueError):
        return "n/a"
    if not math.isfinite(v):
        return "n/a"
    return format(v, spec) + unit


def _darken(frame: np.ndarray, x0: int, y0: int, x1: int, y1: int) -> Image.Image:
    """Crop [y0:y1, x0:x1], darken it for contrast, return it as a Pillow image (to be pasted back)."""
    region = frame[y0:y1, x0:x1].astype(np.uint16)
    region = (region * 2 // 5 + 8).astype(np.uint8)
    return Image.fromarray(region)


def _error_bar(draw, x, y, w, h, e, rho):
    """A bar over [-rho, +rho] with a fill from 0 to e (clipped at the bound)."""
    draw.rectangle([x, y, x + w, y + h], outline=DIM, width=1)
    cx = x + w / 2
    draw.line([cx, y - 2, cx, y + h + 2], fill=DIM, width=1)
    try:
        z = float(e) / float(rho)
    except (TypeError, ValueError, ZeroDivisionError):
        return
    if not math.isfinite(z):
        return
    colour = GOOD if abs(z) < 0.8 else (WARN if abs(z) < 1.0 else BAD)
    zc = max(-1.0, min(1.0, z))
    xe = cx + zc * (w / 2)
    inset = min(2, (h - 1) // 2)
    draw.rectangle([min(cx, xe), y + inset, max(cx, xe), y + h - inset], fill=colour)
    draw.line([xe, y - 3, xe, y + h + 3], fill=colour, width=3)


def _tau_bar(draw, x, y, w, h, tau, q, scale, f=None, limits=None, saturated=False):
    """Law output tau as an outline, the applied force f (Q(tau) when f is None) as a filled bar, Q(tau)
    as a thin marker and the actuators' ``limits`` (lo, hi) as red ticks, all on [-scale, scale]."""
    cx = x + w / 2
    draw.rectangle([x, y, x + w, y + h], outline=DIM, width=1)
    draw.line([cx, y - 2, cx, y + h + 2], fill=DIM, width=1)
    try:
        scale = float(scale)
    except (TypeError, ValueError):
        return
    if not (math.isfinite(scale) and scale > 0):
        return
    filled_value = q if f is None else f
    fill_colour = BAD if saturated else QUANT
    for value, colour, filled, inset in ((filled_value, fill_colour, True, 3), (tau, LAW, False, 1)):
        try:
            v = float(value) / scale
        except (TypeError, ValueError):
            continue
        if not math.isfinite(v):
            continue
        vc = max(-1.0, min(1.0, v))
        xe = cx + vc * (w / 2)
        inset = min(inset, (h - 1) // 2)
        box = [min(cx, xe), y + inset, max(cx, xe), y + h - inset]
        if filled:
            draw.rectangle(box, fill=colour)
        else:
            draw.rectangle(box, outline=colour, width=2)
        if abs(v) > 1.0:  # clipped: an arrow head at the end, pointing out, inside the bar's frame
            s = 1 if v > 0 else -1
            draw.polygon([(xe - s * h * 0.6, y), (xe - s * h * 0.6, y + h), (xe, y + h / 2)], fill=colour)
    if f is not None:  # the transmitted command, where it differs from what was applied
        try:
            vq = float(q) / scale
        except (TypeError, ValueError):
            vq = float("nan")
        if math.isfinite(vq):
            xq = cx + max(-1.0, min(1.0, vq)) * (w / 2)
            draw.line([xq, y, xq, y + h], fill=QUANT, width=2)
    for lim in (limits or ()):
        try:
            vl = float(lim) / scale
        except (TypeError, ValueError):
            continue
        if math.isfinite(vl) and abs(vl) <= 1.0:
            xl = cx + vl * (w / 2)
            draw.line([xl, y - 4, xl, y + h + 4], fill=BAD, width=2)


def draw_hud(frame: np.ndarray, values: dict, *, hud: bool = True, legend: bool = True) -> np.ndarray:
    """Draw the heads-up panel (top left) and the legend (bottom left) onto ``frame`` in place.

    ``values`` keys: t, t_end, speedup, title, e (3), rho (3), tau_u, q_tau_u, tau_r, q_tau_r,
    tau_u_scale, tau_r_scale, camera; optional f_u, f_r (applied), sat_u, sat_r (0/1) and
    tau_u_limits, tau_r_limits ((lo, hi) or None). Missing or non-finite values print as "n/a".
    """
    H, W = frame.shape[:2]
    s = H / 720.0
    if hud:
        _draw_panel(frame, values, s)
    if legend:
        _draw_legend(frame, s, values.get("funnel", True), bool(values.get("safety_boundary")))
        half = values.get("view_half_m")
        if half is not None and math.isfinite(float(half)) and float(half) > 0:
            draw_scale_bar(frame, 2.0 * float(half) / H)
    return frame


def scale_bar_length(m_per_px: float, target_px: float) -> tuple[float, int]:
    """The scale bar's length: the round length (1, 2 or 5 x 10^k m) nearest ``target_px`` pixels at
    ``m_per_px``, and its length in pixels."""
    target_m = target_px * m_per_px
    k = math.floor(math.log10(target_m))
    best = min((f * 10.0 ** e for e in (k - 1, k, k + 1) for f in (1, 2, 5)),
               key=lambda L: abs(math.log(L / target_m)))
    return best, int(round(best / m_per_px))


def draw_scale_bar(frame: np.ndarray, m_per_px: float) -> tuple[float, int]:
    """A scale bar bottom right of ``frame`` (a top-down view, ``m_per_px`` metres a pixel): a white bar
    with end ticks and its length in m; returns (length [m], length [px])."""
    H, W = frame.shape[:2]
    s = H / 720.0
    length_m, length_px = scale_bar_length(m_per_px, 0.2 * W)
    pad, m = int(round(14 * s)), int(round(12 * s))
    font = hud_font(round(15 * s))
    w, h = length_px + 2 * m, int(46 * s)
    x1, y1 = W - pad, H - pad
    x0, y0 = max(0, x1 - w), max(0, y1 - h)
    if x1 - x0 < length_px or y1 - y0 < 10:
        return length_m, length_px
    img = _darken(frame, x0, y0, x1, y1)
    d = ImageDraw.Draw(img)
    yb = h - int(12 * s)
    thick = max(2, int(round(3 * s)))
    d.rectangle([m, yb - thick // 2, m + length_px - 1, yb + thick // 2], fill=TEXT)
    for xe in (m, m + length_px - 1):
        d.line([xe, yb - int(7 * s), xe, yb + int(4 * s)], fill=TEXT, width=max(1, thick // 2))
    text = f"{length_m:g} m"
    d.text((m + length_px / 2 - d.textlength(text, font=font) / 2, int(4 * s)), text, font=font, fill=TEXT)
    frame[y0:y1, x0:x1] = np.asarray(img)
    return length_m, length_px


def _draw_panel(frame, values, s):
    H, W = frame.shape[:2]
    pad = int(round(14 * s))
    x0, y0 = pad, pad
    x1, y1 = min(W, x0 + int(470 * s)), min(H, y0 + int(268 * s))
    if x1 - x0 < 20 or y1 - y0 < 20:
        return
    img = _darken(frame, x0, y0, x1, y1)
    d = ImageDraw.Draw(img)
    big, small, tiny = hud_font(round(24 * s), True), hud_font(round(17 * s)), hud_font(round(14 * s))
    m = int(round(12 * s))
    y = m
    t, t_end, sp = values.get("t"), values.get("t_end"), values.get("speedup")
    d.text((m, y), f"t = {_fmt(t, '6.1f')} s", font=big, fill=TEXT)
    d.text((int(250 * s), y + int(5 * s)), f"/ {_fmt(t_end, '.0f')} s  {_fmt(sp, '.3g')}x", font=small, fill=DIM)
    y += int(32 * s)
    title = str(values.get("title", ""))
    if title:
        d.text((m, y), title[:48], font=tiny, fill=DIM)
    y += int(26 * s)
    label_w, bar_w, bar_h = int(62 * s), int(190 * s), max(4, int(16 * s))
    e = list(values.get("e", (None,) * 3)) + [None] * 3
    rho = list(values.get("rho", (None,) * 3)) + [None] * 3
    funnel = values.get("funnel", True)
    names = ("x e1", "y e2", "psi e3") if funnel else ("x", "y", "psi")
    rows = ((names[0], e[0], rho[0], 1.0, "m", "+6.2f", "5.2f"), (names[1], e[1], rho[1], 1.0, "m", "+6.2f", "5.2f"),
            (names[2], e[2], rho[2], 180.0 / math.pi, "deg", "+6.1f", "5.1f"))
    d.text((m, y), "error / bound (funnel)" if funnel else "pose error (x - x_d, y - y_d, psi - psi_d)",
           font=tiny, fill=DIM)
    y += int(20 * s)
    for label, ei, ri, k, unit, fe, fr in rows:
        d.text((m, y), label, font=small, fill=TEXT)
        _error_bar(d, m + label_w, y + int(2 * s), bar_w, bar_h, ei, ri)
        ev = None if ei is None else float(ei) * k
        rv = None if ri is None else float(ri) * k
        d.text((m + label_w + bar_w + int(10 * s), y), f"{_fmt(ev, fe)}/{_fmt(rv, fr)} {unit}" if funnel else
               f"{_fmt(ev, fe)} {unit}", font=tiny, fill=TEXT)
        y += int(27 * s)
    y += int(4 * s)
    applied = values.get("f_u") is not None
    channels = values.get("channels") or DEFAULT_CHANNELS
    allocated = bool(channels.get("allocated"))
    d.text((m, y), "control: tau (outline), applied f (filled), limit (red)" if applied and not allocated else
           "control: tau (outline), Q(tau) (filled); allocated to" if applied else
           "control: law tau (outline), Q(tau) (filled)", font=tiny, fill=DIM)
    y += int(20 * s)
    rows = [(label, key, unit, k, tag if allocated else "applied")
            for (label, tag, unit, k), key in zip(channels["rows"], ("u", "r"))]
    for label, key, unit, k, tag in rows:
        tau, q, f = values.get(f"tau_{key}"), values.get(f"q_tau_{key}"), values.get(f"f_{key}")
        sat = bool(values.get(f"sat_{key}") or 0.0)
        d.text((m, y), label, font=small, fill=TEXT)
        # allocated: the bar is the force (the law's and the transmitted command), f is not a force
        bar_f = None if allocated else f
        _tau_bar(d, m + label_w, y + int(2 * s), bar_w, bar_h, tau, q, values.get(f"tau_{key}_scale"), bar_f,
                 values.get(f"tau_{key}_limits"), sat)
        if f is None:
            d.text((m + label_w + bar_w + int(10 * s), y), f"Q {_fmt(q, '+8.3g')} {unit}", font=tiny, fill=QUANT)
        else:
            d.text((m + label_w + bar_w + int(10 * s), y), control_text(tag, f, k, unit, sat), font=tiny,
                   fill=BAD if sat else QUANT)
        y += int(27 * s)
    frame[y0:y1, x0:x1] = np.asarray(img)


#: the rows of a run whose channels are forces (a HUD made without the planner's channels)
DEFAULT_CHANNELS = {"allocated": False, "rows": (("tau_u", "tau_u", "N", 1.0), ("tau_r", "tau_r", "N m", 1.0))}


def control_text(tag: str, f, k: float, unit: str, sat: bool) -> str:
    """The words after a control bar: what the plant received, named ("applied", or the quantity an
    allocated force became), its value times ``k`` in ``unit``, and SAT while an actuator limit cut it."""
    fv = None if f is None else float(f) * k
    return f"{tag} {_fmt(fv, '+8.3g')} {unit}{' SAT' if sat else ''}"


LEGEND = (("wake trail", TRAIL_RGBA), ("reference path ahead", PATH_RGBA), ("reference (ghost hull)", GHOST_RGBA),
          ("funnel |e1|<rho1, |e2|<rho2", FUNNEL_OK_RGBA))
SAFETY_ENTRY = ("obstacle safety boundary", SAFETY_LINE_RGBA)


def legend_entries(funnel: bool = True, safety_boundary: bool = False) -> tuple:
    """The legend's (label, RGBA) entries: the funnel box only for a run judged by the funnel, the
    obstacles' safety boundary only for a run that has one."""
    return (LEGEND if funnel else LEGEND[:-1]) + ((SAFETY_ENTRY,) if safety_boundary else ())


def _draw_legend(frame, s, funnel: bool = True, safety_boundary: bool = False):
    entries = legend_entries(funnel, safety_boundary)
    H, W = frame.shape[:2]
    pad = int(round(14 * s))
    w, h = int(300 * s), int(len(entries) * 22 * s + 14 * s)
    x0, y1 = pad, H - pad
    y0, x1 = max(0, y1 - h), min(W, x0 + w)
    if x1 - x0 < 20 or y1 - y0 < 10:
        return
    img = _darken(frame, x0, y0, x1, y1)
    d = ImageDraw.Draw(img)
    font = hud_font(round(14 * s))
    y = int(7 * s)
    for label, rgba in entries:
        c = _rgb(rgba)
        if rgba is GHOST_RGBA:
            c = tuple(min(255, int(v * 0.8 + 40)) for v in c)
        d.rectangle([int(8 * s), y + int(4 * s), int(34 * s), y + int(12 * s)], fill=c)
        d.text((int(44 * s), y), label, font=font, fill=TEXT)
        y += int(22 * s)
    frame[y0:y1, x0:x1] = np.asarray(img)



def _arrow(draw, cx, cy, length, angle, colour, width):
    """An arrow of ``length`` px centred on (cx, cy), pointing at ``angle`` (rad, counter-clockwise from
    image right, image up = +angle/2 pi turn; i.e. world x right, world y up in the top view)."""
    dx, dy = 0.5 * length * math.cos(angle), -0.5 * length * math.sin(angle)
    tail, tip = (cx - dx, cy - dy), (cx + dx, cy + dy)
    draw.line([tail, tip], fill=colour, width=width)
    head = 0.32 * length
    for side in (-1, 1):
        a = angle + math.pi + side * 0.45
        draw.line([tip, (tip[0] + head * math.cos(a), tip[1] - head * math.sin(a))], fill=colour, width=width)


def draw_sea_arrows(frame: np.ndarray, current_xy, wind_speed: float, wind_direction: float, *,
                    top_down: bool = True) -> np.ndarray:
    """The sea panel (left, under the heads-up panel) onto ``frame`` in place.

    ``current_xy``: current velocity [m/s] in the world frame; ``wind_speed`` [m/s] and
    ``wind_direction`` [rad], the going-to direction in the world frame. In the top view (image right =
    world +x, image up = world +y) each arrow points where the current / wind goes; in another camera
    the arrows are drawn the same way and the panel says "world frame, x right, y up".
    """
    H, W = frame.shape[:2]
    s = H / 720.0
    pad = int(round(14 * s))
    x0, y0 = pad, pad + int(268 * s) + pad
    x1, y1 = min(W, x0 + int(300 * s)), min(H, y0 + int(112 * s))
    if x1 - x0 < 40 or y1 - y0 < 30:
        return frame
    img = _darken(frame, x0, y0, x1, y1)
    d = ImageDraw.Draw(img)
    small, tiny = hud_font(round(17 * s)), hud_font(round(13 * s))
    m = int(round(12 * s))
    d.text((m, int(6 * s)), "sea (arrows: going to)" if top_down else "sea (world frame, x right, y up)",
           font=tiny, fill=DIM)
    cu, cv = float(current_xy[0]), float(current_xy[1])
    items = (("current", math.hypot(cu, cv), math.atan2(cv, cu), (90, 200, 255)),
             ("wind", float(wind_speed), float(wind_direction), (235, 235, 240)))
    size = int(44 * s)
    for j, (label, speed, angle, colour) in enumerate(items):
        cx, cy = m + size // 2 + j * int(150 * s), int(58 * s)
        if math.isfinite(speed) and speed > 1e-9 and math.isfinite(angle):
            _arrow(d, cx, cy, size, angle, colour, max(2, int(3 * s)))
        else:
            d.ellipse([cx - 4 * s, cy - 4 * s, cx + 4 * s, cy + 4 * s], outline=colour, width=max(1, int(2 * s)))
        d.text((cx + size // 2 + int(8 * s), cy - int(20 * s)), label, font=tiny, fill=DIM)
        d.text((cx + size // 2 + int(8 * s), cy - int(2 * s)), _fmt(speed, ".2f", " m/s"), font=small, fill=TEXT)
    frame[y0:y1, x0:x1] = np.asarray(img)
    return frame


def draw_labels(frame: np.ndarray, labels) -> None:
    """Each (text, pixel x, pixel y, rgb) of ``labels`` written onto ``frame`` (a fleet's vessel names
    beside their hulls), with a dark outline so that it reads on the water."""
    h, w = frame.shape[:2]
    font = hud_font(max(12, round(16 * h / 720)))
    img = Image.fromarray(frame)
    d = ImageDraw.Draw(img)
    for text, x, y, rgb in labels:
        if 0 <= x < w and 0 <= y < h:
            d.text((x, y), text, font=font, fill=tuple(rgb), stroke_width=2, stroke_fill=(10, 20, 30))
    frame[:] = np.asarray(img)
