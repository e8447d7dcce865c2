"""The README's Conventions in the video frame: a current setting toward the chart's north moves the
hull up the screen, one setting toward east moves it right.

An unpowered hull drifts in a current (``[sea.current] toward_deg``, compass degrees) for 6 s; the
run is rendered to an mp4 by ``render_run`` (what ``usv-mj run --camera chart`` writes) through the
fixed ``chart`` camera of models/scene.xml, and the frames are read back from the file. The hull is
found in the first and last frame by its colour alone (white, grey, brown and black parts, against
water whose red is far below its blue), not from anything the renderer reports, and its centroid
must move up the image (row index down) for north and right (column up) for east, by about the
drift the record shows times the camera's scale, with the other image axis still.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
WIDTH, HEIGHT = 480, 270
DURATION = 6.0


def _gl_or_skip():
    from usv_mj.outputs.render import gl_backend

    try:
        return gl_backend.select_backend()
    except gl_backend.GLUnavailableError as exc:  # pragma: no cover - CI installs Mesa
        pytest.skip(str(exc).splitlines()[0])


def _chart_pixels_per_metre() -> float:
    """Image pixels per metre of water under the chart camera: HEIGHT / 2 over its height x tan(fovy / 2)."""
    cam = next(c for c in ET.parse(ROOT / "models" / "scene.xml").iter("camera") if c.get("name") == "chart")
    z = float(cam.get("pos").split()[2])
    return (HEIGHT / 2) / (z * math.tan(math.radians(float(cam.get("fovy"))) / 2))


def _drift(drift_scenario, toward_deg: float):
    """The record of an unpowered hull at the origin, heading east, in a 1 m/s current setting toward
    ``toward_deg`` (compass)."""
    from usv_mj import simulate

    rec = simulate(drift_scenario(DURATION, 1.0, toward_deg))
    assert rec.status == "completed"
    return rec


def _hull_centroid(frame: np.ndarray) -> tuple[float, float]:
    """(row, column) of the mean pixel that is not water: the sea's red is about 100 below its blue,
    the hull's parts (white, grey, brown, black) have red at least as high as blue less 30."""
    rgb = frame.astype(int)
    mask = rgb[..., 0] > rgb[..., 2] - 30
    assert 30 < mask.sum() < 0.05 * mask.size, f"{mask.sum()} hull pixels: the hull is not found in the frame"
    rows, cols = np.nonzero(mask)
    return float(rows.mean()), float(cols.mean())


@pytest.mark.parametrize("toward_deg, screen", [(0.0, "up"), (90.0, "right")])
def test_a_current_moves_the_hull_the_same_way_on_the_screen_as_on_the_chart(tmp_path, drift_scenario, toward_deg,
                                                                           screen):
    _gl_or_skip()
    import imageio.v3 as iio

    from usv_mj.outputs.render import render_run

    rec = _drift(drift_scenario, toward_deg)
    info = render_run(rec, tmp_path / "drift.mp4", width=WIDTH, height=HEIGHT, fps=5, speedup=2.0, camera="chart",
                      workers=1, progress=False, layers=())
    frames = list(iio.imiter(info["mp4"]))
    assert len(frames) >= 10 and frames[0].shape == (HEIGHT, WIDTH, 3)
    (r0, c0), (r1, c1) = _hull_centroid(frames[0]), _hull_centroid(frames[-1])
    scale = _chart_pixels_per_metre()
    if screen == "up":
        along, across, drift = r0 - r1, c1 - c0, rec["y"][-1] - rec["y"][0]   # rows grow down the image
    else:
        along, across, drift = c1 - c0, r1 - r0, rec["x"][-1] - rec["x"][0]
    assert along > 10.0, (screen, (r0, c0), (r1, c1))                           # px, the screen's direction
    assert abs(across) < 3.0, (screen, (r0, c0), (r1, c1))
    assert drift > 3.0                                                          # m, the chart's direction
    assert along == pytest.approx(drift * scale, rel=0.25), (along, drift * scale)
