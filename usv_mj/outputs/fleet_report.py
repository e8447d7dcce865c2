"""``report.md`` of a run of several vessels: each vessel's outcome and the encounter's measures."""

from __future__ import annotations

from pathlib import Path


def _num(v, fmt="{:.3f}"):
    return "—" if v is None else fmt.format(v)


def write_fleet_report(path, summary: dict) -> Path:
    """Write the report of a fleet's ``summary`` (:func:`usv_mj.jobs.fleet.run_fleet_job`'s) to ``path``."""
    enc = summary["encounters"]
    lines = [f"# {len(summary['vessels'])} vessels in one sea", "",
             f"Plant: {summary['plant']}; {summary['duration_s']:g} s; status **{summary['status']}**"
             + (f" ({summary['stop_reason']})" if summary.get("stop_reason") else "") + ".", "",
             "## The vessels", "", "| vessel | controller | criterion | status |", "|---|---|---|---|"]
    for name, s in summary["vessels"].items():
        crit = (s.get("criterion") or {})
        lines.append(f"| {name}{' (own ship)' if name == summary['own_ship'] else ''} | {s.get('controller', '—')} | "
                     f"{crit.get('description', '—')}: {'passed' if crit.get('passed') else 'not passed' if crit.get('passed') is False else 'not judged'} | "
                     f"{s.get('status', '—')} |")
    lines += ["", "## The encounter", "",
              f"Own ship: **{enc['own_ship']}**; its safety domain: "
              + (f"{enc['safety_domain_m']:.3g} m ({enc['safety_domain_L']:g} own-ship lengths, centre to centre)"
                 if enc.get("safety_domain_m") else "unknown (no hull length)") + ".", "",
              "| pair | closest [m] | at t [s] | DCPA 1 s before [m] | TCPA 1 s before [s] | contact |",
              "|---|---|---|---|---|---|"]
    for name, p in enc["pairs"].items():
        contact = _contacts(p)
        lines.append(f"| {name} | {_num(p['min_range_m'])} | {_num(p['t_min_range_s'], '{:.1f}')} | "
                     f"{_num(p['dcpa_before_m'])} | {_num(p['tcpa_before_s'], '{:.1f}')} | {contact} |")
    lines += ["", "Collision (a contact between hulls; on the analytic plant, which has no contact model, hulls "
              "that overlap): **" + ("yes" if enc["collision"] else "no") + "**.", "",
              "Figures: `figures/fleet_tracks.png` (the tracks, the safety domain at the closest approach), "
              "`figures/fleet_ranges.png` (the ranges and the DCPA over time); the own ship's as a single run's.", ""]
    path = Path(path)
    path.write_text("\n".join(lines))
    return path


def _contacts(pair: dict) -> str:
    """The pair's contacts in one cell: the first's time, how many, how long in all, the hardest."""
    contacts = pair["contacts"]
    if not contacts and "hulls_overlap_from_s" in pair:   # the analytic plant: no contact force to show
        return (f"hulls overlap from t = {pair['hulls_overlap_from_s']:.1f} s, "
                f"{pair['hulls_overlap_s']:.1f} s in all (no contact model)")
    if not contacts:
        return "none"
    n = pair.get("n_contacts", len(contacts))
    peak = max(c["max_force_N"] for c in contacts)
    first = f"from t = {contacts[0]['t_s']:.1f} s"
    if n == 1:
        return f"{first}, {pair.get('in_contact_s', 0.0):.2g} s, up to {peak:.3g} N"
    return f"{first}: {n} touches, {pair.get('in_contact_s', 0.0):.2g} s in all, up to {peak:.3g} N"
