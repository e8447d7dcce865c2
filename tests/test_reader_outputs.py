"""Figures, report and video read as a paper's reader reads them (issue 34): every axis names its
quantity and unit, a controller's diagnostics are drawn one panel per unit, figure 1 magnifies the
steady part, figures 2-4 zoom on the errors once the funnel has narrowed, the report says what the
adaptation does with the bound of its law, and the video tells the safety boundary from the path,
has a scale bar and names the applied force. Numbers are derived here from the records' columns."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from usv_mj import load_scenario, simulate
from usv_mj.outputs import figures


@pytest.fixture(scope="module")
def runs():
    """90 s of the paper on the analytic plant (the funnel narrows within 10 % at ln(10)/0.05 = 46 s,
    before two thirds of the run), its PI baseline, and a run of the PI controller alone."""
    sc = load_scenario(preset="paper", overrides={"duration": 90.0, "plant": {"kind": "analytic"}})
    return {"ppc": simulate(sc), "pi": simulate(sc, controller_kind="pi")}


@pytest.fixture
def drawn(monkeypatch, tmp_path):
    """draw_figures, keeping each figure's axes (labels, limits, children) as it is saved."""
    import matplotlib.pyplot as plt

    kept = {}

    def keep(fig, path, note=""):
        kept[path.name] = fig
        fig.canvas.draw()                 # lays out the inset (its box aspect) as the PNG has it

    monkeypatch.setattr(figures, "save_figure", keep)

    def draw(record, baseline=None):
        kept.clear()
        figures.draw_figures(record, tmp_path, baseline)
        return dict(kept)

    yield draw
    plt.close("all")


def test_figures_5_and_6_name_the_quantity_beside_the_unit(runs, drawn):
    figs = drawn(runs["ppc"], runs["pi"])
    labels5 = [a.get_ylabel() for a in figs["fig5_tau_u.png"].axes]
    labels6 = [a.get_ylabel() for a in figs["fig6_tau_r.png"].axes]
    assert labels5 == ["surge force tau_u, Q(tau_u) [N]", "surge force [N]"]     # before: "[N]" and ""
    assert labels6 == ["yaw moment tau_r, Q(tau_r) [N m]", "yaw moment [N m]"]


def test_figure_1_magnifies_the_steady_part_with_both_tracks(runs, drawn):
    rec, base = runs["ppc"], runs["pi"]
    fig = drawn(rec, base)["fig1_trajectory.png"]
    main = fig.axes[0]
    inset = main.child_axes[0]                              # before: none
    (x0, x1), (y0, y1) = inset.get_xlim(), inset.get_ylim()
    assert x1 - x0 == pytest.approx(y1 - y0, rel=1e-9)      # a square of equal scales
    bb = inset.get_position()
    w_px, h_px = bb.width * fig.bbox.width, bb.height * fig.bbox.height
    assert w_px == pytest.approx(h_px, rel=0.02)
    # centred on the reference at the middle of the steady part, t_c = (max(20, T/4) + T) / 2 = 56.25 s
    dt = rec.metadata["control_period_s"]
    kc = int(round(0.5 * (max(20.0, 0.25 * 90.0) + 90.0) / dt))
    cx, cy = rec["x_d"][kc], rec["y_d"][kc]
    assert 0.5 * (x0 + x1) == pytest.approx(cx, abs=1e-9) and 0.5 * (y0 + y1) == pytest.approx(cy, abs=1e-9)
    dev = max(math.hypot(r["x"][kc] - cx, r["y"][kc] - cy) for r in (rec, base))
    assert 0.5 * (x1 - x0) == pytest.approx(max(0.2, 3.0 * dev), rel=1e-9)
    # both tracks pass through it, and it magnifies: a few tenths of a metre against tens of metres
    for r in (rec, base):
        assert x0 < r["x"][kc] < x1 and y0 < r["y"][kc] < y1
    assert (x1 - x0) < 0.05 * np.ptp(main.get_xlim())
    assert len([ln for ln in inset.get_lines() if len(ln.get_xdata())]) == 3     # reference, PPC, PI


