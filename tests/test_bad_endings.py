"""Issue 38, a job that ends badly loses nothing (causes 7, 9).

Cause 7: ``run --overwrite`` whose new run fails (an output that cannot be written: a full disk
while the figures are drawn) keeps the earlier run in --out, byte for byte, and puts what the
failed run wrote beside it, named in the one line it prints; the next job into --out clears it.
The benchmark and the sweep (usv_mj.outputs.outdir.results_folder) keep their earlier results
the same way. Cause 9: a plug-in that calls ``sys.exit`` mid-run ends the run as a failure with
its outputs (exit 1), not the program with exit 0 and no output folder. Both hold for a fleet
(``[[vessels]]``: run.mcap and a ``vessel-NAME.mcap`` per other vessel, usv_mj.jobs.fleet).
"""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import numpy as np
import pytest

from usv_mj.cli.main import main

FAST = ["run", "--plant", "analytic", "--no-video", "--no-baseline", "-q", "--duration", "0.5"]


def snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def one_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# --- cause 7: --overwrite keeps the earlier output until the new one has ended ---------------------


def test_a_failed_overwrite_keeps_the_earlier_run(tmp_path, capsys, monkeypatch):
    """Before: the cut run replaced the good one (no figures/, a summary saying job_stopped)."""
    import usv_mj.jobs.run as job

    out = tmp_path / "out"
    assert main([*FAST, "--out", str(out)]) == 0
    before = snapshot(out)
    capsys.readouterr()

    def full_disk(record, folder, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(Path(folder) / "fig1_xy.png"))

    monkeypatch.setattr(job, "draw_figures", full_disk)
    assert main([*FAST, "--out", str(out), "--overwrite"]) == 1
    line = one_line(capsys)
    assert snapshot(out) == before
    aside = [p for p in tmp_path.iterdir() if p.name.startswith(".out.failed-")]
    assert len(aside) == 1, sorted(p.name for p in tmp_path.iterdir())
    assert f"{out} still holds the earlier run" in line and f"{aside[0]}/" in line, line
    assert "No space left on device" in line and ".staging" not in line, line
    summary = json.loads((aside[0] / "summary.json").read_text())
    assert "while drawing the figures" in summary["job_stopped"]
    assert "figures/" in summary["missing_outputs"]

    monkeypatch.undo()
    assert main([*FAST, "--out", str(out), "--overwrite"]) == 0       # the next run clears it
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_failed_first_run_still_goes_into_place(tmp_path, capsys, monkeypatch):
    """Nothing to keep: the failed run's summary and report go into --out as before."""
    import usv_mj.jobs.run as job

    def full_disk(record, folder, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(Path(folder) / "fig1_xy.png"))

    monkeypatch.setattr(job, "draw_figures", full_disk)
    out = tmp_path / "out"
    assert main([*FAST, "--out", str(out)]) == 1
    assert json.loads((out / "summary.json").read_text())["missing_outputs"] == ["figures/"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_results_folder_keeps_the_earlier_results_when_the_job_fails(tmp_path):
    """The benchmark's and the sweep's --overwrite (outdir.results_folder): before, a job that
    failed replaced the earlier results with its own cut ones."""
    from usv_mj.outputs.outdir import record, results_folder

    out = tmp_path / "bench"
    out.mkdir()
    (out / "results.parquet").write_bytes(b"the earlier results")
    record(out, fresh=True)
    before = snapshot(out)
    with pytest.raises(OSError) as failed:
        with results_folder(out) as folder:
            assert folder != out
            (folder / "results.parquet").write_bytes(b"half")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(folder / "results.parquet"))
    assert snapshot(out) == before
    aside = [p for p in tmp_path.iterdir() if p.name.startswith(".bench.failed-")]
    assert len(aside) == 1 and (aside[0] / "results.parquet").read_bytes() == b"half"
    assert failed.value.filename == str(aside[0] / "results.parquet")      # where the file is now
    assert failed.value.__notes__ == [f"{out} still holds the earlier output; what this job wrote is in "
                                      f"{aside[0]}/ until the next job into it"]
    with results_folder(out) as folder:               # one that ends replaces them, and clears the failed one
        (folder / "results.parquet").write_bytes(b"new")
    assert (out / "results.parquet").read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench"]


# --- cause 9: sys.exit in a plug-in ------------------------------------------------------------------


class Quitter:
    """A plug-in controller that ends the program at t = 0.2 s (a hostile or careless plug-in)."""

    name, diagnostic_fields = "quitter", ()

    @classmethod
    def from_scenario(cls, gains, scenario):
        return cls()

    def reset(self):
        pass

    def __call__(self, t, x, ref):
        if t >= 0.2:
            raise SystemExit(0)
        return 0.0, 0.0, np.zeros(0)


