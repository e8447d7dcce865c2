"""``report.md`` of a run: our errors beside the paper's Tables 1 and 2, the run's success criterion
(the funnel for the paper's controller, :mod:`usv_mj.record.criteria`) and quantizer statistics, the PI
baseline, the step-halving check and the figures (works from finished runs).

The report speaks in the run's criterion: the funnel's words only for a run judged by the funnel,
the adaptation's (s2 clamps) only for a controller that records them."""

from __future__ import annotations

from pathlib import Path

from usv_mj.outputs.figures import figure_titles
from usv_mj.record.summary import verdict

# docs/model.md §5: the paper's Table 1 (this controller) and Table 2 (the controller of its ref. [26]).
PAPER_TABLE_1 = {"x": (5.32, 3.10, 0.85), "y": (6.42, 4.58, 1.17), "psi": (0.84, 0.65, 0.42)}
PAPER_TABLE_2 = {"x": (5.47, 3.77, 1.85), "y": (6.81, 5.23, 2.04), "psi": (0.92, 0.74, 0.51)}
UNITS = {"x": "m", "y": "m", "psi": "rad"}


def _fmt(v, digits=3):
    if v is None:
        return "—"
    return f"{v:.{digits}f}"


def adaptation_section(record) -> str | None:
    """``## Adaptation`` of report.md for a run whose controller adapts network weights with the paper's
    sigma-modification law W_i_dot = Gamma_i (i_e S_i - theta_i W_i) (docs/model.md §3, step 11; the
    record has ``w_u_norm``... and ``u_e``...; Gamma_i, theta_i and the node count from its scenario):
    per network, |W_i| at the end and its growth over the last fifth of the run, the leakage's rate
    Gamma_i theta_i and time constant, and the bound the law guarantees: d/dt |W|^2 / 2 =
    Gamma (i_e S.W - theta |W|^2) < 0 while |W| > |i_e| |S| / theta, and |S| <= sqrt(N) (N Gaussian
    nodes, each at most 1), so after t_s |W| <= max(|W(t_s)|, sqrt(N) max |i_e| / theta). None for a
    run without them."""
    import math

    import numpy as np

    nets = ("u", "v", "r")
    cols = [f"w_{i}_norm" for i in nets] + [f"{i}_e" for i in nets]
    if not all(c in record for c in cols) or len(record) < 3:
        return None
    gains = ((record.metadata.get("scenario") or {}).get("controller") or {}).get("gains") or {}
    try:
        nodes = int(gains["rbf_nodes"])
        rates = {i: (float(gains[f"gamma_{i}"]), float(gains[f"theta_{i}"])) for i in nets}
    except (KeyError, TypeError, ValueError):
        return None
    n = len(record)
    dt = float(record.metadata.get("control_period_s") or 0.001)
    t_end = (n - 1) * dt
    t_s = 20.0 if t_end >= 40.0 else 0.0     # after the transient, as the report's largest errors
    k_s, k_f = int(round(t_s / dt)), int(round(0.8 * (n - 1)))
    peak = {}
    for i in nets:   # max |i_e| after t_s, chunk by chunk
        m, lo = 0.0, 0
        for chunk in record.column_chunks(f"{i}_e"):
            part = np.abs(chunk[max(0, k_s - lo):])
            if len(part):
                m = max(m, float(np.max(part)))
            lo += len(chunk)
        peak[i] = m
    lines = ["## Adaptation (network weights, figure 7)", "",
             f"The weights follow the paper's sigma-modification law W_i_dot = Gamma_i (i_e S_i - theta_i W_i) "
             f"(docs/model.md §3, step 11), with {nodes} Gaussian nodes (each S_ij in (0, 1], so |S_i| <= "
             f"sqrt({nodes}) = {math.sqrt(nodes):.2f}). What the paper's leakage theta_i guarantees is that the "
             f"weights stay bounded, not that they settle: |W_i| can only shrink while |W_i| > |i_e| |S_i| / "
             f"theta_i, so after t = {t_s:g} s it stays below max(|W_i({t_s:g} s)|, sqrt({nodes}) max |i_e| / "
             f"theta_i) (the bound below).", "",
             f"| network | \\|W\\| at {t_end:g} s | growth over the last {t_end - k_f * dt:.0f} s | Gamma theta [1/s] "
             f"| leakage time constant | max \\|i_e\\| after {t_s:g} s | bound on \\|W\\| |",
             "|---|---|---|---|---|---|---|"]
    words = []
    for i in nets:
        w_end, w_f, w_s = (record.value(f"w_{i}_norm", k) for k in (n - 1, k_f, k_s))
        gamma, theta = rates[i]
        leak = gamma * theta
        tau = math.inf if leak <= 0 else 1.0 / leak
        bound = math.inf if theta <= 0 else max(w_s, math.sqrt(nodes) * peak[i] / theta)
        unit = "m/s" if i != "r" else "rad/s"
        tau_text = "none" if not math.isfinite(tau) else (f"{tau:.3g} s" + (f" ({tau / 3600:.3g} h)" if tau >= 3600 else ""))
        lines.append(f"| W_{i} | {w_end:.3g} | {w_end - w_f:+.3g} | {leak:.3g} | {tau_text} | {peak[i]:.3g} {unit} "
                     f"| {bound:.3g} |")
        # growing: rising at every one of the last five of ten samples after t_s, and by 2 % over the last fifth
        samples = record.take(f"w_{i}_norm", np.linspace(k_s, n - 1, 10).round().astype(int))
        growing = bool(np.all(np.diff(samples[-5:]) > 0)) and w_end - w_f > 0.02 * max(w_end, 1e-12)
        last = record.take(f"w_{i}_norm", np.linspace(k_f, n - 1, 50).round().astype(int))
        if not growing:
            words.append(f"|W_{i}| shows no trend over the last fifth of the run (between {last.min():.3g} and "
                         f"{last.max():.3g}), inside its bound {bound:.3g}.")
        else:
            words.append(
                f"|W_{i}| is still growing at the end ({w_f:.3g} at {k_f * dt:.0f} s, {w_end:.3g} at {t_end:g} s): "
                f"with Gamma_{i} = {gamma:g} and theta_{i} = {theta:g} the leakage pulls W_{i} back at "
                f"{leak:.3g} 1/s, a time constant of {tau_text}, "
                + (f"far longer than this {t_end:g} s run, so the law integrates {i}_e S_{i} almost without "
                   f"leakage and |W_{i}| grows for as long as {i}_e keeps a sign against S_{i} (|{i}_e| is at most "
                   f"{peak[i]:.3g} {unit} after {t_s:g} s). " if tau > t_end else "")
                + f"It is {bound / max(w_end, 1e-300):.2g} times below the law's bound {bound:.3g}: bounded, "
                f"as the paper's argument needs, but not converged; it would level off only over the leakage's "
                f"time constant, or sooner where {i}_e S_{i} averages out.")
    for w in words:
        lines += ["", w]
    return "\n".join(lines)


