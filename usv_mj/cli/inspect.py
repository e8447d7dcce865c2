"""``usv-mj inspect RUN.mcap``: topics, message counts, duration, metadata and status of a run log.

Exit codes: 0 read (also a cut or damaged file, which is reported), 2 missing file / not an MCAP run log.
"complete" means every check held: the footer and the closing magic are there, and the CRCs of
every chunk, of the data section (DataEnd) and of the summary (footer) match; otherwise the file is
"cut short" (it ends early) or "damaged" (a CRC does not hold), with the reason (``problem`` in --json).
"""

from __future__ import annotations

import json
import sys

from usv_mj.cli import args as flags
from usv_mj.cli.commands import COMMANDS


def add_arguments(p) -> None:
    p.add_argument("run", metavar="RUN.mcap", help="a run log written by usv-mj run (or a run folder holding run.mcap)")
    flags.add_json_argument(p)


def _fmt_size(n: int) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000.0
    return str(n)


@COMMANDS.register("inspect", arguments=add_arguments,
                   help="topics, message counts, duration and metadata of a run log (.mcap)",
                   description="Say what a run log (.mcap) holds: its runs, topics, message counts, duration, "
                   "status and\nmetadata, and whether the file is complete. --json prints the same as one JSON "
                   "object.")
def run(args) -> int:
    from pathlib import Path

    from usv_mj.outputs.log.reader import RunLogReadError, companion_files, scan_summary

    path = Path(args.run)
    if path.is_dir() and (path / "run.mcap").is_file():
        path = path / "run.mcap"
    if path.exists() and not path.is_file():  # a folder without run.mcap, a named pipe
        print(f"usv-mj inspect: error: {path}: is not a regular file (a run log .mcap)", file=sys.stderr)
        return 2
    try:
        info = scan_summary(path)
    except RunLogReadError as exc:
        print(f"usv-mj inspect: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"usv-mj inspect: error: cannot read {path}: {exc}", file=sys.stderr)
        return 2
    meta = {}
    runs = {}
    for name, m in info["metadata"]:
        if name == "usv_mj":
            meta = m
        elif "/" in name:
            kind, run = name.split("/", 1)
            runs.setdefault(run, {})[kind] = m
    companions = companion_files(path)
    if getattr(args, "json", False):
        print(json.dumps({**info, "metadata": {n: m for n, m in info["metadata"]},
                          "companions": [str(c) for c in companions]}, indent=1, default=str))
        return 0
    if info["complete"]:
        state = "complete (summary, footer and closing magic present; the chunk, data-section and summary CRCs hold)"
    elif info["damaged"]:
        state = f"DAMAGED: {info['problem']}"
    else:
        state = f"CUT SHORT: {info['problem'] or 'no summary'}"
    print(f"{path}: MCAP run log, {_fmt_size(info['size'])}, {info['chunks']} chunks, {state}")
    t0, t1 = info["start_ns"] / 1e9, info["end_ns"] / 1e9
    print(f"log time: {t0:.3f} .. {t1:.3f} s (duration {t1 - t0:.3f} s)")
    if meta:
        versions = meta.get("versions", "")
        try:
            versions = ", ".join(f"{k} {v}" for k, v in json.loads(versions).items())
        except (ValueError, AttributeError):
            pass
        print(f"preset: {meta.get('preset', '?')}  source: {meta.get('source', '?')}")
        version = meta.get("usv_mj_version")
        if meta.get("git_commit") and meta["git_commit"] != "unknown":
            print(f"usv_mj {version or '?'}, git commit {meta['git_commit']}"
                  + ("  (uncommitted changes)" if meta.get("git_dirty") == "true" else ""))
        elif version:
            print(f"usv_mj {version} (an installed package, not a git checkout)")
        else:   # a log written before the version was recorded
            print(f"git commit: {meta.get('git_commit', '?')}")
        try:
            plugins = json.loads(meta.get("plugins") or "{}")
        except ValueError:
            plugins = {}
        for kind, where in plugins.items():
            what = (f"{where['distribution']} {where.get('version') or '?'}" if where.get("distribution") else
                    where.get("file") or where.get("source", "?"))
            print(f"plug-in {kind}: {what} (module {where.get('module', '?')})")
        print(f"created: {meta.get('created_utc', '?')}  schema: {meta.get('schema_version', '?')}")
        print(f"versions: {versions}")
    for run, parts in runs.items():
        start = parts.get("run_start", {})
        end = parts.get("run_end")
        try:
            rmeta = json.loads(start.get("metadata", "{}"))
        except ValueError:
            rmeta = {}
        desc = f"run {run} ({start.get('prefix', '?')}): plant {rmeta.get('plant', '?')}, controller " \
               f"{rmeta.get('controller', '?')}, dt {start.get('control_period_s', '?')} s"
        if end is not None:
            desc += f"; status {end.get('status')}, {end.get('rows')} rows"
            if end.get("stop_reason"):
                desc += f"; stop reason: {end['stop_reason']}"
        else:
            desc += "; no end record (the run was cut off)"
        print(desc)
    print("topics (messages, schema, encoding):")
    width = max((len(t) for t in info["topics"]), default=10)
    swidth = max((len(t["schema"]) for t in info["topics"].values()), default=10)
    for topic, t in info["topics"].items():
        print(f"  {topic:<{width}}  {t['count']:>9}  {t['schema']:<{swidth}}  {t['encoding']}")
    for c in companions:
        print(f"companion log beside it: {c.name} (read with it by usv-mj plot / read_run; inspect it on its own)")
    if meta.get("companion_of"):
        try:
            main_file = json.loads(meta["companion_of"]).get("file", "?")
        except (ValueError, AttributeError):
            main_file = "?"
        print(f"companion of: {main_file} (the main run's log)")
    if info["attachments"]:
        print("attachments: " + ", ".join(f"{k} ({_fmt_size(v)})" for k, v in info["attachments"].items()))
    return 0