@pytest.fixture
def quitter():
    from usv_mj import CONTROLLERS

    CONTROLLERS.register("quitter")(Quitter)
    try:
        yield "quitter"
    finally:
        CONTROLLERS.unregister("quitter")


def test_a_plugin_calling_sys_exit_fails_the_run_with_its_outputs(tmp_path, capsys, quitter):
    """Before: exit 0 and no output folder (the SystemExit passed every handler)."""
    out = tmp_path / "out"
    assert main([*FAST, "--set", f"controller.kind={quitter}", "--out", str(out)]) == 1
    line = one_line(capsys)
    assert "sys.exit(0)" in line and "test_bad_endings" in line, line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and "sys.exit(0)" in summary["stop_reason"]
    from usv_mj.outputs.log import read_run

    log = read_run(out / "run.mcap")
    assert log.complete and log.record.status == "failed"
    assert log.record.value("t", -1) == pytest.approx(0.199, abs=1e-12)   # every row before the exit


def test_simulate_reports_a_plugins_sys_exit_as_an_error(quitter):
    from usv_mj import load_scenario, simulate
    from usv_mj.core.errors import PluginExit

    sc = load_scenario(preset="paper", overrides={"duration": 0.5, "plant": {"kind": "analytic"},
                                                  "controller": {"kind": quitter}, "baseline": {"enabled": False}})
    with pytest.raises(PluginExit, match=r"test_bad_endings .*sys\.exit\(0\)"):
        simulate(sc)


# --- a fleet ([[vessels]]): the same endings, every vessel's log kept -------------------------------


FLEET = """
preset = "paper"
duration = 0.5
control_period = 0.01
[plant]
kind = "analytic"

[[vessels]]
name = "own"
own_ship = true
steer = "keep"
speed = 0.6
initial = {{ eta = [0.0, 0.0, 1.5707963267948966], nu = [0.6, 0.0, 0.0] }}

[[vessels]]
name = "target"
initial = {{ eta = [0.0, 30.0, -1.5707963267948966], nu = [0.6, 0.0, 0.0] }}
{target}
"""


def fleet_args(tmp_path: Path, out: Path, target: str = 'steer = "keep"\nspeed = 0.6') -> list:
    scenario = tmp_path / "fleet.toml"
    scenario.write_text(FLEET.format(target=target))
    return ["run", "--scenario", str(scenario), "--plant", "analytic", "--no-video", "-q", "--out", str(out)]


def test_a_failed_fleet_overwrite_keeps_the_earlier_run(tmp_path, capsys, monkeypatch):
    """Before: the fleet's job put its cut run in place of the earlier one (no fleet figures, no
    summary.json) and said only the OSError."""
    import usv_mj.jobs.fleet as fleet_job

    out = tmp_path / "out"
    args = fleet_args(tmp_path, out)
    assert main(args) == 0
    before = snapshot(out)
    assert {"run.mcap", "vessel-target.mcap", "summary.json"} <= set(before)
    capsys.readouterr()

    def full_disk(record, folder, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(Path(folder) / "fleet_tracks.png"))

    monkeypatch.setattr(fleet_job, "draw_fleet_figures", full_disk)
    assert main([*args, "--overwrite"]) == 1
    line = one_line(capsys)
    assert snapshot(out) == before
    aside = [p for p in tmp_path.iterdir() if p.name.startswith(".out.failed-")]
    assert len(aside) == 1, sorted(p.name for p in tmp_path.iterdir())
    assert {"run.mcap", "vessel-target.mcap", "traceback.txt"} <= {p.name for p in aside[0].iterdir()}
    assert f"{out} still holds the earlier run" in line and f"{aside[0]}/" in line, line
    assert "No space left on device" in line and ".staging" not in line, line


def test_a_fleets_plugin_calling_sys_exit_fails_the_run_with_every_vessels_log(tmp_path, capsys, quitter):
    """Before: the SystemExit passed the fleet's loop and job: exit 0, the logs without an end."""
    out = tmp_path / "out"
    assert main(fleet_args(tmp_path, out, f'controller = {{ kind = "{quitter}" }}')) == 1
    line = one_line(capsys)
    assert "sys.exit(0)" in line and "test_bad_endings" in line, line
    from usv_mj.outputs.log import read_run

    log = read_run(out / "run.mcap")             # vessel-target.mcap read with it
    assert log.complete and set(log.runs) == {"main", "target"}
    for run in log.runs.values():
        assert run.status == "failed" and "sys.exit(0)" in run.stop_reason
    # the target's controller quit at the 21st step (t = 20 * 0.01 s), after the own ship's row of it:
    # every vessel's rows end at the last whole step, one before
    for run in log.runs.values():
        assert len(run) == 20 and run.value("t", -1) == pytest.approx(19 * 0.01, abs=1e-12)
