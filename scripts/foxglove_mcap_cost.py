"""Writer CPU per row: today's hand-laid MCAP writer (usv_mj.outputs.log) against foxglove-sdk's MCAP writer.

    python scripts/foxglove_mcap_cost.py [SECONDS]      (default 30 s of the paper run, 1 ms steps)

Today's writer is timed over the whole job it does (protobuf and JSON layout of every topic, chunks,
zstd, indexes), in this process (``background=False``). The SDK writer is timed on the same
messages, already encoded (read back from today's file), logged with ``Channel.log`` into
``foxglove.open_mcap``: its cost leaves out the encoding, so it is a lower bound for adopting it.
Prints both in microseconds of CPU per row (a row: one control step, all its topics).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import foxglove
from mcap.reader import make_reader

from usv_mj import load_scenario, simulate
from usv_mj.outputs.log import RunLogWriter


def main(seconds: float = 30.0) -> None:
    scenario = load_scenario(overrides={"duration": seconds, "plant": {"kind": "analytic"}})
    record = simulate(scenario)
    n = len(record)
    tmp = Path(tempfile.mkdtemp(prefix="usv_mj_fgcost_"))
    best_ours = best_sdk = float("inf")
    for _ in range(3):
        path = tmp / "ours.mcap"
        path.unlink(missing_ok=True)
        c0 = time.process_time()
        with RunLogWriter(path, scenario, background=False) as writer:
            sink = writer.sink("main")
            sink.start(record)
            for lo in range(0, n, 2000):
                sink.rows(record, lo, min(n, lo + 2000))
            sink.finish(record)
        best_ours = min(best_ours, time.process_time() - c0)
    with open(tmp / "ours.mcap", "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        messages = [(ch.id, m.log_time, m.data) for _, ch, m in reader.iter_messages()]
    for k in range(3):
        ctx = foxglove.Context()
        out = tmp / f"sdk{k}.mcap"
        c0 = time.process_time()
        mcap = foxglove.open_mcap(out, context=ctx)
        chans = {}
        for cid, ch in summary.channels.items():
            s = summary.schemas[ch.schema_id]
            chans[cid] = foxglove.Channel(ch.topic, schema=foxglove.Schema(name=s.name, encoding=s.encoding, data=s.data),
                                          message_encoding=ch.message_encoding, context=ctx)
        for cid, t, data in messages:
            chans[cid].log(data, log_time=t)
        mcap.close()
        best_sdk = min(best_sdk, time.process_time() - c0)
    print(f"{n} rows, {len(messages)} messages ({len(messages) / n:.2f} a row)")
    print(f"usv_mj.outputs.log (encode + write): {best_ours / n * 1e6:.2f} us CPU a row, "
          f"{(tmp / 'ours.mcap').stat().st_size / 1e6:.1f} MB")
    from importlib.metadata import version

    print(f"foxglove-sdk {version('foxglove-sdk')} MCAPWriter (log only, "
          f"messages pre-encoded): {best_sdk / n * 1e6:.2f} us CPU a row, {(tmp / 'sdk0.mcap').stat().st_size / 1e6:.1f} MB")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 30.0)