def gains_section(record, baseline=None) -> str | None:
    """``## Gains`` of report.md: the gains the run's controller (and the baseline's) ran with, from
    the record's scenario (``metadata["scenario"]``: the gains the scenario gave and those derived
    from the vessel, docs/gains.md, each marked); None when the record names no gains."""
    table = record.metadata.get("scenario") or {}
    runs = [(record, "controller")]
    if baseline is not None:
        runs.append((baseline, "baseline"))
    blocks = []
    for rec, section in runs:
        spec = table.get(section) or {}
        gains = spec.get("gains") or {}
        if not gains:
            continue
        derived = set(spec.get("derived") or ())
        vessel = ((table.get("vessel") or {}).get("kind")) or "paper"
        who = str(rec.metadata.get("controller") or spec.get("kind"))
        lines = [f"`{who}` ({section} `{spec.get('kind')}`)" + (f"; derived from the vessel `{vessel}` (docs/gains.md): "
                                                                  f"{', '.join(sorted(derived))}" if derived else ""),
                 "", "| gain | value | from |", "|---|---|---|"]
        for name, value in gains.items():
            shown = f"{value:.6g}" if isinstance(value, float) else str(value)
            lines.append(f"| {name} | {shown} | {'the vessel (derived)' if name in derived else 'the scenario or the default'} |")
        blocks.append("\n".join(lines))
    if not blocks:
        return None
    return "## Gains\n\nThe gains each controller ran with.\n\n" + \
        "\n\n".join(blocks)


