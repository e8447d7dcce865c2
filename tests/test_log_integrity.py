"""Run logs that never claim more than they hold (issue 27, item 3).

The references are independent of the reader under test: the in-memory RunRecord the log was
written from (rows compared bit for bit), the mcap library's own writer (an unchunked file, a file
whose messages are in reverse time order) and byte-level edits of a real log (cuts, flipped bytes,
a changed character). Each damaged file must either read as a correct prefix of the run, flagged
as cut or damaged, or give one line of error; "complete" only when every byte is what was written.
"""

from __future__ import annotations

import argparse
import io
import json
import random

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from usv_mj.outputs.log import RunLogReadError, RunLogWriter, read_run
from usv_mj.cli.inspect import add_arguments as add_inspect_arguments, run as inspect_command
from usv_mj.scenario.spec import load_scenario
from usv_mj.loop.simulate import simulate

DURATION = 3.0


@pytest.fixture(scope="module")
def logged(tmp_path_factory):
    """A short real log (main run and its PI baseline companion, many small chunks) and the records."""
    scenario = load_scenario(preset="paper", overrides={"duration": DURATION, "plant": {"kind": "analytic"}})
    folder = tmp_path_factory.mktemp("integrity")
    path = folder / "run.mcap"
    with RunLogWriter(path, scenario, rows_per_chunk=250) as writer:
        main = simulate(scenario, sinks=[writer.sink("main")], block=500)
    with RunLogWriter(folder / "baseline.mcap", scenario, companion_of=writer, rows_per_chunk=250) as bw:
        base = simulate(scenario, controller_kind="pi", sinks=[bw.sink("baseline")], block=500)
    return path, main, base


def _same_prefix(got, want) -> bool:
    """``got`` holds the first len(got) rows of ``want``, every column bit for bit."""
    n = len(got)
    if n == 0:
        return True
    if n > len(want) or got.column_names != want.column_names:
        return False
    return all(np.array_equal(got[c].view(np.uint64), want[c][:n].view(np.uint64)) for c in want.column_names)


def _inspect_json(path, capsys) -> dict:
    parser = argparse.ArgumentParser()
    add_inspect_arguments(parser)
    assert inspect_command(parser.parse_args([str(path), "--json"])) == 0
    return json.loads(capsys.readouterr().out)


# --- inspect checks before it says "complete" ------------------------------------------------------


def test_the_intact_log_is_complete(logged, capsys):
    path, main, _ = logged
    info = _inspect_json(path, capsys)
    assert info["complete"] and not info["damaged"] and not info["truncated"], info["problem"]
    log = read_run(path, companions=False)
    assert log.complete and not log.notice and _same_prefix(log.record, main) and len(log.record) == len(main)


@pytest.mark.parametrize("missing", range(1, 9))
def test_a_file_missing_its_last_bytes_is_not_complete(logged, tmp_path, capsys, missing):
    """Before: ``complete: true`` (the footer was read, the closing magic never checked)."""
    path, main, _ = logged
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[:-missing])
    info = _inspect_json(cut, capsys)
    assert info["complete"] is False and "magic" in info["problem"]
    log = read_run(cut, companions=False)
    assert not log.complete and "cut short" in log.notice and _same_prefix(log.record, main)
    assert len(log.record) == len(main)      # every chunk is there: all rows recovered, the file flagged


def _edit(data: bytes, needle: bytes, offset: int = 0) -> bytes:
    """``data`` with one byte (``offset`` into the first ``needle``) changed to another value."""
    at = data.index(needle) + offset
    return data[:at] + bytes([data[at] ^ 0x01]) + data[at + 1:]


@pytest.mark.parametrize("needle, offset, what", [
    (b"usv_mj.State", 7, "schema name"),              # the State schema record (data section, first copy)
    (b"R\x03psi", 4, "schema field name"),           # the json name of State.psi inside the protobuf schema
    (b'"paper"', 2, "metadata"),                      # the preset name in the file's metadata record
])
def test_a_damaged_record_outside_the_chunks_is_not_complete(logged, tmp_path, capsys, needle, offset, what):
    """Before: ``complete: true`` and the damaged text printed as good (the data-section CRC was not checked)."""
    path, _, _ = logged
    data = path.read_bytes()
    assert needle in data, what
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(_edit(data, needle, offset))
    info = _inspect_json(bad, capsys)
    assert info["complete"] is False and info["damaged"] is True and "CRC" in info["problem"], what
    try:
        log = read_run(bad, companions=False)
    except RunLogReadError as exc:           # a schema it cannot use: one line
        assert "\n" not in str(exc)
    else:
        assert not log.complete and "damaged" in log.notice


