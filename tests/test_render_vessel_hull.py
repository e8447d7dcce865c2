"""The video draws the run's own vessel: the model file's hull scaled to its L, B, T by the MuJoCo
plant's scale_hull (one source), not the paper hull for every vessel.

Independent numbers: the vessel's main dimensions from its data (the drawn hull's bounding box in
its own frame is L x B exactly, as models/usv.xml's is 1.98 m x 0.76 m), and the pixels of a top
view (a hull twice as long is drawn twice as long)."""

import numpy as np
import pytest

from tests.test_render import _gl_or_skip, pose_record
from usv_mj.outputs.render.planner import TopView
from usv_mj.outputs.render.replay import build_replay_model
from usv_mj.outputs.render.world import hull_dimensions


def _hull_box(model, names=("hull_mid", "hull_bow")):
    """(x extent, y extent) [m] of the hull's shell (models/usv.xml: the box amidships and the
    ellipsoid bow, x from -0.98 to 1.0 m, y +-0.38 m), in the hull's frame (the body at rest)."""
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for name in names:
        g = model.geom(name)
        c, half = np.asarray(g.pos)[:2], np.asarray(g.size)[:2]
        lo, hi = np.minimum(lo, c - half), np.maximum(hi, c + half)
    return tuple(hi - lo)


def test_the_drawn_hull_has_the_vessels_length_and_beam():
    from usv_mj import load_scenario

    paper, _ = build_replay_model(None, width=64, height=64, sea=False)
    assert _hull_box(paper) == pytest.approx((1.98, 0.76), abs=1e-9)      # models/usv.xml as drawn
    for kind, (L, B) in (("otter", (2.0, 1.08)), ("cybership2", (1.255, 0.29))):
        scenario = load_scenario(preset="paper", overrides={"vessel": {"kind": kind}})
        dims = hull_dimensions(scenario)
        assert dims[:2] == (L, B)
        assert hull_dimensions(scenario.to_dict()) == dims                # from a record's metadata table
        model, _ = build_replay_model(None, width=64, height=64, sea=False, hull=dims)
        assert _hull_box(model) == pytest.approx((L, B), abs=1e-9)
    assert hull_dimensions(load_scenario(preset="paper")) is None        # the paper hull: the file's, untouched


def test_a_record_of_another_vessel_is_drawn_at_its_size():
    _gl_or_skip()
    from usv_mj.outputs.render import render_frames

    w, h = 320, 240
    view = TopView(0.0, 0.0, 10.0)
    lengths = []
    for hull in (None, (3.96, 0.76, 0.2)):               # the paper hull, and one twice as long
        empty, frame = render_frames(pose_record([(1e4, 1e4, 0.0), (0.0, 0.0, 0.0)]), rows=[0, 1], width=w,
                                     height=h, layers=(), views=view, hull=hull)
        cols = np.nonzero((np.abs(frame.astype(int) - empty.astype(int)).sum(axis=2) > 40).any(axis=0))[0]
        lengths.append(cols.max() - cols.min() + 1)
    # the silhouette includes the outboard motor aft of the transom (scaled too): twice as long within 10 %
    assert lengths[1] / lengths[0] == pytest.approx(2.0, rel=0.1)


def test_the_closest_zoom_keeps_a_long_hull_in_the_picture():
    from usv_mj import load_scenario
    from usv_mj.outputs.render.planner import MIN_HALF_HEIGHT, plan_frames

    rec = pose_record([(0.0, 0.0, 0.0), (0.5, 0.0, 0.0)])              # a hull alone: the closest zoom
    paper = plan_frames(rec, rows=[0], width=320, height=240).frames[0].view.half_height
    assert paper == pytest.approx(MIN_HALF_HEIGHT)                       # the paper hull's picture: unchanged
    rec.metadata["scenario"] = load_scenario(preset="paper", overrides={
        "vessel": {"kind": "clarke83", "L": 7.0, "B": 1.2, "T": 0.45}}).to_dict()
    long_ = plan_frames(rec, rows=[0], width=320, height=240).frames[0].view.half_height
    assert long_ == pytest.approx(MIN_HALF_HEIGHT * 7.0 / 2.0)           # the same share of the height as 2 m
