"""Issue 28 item 5: the outputs of a run say only what is true.

A harbour run in a sea (the example harbour_gap, found by name, with waves, current and wind set as
a user writes them): every path the console lists is in the output folder and every output is
listed; summary.json and report.md give each direction in the user's convention (compass, waves
and wind coming from, the current setting toward), never the internal direction_deg; the report of
a run without a baseline has no baseline column and no placeholder.
"""

import json
import re

from usv_mj.cli.main import main

SEA = {"sea.waves.hs": 0.2, "sea.waves.tp": 2.0, "sea.waves.from_deg": 250.0, "sea.waves.components": 16,
       "sea.current.speed": 0.3, "sea.current.toward_deg": 60.0, "sea.wind.speed": 5.0, "sea.wind.from_deg": 200.0}


def test_a_harbour_run_in_a_sea_lists_and_writes_only_what_is_true(tmp_path, capsys):
    out = tmp_path / "harbour"
    sets = [a for key, value in SEA.items() for a in ("--set", f"{key}={value}")]
    assert main(["run", "--scenario", "harbour_gap", "--plant", "analytic", "--duration", "1", "--no-video",
                 "--no-baseline", "-q", *sets, "--out", str(out)]) == 0
    console = capsys.readouterr().out
    listed = re.search(rf"outputs in {re.escape(str(out))}/: (.*)$", console, re.M).group(1).split(", ")
    for name in listed:
        path = out / name.rstrip("/")
        assert path.is_dir() if name.endswith("/") else path.is_file(), (name, console)
    on_disk = {p.name + ("/" if p.is_dir() else "") for p in out.iterdir() if not p.name.startswith(".")}
    assert set(listed) == on_disk
    assert {"sea_spectrum.png", "sea_loads.png"} <= {p.name for p in (out / "figures").iterdir()}

    summary_text = (out / "summary.json").read_text()
    sea = json.loads(summary_text)["sea"]
    assert sea["waves"]["from_deg"] == SEA["sea.waves.from_deg"]
    assert sea["current"]["toward_deg"] == SEA["sea.current.toward_deg"]
    assert sea["wind"]["from_deg"] == SEA["sea.wind.from_deg"]
    report = (out / "report.md").read_text()
    assert "direction_deg" not in summary_text and "direction_deg" not in report

    line = next(ln for ln in report.splitlines() if ln.startswith("Sea: "))
    waves = re.search(r"waves Hs (\S+) m, Tp (\S+) s, from (\S+) deg", line)
    current = re.search(r"current (\S+) m/s toward (\S+) deg", line)
    wind = re.search(r"wind (\S+) m/s from (\S+) deg", line)
    assert [float(v) for v in waves.groups()] == [SEA["sea.waves.hs"], SEA["sea.waves.tp"], SEA["sea.waves.from_deg"]]
    assert [float(v) for v in current.groups()] == [SEA["sea.current.speed"], SEA["sea.current.toward_deg"]]
    assert [float(v) for v in wind.groups()] == [SEA["sea.wind.speed"], SEA["sea.wind.from_deg"]]

    assert "baseline |" not in report and "BASELINE" not in report and "None" not in report
    header = next(ln for ln in report.splitlines() if ln.startswith("| error | t |"))
    rows = [ln for ln in report.splitlines() if re.match(r"\| (x|y|psi) \[", ln)]
    assert header.count("|") == rows[0].count("|") == 6          # error, t, this run, two paper tables
