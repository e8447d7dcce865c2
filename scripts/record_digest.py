"""Digests of the records of a fixed set of runs: a structural change must leave every one unchanged.

A move of code (a module to another folder, a chain written once instead of six times) must keep
every record bit for bit. This script runs the cases below through the public API only
(``load_scenario`` and ``simulate``, which every version has) and prints one line per case: the
SHA-256 of the record's columns (by name, in the order of the record), its status and its events.
Run it on two trees and diff the outputs::

    git worktree add /tmp/before 6874514
    PYTHONPATH=/tmp/before python scripts/record_digest.py > before.txt
    python scripts/record_digest.py > after.txt
    diff before.txt after.txt

``--only SUBSTRING`` runs the cases whose name holds it; ``--list`` prints the names; ``--loops
auto,python,batch`` adds the batched loop (usv_mj.loop.batch: every case of a plant in one batch; its
lines must equal the others').
"""

from __future__ import annotations

import argparse
import hashlib
import sys

# (name, scenario file or None, preset, overrides, controller kind or None, duration [s])
CASES = [
    ("paper", None, "paper", {}, None, 60.0),
    ("paper-pi", None, "paper", {}, "pi", 30.0),
    ("paper-limited", None, "paper-limited", {}, None, 30.0),
    ("harsh", None, "harsh", {}, None, 20.0),
    ("harbour-sea", "harbour_gap", None, {"sea": {"preset": "moderate"}}, None, 40.0),
    ("harbour", "harbour_gap", None, {}, None, 30.0),
    ("otter-los", "los_circle", None, {"vessel": {"kind": "otter"}}, None, 40.0),
    ("otter-ppc-sea", None, "paper", {"vessel": {"kind": "otter"}, "sea": {"preset": "moderate"}}, None, 20.0),
    ("kvlcc2-los", "kvlcc2_los_circle", None, {}, None, 60.0),
    ("kvlcc2-zigzag", "zigzag_10_10", None, {"vessel": {"kind": "kvlcc2"}}, None, 30.0),
    ("all-loads-sea", "all_loads_sea", None, {}, None, 20.0),
    ("head-on-boat", "head_on_boat", None, {}, None, 20.0),
]


def digest(record) -> str:
    h = hashlib.sha256()
    for name in record.column_names:
        h.update(name.encode())
        h.update(record[name].tobytes())
    return h.hexdigest()[:20]


def events(record) -> str:
    h = hashlib.sha256()
    for e in record.events:
        h.update(f"{e.t!r} {e.kind} {e.message}".encode())
    return h.hexdigest()[:12]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="run the cases whose name holds this")
    ap.add_argument("--list", action="store_true", help="print the case names")
    ap.add_argument("--plants", default="analytic,mujoco")
    ap.add_argument("--loops", default="auto,python", help="auto, python and/or batch")
    args = ap.parse_args(argv)
    from usv_mj import load_scenario, simulate

    loops = args.loops.split(",")
    batched = {}   # loop "batch": every case of a plant in one batch (usv_mj.loop.batch), printed in case order
    if "batch" in loops and not args.list:
        from usv_mj.loop.batch import simulate_batch

        for plant in args.plants.split(","):
            cases = [c for c in CASES if args.only in c[0]]
            for controller in {c[4] for c in cases}:
                mine = [c for c in cases if c[4] == controller]
                scenarios = [load_scenario(path, preset=preset, overrides={
                    **overrides, "duration": duration, "plant": {**overrides.get("plant", {}), "kind": plant}})
                    for _, path, preset, overrides, _, duration in mine]
                for case, record in zip(mine, simulate_batch(scenarios, controller_kind=controller)):
                    batched[(case[0], plant)] = record
    for name, path, preset, overrides, controller, duration in CASES:
        if args.only not in name:
            continue
        if args.list:
            print(name)
            continue
        for plant in args.plants.split(","):
            for loop in loops:
                over = {**overrides, "duration": duration, "plant": {**overrides.get("plant", {}), "kind": plant}}
                scenario = load_scenario(path, preset=preset, overrides=over)
                record = batched[(name, plant)] if loop == "batch" else simulate(scenario, controller_kind=controller,
                                                                                  loop=loop)
                print(f"{name:16s} {plant:8s} {loop:6s} rows={record.n_rows:6d} {record.status:10s} "
                      f"{digest(record)} events={len(record.events)}:{events(record)} "
                      f"loop={record.metadata.get('loop')}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