@pytest.mark.parametrize("axis", [1, 2, 3])
def test_figures_2_to_4_zoom_on_the_errors_once_the_funnel_has_narrowed(runs, drawn, axis):
    rec, base = runs["ppc"], runs["pi"]
    fig = drawn(rec, base)[("fig2_error_x.png", "fig3_error_y.png", "fig4_error_psi.png")[axis - 1]]
    assert len(fig.axes) == 2                               # before: the funnel panel alone
    zoom = fig.axes[1]
    t0 = zoom.get_xlim()[0]
    # rho = (rho_0 - rho_inf) e^(-0.05 t) + rho_inf; narrowed once rho - rho(T) <= 10 % of rho_0 - rho(T):
    # (rho_0 - rho_inf) e^(-0.05 t) = 0.1 (rho_0 - rho(T)) + rho(T) - rho_inf (44.2 s for e1, e2 at T = 90 s)
    rho_0, rho_inf = ((18.0, 2.0), (18.0, 2.0), (3.0, math.pi / 6))[axis - 1]
    rho_T = (rho_0 - rho_inf) * math.exp(-0.05 * 90.0) + rho_inf
    t_closed = math.log((rho_0 - rho_inf) / (0.1 * (rho_0 - rho_T) + rho_T - rho_inf)) / 0.05
    assert rec[f"rho{axis}"][-1] == pytest.approx(rho_T, rel=1e-9)
    assert t0 == pytest.approx(t_closed, abs=0.02)
    t = rec["t"]
    peak = max(np.max(np.abs(r[f"e{axis}"][t >= t0])) for r in (rec, base))
    assert zoom.get_ylim()[1] == pytest.approx(1.3 * peak, rel=0.02)
    assert zoom.get_ylim()[1] < 0.5 * rec[f"rho{axis}"][-1]   # far inside the funnel: what the top panel hid


def test_figure_7_draws_declared_diagnostics_one_panel_per_unit(runs, drawn):
    rec = runs["pi"]
    units = rec.metadata["diagnostic_units"]              # the PI controller declares them
    assert units["u_e"] == "m/s" and units["integral_r"] == "rad s" and units["e1s"] == "-"
    fig = drawn(rec)["fig7_weights.png"]
    labels = [a.get_ylabel() for a in fig.axes]
    assert len(labels) == 6                                 # -, rad, m/s, rad/s, m, rad s; before: one "value" axis
    for unit, names in (("-", "e1s, e2s, e3s"), ("rad", "psi_a"), ("m/s", "u_e"), ("rad/s", "r_e"),
                        ("m", "integral_u"), ("rad s", "integral_r")):
        assert any(lab.replace("\n", " ") == f"{names} [{unit}]" for lab in labels), (unit, labels)
    # a plug-in that declares no units: a panel per field (never two unknown units on one axis)
    rec.metadata.pop("diagnostic_units")
    try:
        fig = drawn(rec)["fig7_weights.png"]
    finally:
        rec.metadata["diagnostic_units"] = units
    labels = [a.get_ylabel() for a in fig.axes]
    assert len(labels) == figures.MAX_PANELS and all(lab.endswith("[unit not declared]") for lab in labels)
    assert fig.axes[0].get_title().endswith(f"(the first {figures.MAX_PANELS} of 8)")


def test_diagnostic_panels_group_by_declared_unit():
    panels = figures.diagnostic_panels(["a", "b", "c", "d", "e"], {"a": "m", "c": "m", "d": "rad"})
    assert panels == [("m", ["a", "c"]), (None, ["b"]), ("rad", ["d"]), (None, ["e"])]


def test_a_controller_s_declared_units_go_into_the_record():
    """Only the fields it has, as text; none declared: no key (the built-in PPC's metadata unchanged)."""
    from usv_mj.controllers.pi_baseline import PIController

    class Declaring(PIController):
        diagnostic_units = {"u_e": "m/s", "not_a_field": "kg"}

    from usv_mj.controllers.pi_baseline import PIGains

    sc = load_scenario(preset="paper", overrides={"duration": 0.01, "plant": {"kind": "analytic"}})
    rec = simulate(sc, controller=Declaring.from_scenario(PIGains(), sc))
    assert rec.metadata["diagnostic_units"] == {"u_e": "m/s"}
    assert "diagnostic_units" not in simulate(sc).metadata


