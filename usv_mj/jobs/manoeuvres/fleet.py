"""One manoeuvre on several vessels: ``usv-mj manoeuvre turning --vessel paper,otter,...`` (or ``all``).

Each vessel runs the manoeuvre exactly as ``usv-mj manoeuvre KIND --vessel V`` would (the same
scenario, flags and ``--set`` keys, through :func:`usv_mj.jobs.manoeuvres.run_manoeuvre`), with its own
"rudder" and approach speed where the flags do not set them (:func:`.options.vessel_defaults`: the
vessel's declared defaults, or the paper hull's test Froude-scaled to its length), into
``OUT/<vessel>/`` with every output of a single run. Beside them:

- ``manoeuvre_vessels.png``: every vessel's track from the execute, in the course frame (x along
  the original course, y towards the turn, so that port and starboard turns overlay), in ship
  lengths (left) and in metres (right);
- ``vessels.json``: per vessel its L, the options it ran with, the measures (m and L) and the IMO rows;
- ``vessels.md``: the table of the measures (m and L), one row per vessel.

``all`` is every kind of :data:`usv_mj.core.registry.VESSELS` (built in, registered or an entry point),
so a vessel added later appears without a change here.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from usv_mj.core.errors import ScenarioError
from usv_mj.jobs.manoeuvres.figures import ruddered

#: the measures of each kind in the table: (key without _m/_L, heading, has an L form)
TABLE = {
    "turning": (("advance", "advance", True), ("transfer", "transfer", True),
                ("tactical_diameter", "tactical diameter", True), ("steady_diameter", "steady diameter", True)),
    "zigzag": (("first_overshoot_deg", "1st overshoot [deg]", False),
               ("second_overshoot_deg", "2nd overshoot [deg]", False),
               ("initial_turning_time_s", "time to 2nd execute [s]", False)),
    "stopping": (("track_reach", "track reach", True), ("head_reach", "head reach", True),
                 ("time_to_stop_s", "time to stop [s]", False)),
    "spiral": (),
}


def is_fleet(text) -> bool:
    """``--vessel`` names more than one vessel (a comma-separated list, or ``all``)."""
    return isinstance(text, str) and ("," in text or text.strip() == "all")


def vessel_list(text: str) -> list[str]:
    """The vessel kinds of ``--vessel A,B,...`` or ``all`` (every kind of the registry), each checked."""
    from usv_mj.core.registry import VESSELS

    if text.strip() == "all":
        return list(VESSELS.kinds())
    kinds = []
    for item in text.split(","):
        kind = item.strip()
        if not kind:
            raise ScenarioError(f"--vessel {text}: an empty name in the list; give kinds separated by commas")
        if kind in kinds:
            raise ScenarioError(f"--vessel {text}: {kind} is named twice")
        if not kind.endswith(".toml") and kind not in VESSELS:
            raise ScenarioError(f"--vessel {text}: unknown vessel kind {kind!r}; the kinds are "
                                f"{', '.join(VESSELS.kinds())} (or 'all')")
        kinds.append(kind)
    return kinds


def folder_name(kind: str) -> str:
    """The subfolder of a vessel kind (a data file's path becomes its file name's stem)."""
    name = Path(kind).stem if kind.endswith(".toml") else kind
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name)


def course_frame(x, y, psi, k0: int) -> tuple[np.ndarray, np.ndarray]:
    """The track from sample ``k0`` (the execute) in the course frame: along the original course and
    towards the turn (the side the heading goes at the end) [m]."""
    x, y, psi = (np.asarray(a, float)[k0:] for a in (x, y, psi))
    e = np.array([math.cos(psi[0]), math.sin(psi[0])])
    side = 1.0 if psi[-1] - psi[0] >= 0 else -1.0
    n = side * np.array([-e[1], e[0]])
    d = np.column_stack([x - x[0], y - y[0]])
    return d @ e, d @ n


def rudder_label(result: dict) -> str:
    """The "rudder" a vessel ran with, from its options: a yaw moment, or whatever its own path uses."""
    o = result.get("options", {})
    side = o.get("side") or o.get("first_turn") or ""
    if ruddered(result):   # a ruddered vessel: an angle, not a moment
        key = {"turning": "rudder_deg", "zigzag": "angle_deg", "spiral": "max_rudder_deg"}.get(result.get("kind"))
        angle = o.get(key) if key is not None else None
        if angle is not None:
            return (f"+-{angle:g} deg rudder" if key == "max_rudder_deg" else f"{angle:g} deg rudder {side}").strip()
    for key, unit in (("yaw_moment", "N m"), ("max_yaw_moment", "N m")):
        if key in o:
            return f"{o[key]:.4g} {unit} {side}".strip()
    own = [(k, v) for k, v in o.items() if "rudder" in k]
    return ", ".join(f"{k} = {v:g}" if isinstance(v, float) else f"{k} = {v}" for k, v in own) or "—"


def _num(v, fmt="{:.3f}"):
    return "—" if v is None else fmt.format(v)


def table_lines(kind: str, rows: list[dict]) -> list[str]:
    """The markdown table of the measures, one row per vessel (``rows``: vessels.json's entries)."""
    head = ["vessel", "L [m]", "approach [m/s]", "\"rudder\""]
    for key, title, has_l in TABLE[kind]:
        head += [f"{title} [m]", f"{title} [L]"] if has_l else [title]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        m = r["measures"]
        cells = [r["vessel"], f"{r['length_m']:g}", f"{r['options'].get('approach_speed', float('nan')):.3f}",
                 r["rudder"]]
        for key, _, has_l in TABLE[kind]:
            cells += [_num(m.get(f"{key}_m")), _num(m.get(f"{key}_L"))] if has_l else [_num(m.get(key), "{:.2f}")]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def draw_tracks(kind: str, tracks: dict, path: Path, label: str) -> Path:
    """``manoeuvre_vessels.png``: every vessel's track in the course frame, in L and in metres."""
    from usv_mj.outputs.figures import plt, save_figure

    from usv_mj.jobs.manoeuvres.figures import TITLES

    fig, axes = plt.subplots(1, 2, figsize=(13, 6))
    for i, (vessel, tr) in enumerate(tracks.items()):
        a, n, length = tr["along"], tr["across"], tr["length"]
        for ax, s in ((axes[0], 1.0 / length), (axes[1], 1.0)):
            ax.plot(n * s, a * s, f"C{i % 10}", lw=1.4, label=f"{vessel} (L = {length:g} m, {tr['rudder']})")
            ax.plot([0.0], [0.0], "ko", ms=3)
    for ax, unit in ((axes[0], "L"), (axes[1], "m")):
        ax.set_xlabel(f"transfer: across the original course, towards the turn [{unit}]")
        ax.set_ylabel(f"advance: along the original course [{unit}]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.axvline(0.0, color="0.5", lw=0.8, ls="-.")
    axes[0].legend(fontsize=7, loc="best")
    axes[0].set_title(f"{TITLES[kind]} of every vessel, in ship lengths")
    axes[1].set_title(f"in metres ({label}; from the execute)")
    fig.tight_layout()
    save_figure(fig, path)
    return path


def run_fleet(scenario_for, kinds: list[str], kind: str, out: Path, *, plant_kind=None, video=False,
              progress=False, overwrite=False, render_options=None, skip_refused: bool = False) -> dict:
    """Run manoeuvre ``kind`` on each of ``kinds`` (``scenario_for(vessel)``: the scenario of one
    vessel, as the single command builds it) into ``out`` (module docstring); returns
    {"rows": [...], "files": {...}, "jobs": {vessel: JobResult}, "skipped": [(vessel, why)]}.
    ``skip_refused`` (``--vessel all``): a vessel that refuses the manoeuvre (KVLCC2's stopping
    test) is left out and said so (``skipped``, vessels.json, vessels.md) instead of failing all."""
    from usv_mj.jobs.run import write_json
    from usv_mj.outputs.outdir import Staging, check_folder

    from usv_mj.jobs.manoeuvres import run_manoeuvre

    scenarios, skipped = {}, []
    for v in kinds:                                     # every vessel's input checked before any run
        try:
            scenarios[v] = scenario_for(v)
        except ScenarioError as exc:
            if not skip_refused:
                raise
            skipped.append((v, str(exc)))
    kinds = [v for v in kinds if v in scenarios]
    if not kinds:
        raise ScenarioError(f"manoeuvre {kind}: no vessel can run it ("
                            + "; ".join(f"{v}: {why}" for v, why in skipped) + ")")
    names = [folder_name(v) for v in kinds]
    if len(set(names)) != len(names):
        raise ScenarioError(f"--vessel: two vessels share the folder name {names!r}")
    check_folder(out, overwrite)
    stage = Staging(out)
    committed = False
    try:
        rows, tracks, jobs = [], {}, {}
        for vessel, name in zip(kinds, names):
            result = run_manoeuvre(scenarios[vessel], plant_kind=plant_kind, out_dir=stage.path / name, video=video,
                                   progress=progress, render_options=render_options)
            job = jobs[vessel] = result["job"]
            if "options" not in result:
                raise ScenarioError(f"--vessel {vessel}: the run {job.summary.get('status')}: "
                                    f"{job.summary.get('stop_reason')}")
            rec = job.record
            k0 = int(np.searchsorted(rec["t"], result["options"].get("approach_s", 0.0)))
            along, across = course_frame(rec["x"], rec["y"], rec["psi"], k0)
            row = {"vessel": vessel, "folder": name, "length_m": result["length_m"], "plant": result["plant"],
                   "status": result["status"], "rudder": rudder_label(result), "options": result["options"],
                   "measures": {k: v for k, v in result["measures"].items() if not isinstance(v, (list, dict))},
                   "saturated_fraction": result["saturated_fraction"], "imo": result["imo"]}
            rows.append(row)
            tracks[vessel] = {"along": along, "across": across, "length": result["length_m"], "rudder": row["rudder"]}
            if job.summary.get("job_stopped") or job.summary.get("status") == "interrupted":
                break          # Ctrl-C or a signal: the vessels done so far are written, the rest not run
        plant = rows[0]["plant"] if rows else plant_kind
        files = {"figure": draw_tracks(kind, tracks, stage.path / "manoeuvre_vessels.png", f"{plant} plant")}
        files["json"] = stage.path / "vessels.json"
        write_json(files["json"], {"kind": kind, "plant": plant, "vessels": rows,
                                   "skipped": [{"vessel": v, "reason": why} for v, why in skipped]})
        md = [f"# {kind} on {len(rows)} vessels ({plant} plant)", "",
              "Each vessel's own run (its folder) holds its log, report and figures; the \"rudder\" is the "
              "vessel's (docs/manoeuvres.md).", "", *table_lines(kind, rows), "",
              "![tracks](manoeuvre_vessels.png)", ""]
        if skipped:
            md += ["Not run (the manoeuvre is not available on them):", ""] + \
                [f"- `{v}`: {why}" for v, why in skipped] + [""]
        files["report"] = stage.path / "vessels.md"
        files["report"].write_text("\n".join(md))
        stage.commit()
        committed = True
    finally:
        if not committed:
            stage.discard()
    return {"rows": rows, "files": {k: out / Path(v).name for k, v in files.items()}, "jobs": jobs,
            "skipped": skipped}
