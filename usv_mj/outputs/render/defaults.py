"""The video's defaults and limits: size, frame rate, cameras (standard library only).

Read by the renderer (:mod:`usv_mj.outputs.render.video`) and by the command line, which builds its
video flags from them without importing numpy or MuJoCo.
"""

from __future__ import annotations

import numbers

DEFAULT_WIDTH, DEFAULT_HEIGHT, DEFAULT_FPS = 1280, 720, 30
MAX_FPS = 240.0  # frames per video second: more is no video a player shows, and the frames fill memory
CAMERAS_HELP = ("top (follows ship and reference from above, north up), chase (behind the hull), overview (fixed, "
                "looking north over the start), chart (fixed, straight down over the origin: north up, east "
                "right), or another camera of the model")


def check_size(width, height):
    """ValueError unless ``width`` and ``height`` are even integers of pixels in [16, 8192] (numpy's too)."""
    for name, v in (("width", width), ("height", height)):
        if not isinstance(v, numbers.Integral) or isinstance(v, bool) or v < 16 or v > 8192:
            raise ValueError(f"{name} = {v!r}: the video size must be an integer number of pixels in [16, 8192]")
        if v % 2:
            raise ValueError(f"{name} = {v}: H.264 with yuv420p needs an even number of pixels")