def test_the_report_says_what_the_adaptation_does_with_the_law_s_bound(runs):
    from usv_mj.outputs.report import adaptation_section

    rec = runs["ppc"]
    text = adaptation_section(rec)
    gains = rec.metadata["scenario"]["controller"]["gains"]
    dt = rec.metadata["control_period_s"]
    after = rec["t"] >= 20.0 - 1e-9
    k20 = int(round(20.0 / dt))
    # |W_u| <= max(|W_u(20 s)|, sqrt(N) max |u_e| / theta_u) after 20 s (Gamma_u theta_u = 1e3 x 1e-8 = 1e-5 1/s)
    bound = max(rec["w_u_norm"][k20], math.sqrt(gains["rbf_nodes"]) * np.max(np.abs(rec["u_e"][after])) / gains["theta_u"])
    row = next(line for line in text.splitlines() if line.startswith("| W_u |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1] == f"{rec['w_u_norm'][-1]:.3g}"
    assert cells[3] == "1e-05" and cells[4] == "1e+05 s (27.8 h)"
    assert cells[6] == f"{bound:.3g}"
    assert np.all(rec["w_u_norm"][after] <= bound)            # the bound holds over the run
    assert "|W_u| is still growing at the end" in text and "bounded" in text and "not converged" in text
    assert adaptation_section(runs["pi"]) is None              # no network weights: no section


def test_the_run_s_report_has_the_adaptation_section(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    res = subprocess.run([sys.executable, "-m", "usv_mj.cli", "run", "--duration", "30", "--plant", "analytic",
                          "--no-video", "--no-baseline", "--no-log", "-q", "--out", str(tmp_path / "r")], cwd=root,
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    report = (tmp_path / "r" / "report.md").read_text()
    assert "## Adaptation (network weights, figure 7)" in report and "| W_u |" in report


# --- the video's overlay -------------------------------------------------------------------------


def test_the_safety_boundary_has_its_own_colour_and_legend_entry():
    from usv_mj.outputs.render import overlay
    from usv_mj.outputs.render.planner import PATH_RGBA, SAFETY_LINE_RGBA

    entries = overlay.legend_entries(funnel=True, safety_boundary=True)
    assert entries[-1] == ("obstacle safety boundary", SAFETY_LINE_RGBA)
    assert overlay.SAFETY_ENTRY not in overlay.legend_entries(funnel=True, safety_boundary=False)
    # apart from every other colour of the legend (before: (1, 0.8, 0.1), the path's (1, 0.84, 0.1))
    for label, rgba in entries[:-1]:
        assert np.linalg.norm(np.subtract(SAFETY_LINE_RGBA[:3], rgba[:3])) > 0.45, label
    assert np.linalg.norm(np.subtract(SAFETY_LINE_RGBA[:3], PATH_RGBA[:3])) > 0.8


def test_the_scale_bar_is_a_round_length_drawn_to_scale():
    from usv_mj.outputs.render import overlay

    # 1280 x 720 showing +-10 m vertically: 20 / 720 m a pixel; a fifth of the width, 256 px, is 7.1 m:
    # the nearest round length (|ln(10/7.1)| = 0.34 < |ln(5/7.1)| = 0.35) is 10 m, 360 px
    assert overlay.scale_bar_length(20.0 / 720.0, 256.0) == (10.0, 360)
    assert overlay.scale_bar_length(0.01, 100.0) == (1.0, 100)
    assert overlay.scale_bar_length(0.013, 100.0) == (1.0, 77)
    frame = np.zeros((720, 1280, 3), np.uint8)
    overlay.draw_hud(frame, {"view_half_m": 10.0, "camera": "top"}, hud=False, legend=True)
    region = frame[600:, 800:]
    white = np.all(region == overlay.TEXT, axis=2)

    def runs_of(row):   # lengths of the runs of True in a row of pixels
        edges = np.flatnonzero(np.diff(np.r_[0, row.astype(int), 0]))
        return edges[1::2] - edges[0::2]

    longest = max((int(runs_of(row).max()) for row in white if row.any()), default=0)
    assert longest == 360
    # not in a perspective camera, which has no single scale
    frame2 = np.zeros((720, 1280, 3), np.uint8)
    overlay.draw_hud(frame2, {"view_half_m": None, "camera": "chase"}, hud=False, legend=True)
    assert not np.any(np.all(frame2[600:, 800:] == overlay.TEXT, axis=2))


def test_the_applied_force_is_named():
    from usv_mj.outputs.render import overlay

    assert overlay.control_text("applied", 60.14, 1.0, "N", False) == "applied    +60.1 N"   # before: "F    +60.1 N"
    assert overlay.control_text("applied", -0.1, 180.0 / math.pi, "deg", True).endswith(" deg SAT")


def test_the_planner_marks_a_run_with_a_safety_boundary(tmp_path):
    from usv_mj.outputs.render.planner import plan_frames

    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "examples" / "scenarios" / "harbour_gap.toml"
    sc = load_scenario(str(path), overrides={"duration": 2.0, "plant": {"kind": "analytic"}})
    rec = simulate(sc)
    plan = plan_frames(rec, fps=2.0, max_frames=2)
    hud = plan.frames[0].hud
    assert hud["safety_boundary"] is True and hud["view_half_m"] == plan.frames[0].view.half_height
    plain = plan_frames(simulate(load_scenario(preset="paper", overrides={"duration": 2.0, "plant": {"kind": "analytic"}})),
                        fps=2.0, max_frames=2, camera="chase")
    assert plain.frames[0].hud["safety_boundary"] is False and plain.frames[0].hud["view_half_m"] is None