def _rewrite(src, dst, reverse: bool = False, chunked: bool = True):
    """``src`` written again by the mcap library's own Writer: its schemas, channels, metadata and
    messages (log-time order, or the reverse), chunked (small chunks) or not."""
    with open(src, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        metadata = [(m.name, dict(m.metadata)) for m in reader.iter_metadata()]
        messages = [(c.id, m.log_time, m.data, m.sequence) for _, c, m in reader.iter_messages(log_time_order=True)]
    if reverse:
        messages.reverse()
    with open(dst, "wb") as out:
        w = Writer(out, chunk_size=20000, compression=CompressionType.ZSTD, use_chunking=chunked, enable_data_crcs=True)
        w.start(profile="", library="mcap-python")
        for sid, s in sorted(summary.schemas.items()):
            assert w.register_schema(s.name, s.encoding, s.data) == sid
        for cid, c in sorted(summary.channels.items()):
            assert w.register_channel(c.topic, c.message_encoding, c.schema_id, dict(c.metadata)) == cid
        for name, m in metadata:
            w.add_metadata(name, m)
        for cid, t, data, seq in messages:
            w.add_message(cid, t, data, t, seq)
        w.finish()
    return len(messages)


def test_an_unchunked_log_reads_its_messages(logged, tmp_path, capsys):
    """Before: "completed" with 0 rows (messages outside chunks were not read)."""
    path, main, _ = logged
    flat = tmp_path / "unchunked.mcap"
    _rewrite(path, flat, chunked=False)
    log = read_run(flat, companions=False)
    assert log.complete and len(log.record) == len(main) and _same_prefix(log.record, main)
    info = _inspect_json(flat, capsys)
    assert info["complete"] and info["topics"]["/usv/state"]["count"] == len(main)


def test_messages_in_reverse_time_order_read_in_log_time_order(logged, tmp_path):
    """Before: rows that differ from the original and nothing flagged."""
    path, main, _ = logged
    rev = tmp_path / "reverse.mcap"
    _rewrite(path, rev, reverse=True)
    log = read_run(rev, companions=False)
    assert len(log.record) == len(main) and _same_prefix(log.record, main)
    assert [e.t for e in log.record.events] == sorted(e.t for e in main.events)


# --- what plot and read_run say about a cut log or a cut companion -----------------------------------


def _cut_copy(folder, path, which: str, fraction: float = 0.5):
    folder.mkdir()
    for name in ("run.mcap", "baseline.mcap"):
        data = (path.parent / name).read_bytes()
        (folder / name).write_bytes(data[:int(len(data) * fraction)] if name == which else data)
    return folder / "run.mcap"


@pytest.mark.parametrize("which", ["run.mcap", "baseline.mcap"])
def test_plot_of_a_cut_log_says_so(logged, tmp_path, capsys, which):
    """Before: figures and a report that do not say the log (or only its baseline) is cut."""
    from usv_mj.cli import main as cli

    path, main, base = logged
    run = _cut_copy(tmp_path / "c", path, which)
    log = read_run(run)
    assert which in log.notice and "cut short" in log.notice and "rows up to t = " in log.notice
    cut_rec = log.record if which == "run.mcap" else log.baseline
    assert 0 < len(cut_rec) < len(main) and _same_prefix(cut_rec, main if which == "run.mcap" else base)
    assert f"rows up to t = {cut_rec['t'][-1]:.3f} s" in log.notice
    # a new folder: the copy's own folder holds files no usv_mj command wrote (--overwrite refuses those)
    assert cli.main(["plot", str(run), "--out", str(tmp_path / "plotted")]) == 0
    err = capsys.readouterr().err
    assert "incomplete" in err and which in err
    report = (tmp_path / "plotted" / "report.md").read_text()
    assert "The log is incomplete" in report and which in report


def test_a_companion_cut_before_its_first_chunk_is_named(logged, tmp_path):
    path, _, _ = logged
    data = (path.parent / "baseline.mcap").read_bytes()
    first_chunk = min(c.chunk_start_offset for c in make_reader(io.BytesIO(data)).get_summary().chunk_indexes)
    run = _cut_copy(tmp_path / "c", path, "baseline.mcap", fraction=(first_chunk + 10) / len(data))
    log = read_run(run)
    assert log.baseline is not None and len(log.baseline) == 0
    assert "baseline.mcap: cut short" in log.notice and "baseline no rows" in log.notice


# --- the fuzz: 200 cuts and flipped bytes of a real log ---------------------------------------------


def test_fuzz_cuts_and_flips_give_a_flagged_correct_prefix_or_one_line_of_error(logged):
    path, main, _ = logged
    data = path.read_bytes()
    rng = random.Random(27)
    outcomes = {"prefix": 0, "error": 0}
    for case in range(200):
        if case % 2 == 0:
            cut = rng.randrange(0, len(data))
            bad = data[:cut]
            what = f"cut at {cut} of {len(data)}"
        else:
            at = rng.randrange(0, len(data))
            bad = data[:at] + bytes([data[at] ^ rng.randrange(1, 256)]) + data[at + 1:]
            what = f"byte {at} of {len(data)} changed"
        try:
            log = read_run(io.BytesIO(bad), companions=False)
        except RunLogReadError as exc:
            assert "\n" not in str(exc), what
            outcomes["error"] += 1
            continue
        assert not log.complete and log.notice, f"{what}: read as complete"
        rec = log.record
        assert _same_prefix(rec, main), f"{what}: rows that are not the run's ({log.notice})"
        outcomes["prefix"] += 1
    assert outcomes["prefix"] > 50, outcomes


def test_render_reads_the_notice_of_a_cut_log(logged, tmp_path, capsys):
    """``usv-mj render`` prints the notice before drawing (its log is read by load_run_log)."""
    from usv_mj.cli.render import run as run_command
    from usv_mj.outputs.render.video import load_run_log

    path, main, _ = logged
    run = _cut_copy(tmp_path / "c", path, "run.mcap")
    log, mcap = load_run_log(run.parent)
    assert mcap == run and "run.mcap: cut short" in log.notice
    import argparse

    from usv_mj.cli.render import add_arguments

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    # an --out that is refused (not a video file name): the command stops before any GL work, after the notice
    assert run_command(parser.parse_args([str(run), "--out", str(tmp_path / "notes.txt")])) == 2
    assert "the log is incomplete" in capsys.readouterr().err
