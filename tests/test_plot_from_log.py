"""Everything we make of a run can be made again from its MCAP log alone (issue 5)."""

import hashlib

from usv_mj import load_scenario
from usv_mj.cli.main import main
from usv_mj.outputs.figures import draw_figures
from usv_mj.jobs.run import run_job
from usv_mj.outputs.log import read_run


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_figures_from_the_log_equal_those_from_the_live_run(tmp_path):
    scenario = load_scenario(preset="paper", overrides={"duration": 22.0, "plant": {"kind": "analytic"}})
    live = run_job(scenario, tmp_path / "live", video=False, progress=False)
    log = read_run(tmp_path / "live" / "run.mcap")
    assert log.record.status == "completed" and len(log.record) == len(live.record)
    again = draw_figures(log.record, tmp_path / "again", log.baseline)
    for path in again:
        assert digest(path) == digest(tmp_path / "live" / "figures" / path.name), path.name
    # and through the command line, next to the log
    assert main(["plot", str(tmp_path / "live" / "run.mcap"), "--out", str(tmp_path / "cli")]) == 0
    for path in again:
        assert digest(tmp_path / "cli" / "figures" / path.name) == digest(path)
    report = (tmp_path / "cli" / "report.md").read_text()
    assert "Tables 1 and 2" in report or "Table 1" in report