def write_report(path, summary: dict, baseline_summary: dict | None = None, step_check: dict | None = None,
                 extra_sections: list[str] | None = None) -> Path:
    """Write ``report.md`` at ``path`` (figures are linked as ``figures/<name>``)."""
    lines = [f"# usv_mj run: preset `{summary['preset']}` on the {summary['plant']} plant", ""]
    status = summary["status"]
    if status == "completed":
        wall, factor = summary.get("wall_time_s"), summary.get("realtime_factor")
        timing = (f" in {wall:.1f} s ({factor:.0f} times real time)"
                  if isinstance(wall, (int, float)) and isinstance(factor, (int, float)) else "")
        lines.append(f"The run completed {summary['simulated_s']:.1f} s of simulated time{timing}.")
    else:
        lines.append(f"**The run stopped early ({status}) after {summary['simulated_s']:.3f} s of simulated time:** "
                     f"{summary['stop_reason']}")
    lines.append("")
    crit = summary["criterion"]
    funnel = "funnel_violations" in summary
    viol = summary.get("funnel_violations")
    name = str(summary.get("controller") or "run").upper()
    bname = str((baseline_summary or {}).get("controller") or "baseline").upper()
    # without a baseline run its column is left out (no placeholder name, no column of dashes)
    bcol = f" {bname} baseline |" if baseline_summary else ""
    bsep = "---|" if baseline_summary else ""
    if not funnel:
        lines.append(f"The {name} controller is judged by its own criterion: {crit['description']}. "
                     f"Outcome: **{verdict(crit)}**.")
    elif viol == 0:
        lines.append("The tracking errors stayed inside all three prescribed-performance funnels "
                     "(0 control steps with |z_i| >= 1).")
    else:
        lines.append(f"**The funnel was lost**: {viol} control steps with |z_i| >= 1, the first at "
                     f"t = {_fmt(summary['first_violation_s'])} s.")
    lines += ["", "## Tracking errors beside the paper", "",
              "Errors are x - x_d, y - y_d and wrap(psi - psi_d), as in the paper's tables. The paper's "
              "numbers do not fit its own start pose (eta0 = (2, -3, 0): they imply that the error grows "
              "from 3.6 m to 8.3 m in 5 s, docs/model.md §5), so they are shown, not matched.", "",
              f"| error | t | this run ({name}) |{bcol} paper Table 1 | paper Table 2 (ref. [26]) |",
              f"|---|---|---|{bsep}---|---|"]
    for axis in ("x", "y", "psi"):
        for i, tc in enumerate(("5", "10", "20")):
            ours = summary["errors_at"][tc][axis]
            base = f" {_fmt(baseline_summary['errors_at'][tc][axis])} |" if baseline_summary else ""
            lines.append(f"| {axis} [{UNITS[axis]}] | {tc} s | {_fmt(ours)} |{base} "
                         f"{PAPER_TABLE_1[axis][i]:.2f} | {PAPER_TABLE_2[axis][i]:.2f} |")
    m = summary["max_abs_error_after_20s"]
    lines += ["", f"Largest error after 20 s: |x| {_fmt(m['x'])} m, |y| {_fmt(m['y'])} m, "
                  f"|psi| {_fmt(m['psi'])} rad.", ""]
    clamps = summary.get("s2_clamps") is not None
    lines += ["## " + ("Funnel, adaptation and quantizer" if funnel else
                       "Success criterion" + (", adaptation" if clamps else "") + " and quantizer"), "",
              f"| quantity | {name} |{bcol}", f"|---|---|{bsep}"]

    def cell(value, fmt=str) -> str:
        return (f" {fmt(value) if value is not None else '—'} |") if baseline_summary else ""

    def both(key, fmt=str, get=lambda s, key: s.get(key)):
        b = get(baseline_summary, key) if baseline_summary else None
        return f"| {key} | {fmt(get(summary, key))} |{cell(b, fmt)}"

    if funnel:
        lines.append(both("funnel_violations"))
        lines.append(both("first_violation_s", lambda v: _fmt(v)))
    else:
        judged = lambda s, key: (s.get("criterion") or {}).get(key)  # noqa: E731
        lines.append(both("passed", lambda v: {True: "yes", False: "no"}.get(v, "not judged"), judged))
        lines.append(both("violations", get=judged))
        lines.append(both("first_violation_s", lambda v: _fmt(v), judged))
        for key in sorted(k for k in crit if k.startswith("max_")):
            lines.append(both(key, lambda v: _fmt(v), judged))
    if clamps:
        lines.append(both("s2_clamps"))
    qs = summary["quantizer_switches"]
    qb = baseline_summary["quantizer_switches"] if baseline_summary else {"u": None, "r": None}
    lines.append(f"| quantizer output changes, surge | {qs['u']} |{cell(qb['u'])}")
    lines.append(f"| quantizer output changes, yaw | {qs['r']} |{cell(qb['r'])}")
    lines += ["", "## Actuators", ""]
    act = summary.get("actuators")
    if act is None:
        lines.append("The run's actuator table is not known.")
    elif act["unlimited"]:
        lines.append("**The actuators are unlimited** (as in the paper, which gives no thrust limits): the plant "
                     "receives the quantized command Q(tau) whatever its size. The forces of this run say what the "
                     "control law asks for, not what a hull of this size can deliver (preset `paper-limited` "
                     "gives the hull twin thrusters).")
    else:
        sat, ep = summary["saturated_fraction"], summary.get("saturation_episodes", {"u": None, "r": None})
        lg = summary.get("longest_saturation_s", {"u": None, "r": None})
        lines += [f"Actuators: {act['description']}.", "",
                  "| channel | time saturated | episodes | longest [s] |", "|---|---|---|---|",
                  f"| surge | {sat['u'] * 100:.2f} % | {ep['u']} | {_fmt(lg['u'])} |",
                  f"| yaw | {sat['r'] * 100:.2f} % | {ep['r']} | {_fmt(lg['r'])} |", "",
                  "Saturated: a limit of the actuators (magnitude or rate) cut the quantized command in that "
                  "control period; each episode is an `actuator_saturation` event (start and end) in the log."]
    if baseline_summary:
        lines += ["", "The PI baseline (docs/model.md §6: surge-speed PI on the along-track error, heading PI with "
                  "yaw-rate damping on the same psi_a) runs through the same quantizer on the same plant. "
                  + ((f"Judged as this run is: {verdict(baseline_summary['criterion'])}."
                      if "criterion" in baseline_summary else "") if "funnel_violations" not in baseline_summary else
                     "It stayed inside the funnel." if baseline_summary["funnel_violations"] == 0 else
                     f"It left the funnel first at t = {_fmt(baseline_summary['first_violation_s'])} s "
                     f"({baseline_summary['funnel_violations']} control steps outside).")]
    if step_check and step_check.get("max_position_m") is None:
        lines += ["", "## Step-size check (docs/model.md §5)", "",
                  f"The run again at half the control period did not finish ({step_check.get('status')}: "
                  f"{step_check.get('stop_reason') or 'no reason recorded'}), so there is no step-size check."]
    elif step_check:
        lines += ["", "## Step-size check (docs/model.md §5)", "",
                  f"The first {step_check['duration_s']:.0f} s again at half the control period "
                  f"({step_check['dt_half']*1e3:g} ms) moved the errors at 5 / 10 / 20 s by at most "
                  f"{step_check['max_position_m']*100:.3f} cm in position and {step_check['max_heading_rad']:.2e} rad "
                  f"in heading (bound: 1 cm and 0.01 rad): "
                  + ("within the bound." if step_check["ok"] else "**outside the bound**.")]
    if summary.get("obstacles"):
        lines += ["", "## Obstacles", "",
                  f"Minimum clearance over the run: {_fmt(summary['min_clearance_m'])} m; contact events: "
                  f"{summary['contacts']}."
                  + (f" Obstacles the hull never came within {summary['beyond_reach_m']:g} m of (the clearance "
                     f"monitor's reach) were not measured: their minimum is —, and it is more than that."
                     if summary.get("beyond_reach_m") is not None else ""), "",
                  "| obstacle | kind | min clearance [m] | at t [s] | peak normal force [N] | safety inflation [m] |",
                  "|---|---|---|---|---|---|"]
        for o in summary["obstacles"]:
            lines.append(f"| {o['name']} | {o['kind']}{' (moving)' if o.get('moving') else ''} | "
                         f"{_fmt(o['min_clearance_m'])} | {_fmt(o['t_min_s'], 2)} | "
                         f"{_fmt(o['peak_normal_force_N'], 1)} | {_fmt(o.get('inflation_m'))} |")
    for section in extra_sections or []:
        lines += ["", section]
    lines += ["", "## Figures", ""]
    weights = "w_u_norm" in (summary.get("diagnostic_fields") or ())
    for name, title in figure_titles(crit["kind"], weights).items():
        lines += [f"### {title}", "", f"![{title}](figures/{name})", ""]
    path = Path(path)
    tmp = path.with_suffix(".md.tmp")
    tmp.write_text("\n".join(lines) + "\n")
    tmp.replace(path)
    return path
