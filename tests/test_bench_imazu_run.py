"""usv-mj bench on Imazu situations through the sweep's engine (issue 35 item 5): a user's avoidance
controller from a temporary folder (a plug-in) ranked beside the built-ins, and one worker against
two giving the same rows and the same report.

A short suite (the placement of the shipped one at R = 10 L and 1.25 T: about 40 s simulated per
episode; the shipped suite's own geometry is tested in tests/test_bench_imazu.py): situations 1
(head-on) and 2 (crossing, give way), calm water, the paper hull, four controllers.
"""

from __future__ import annotations

import json
import os
import textwrap

from usv_mj.jobs.bench import run_bench
from usv_mj.jobs.bench.suite import load_suite
from usv_mj.jobs.sweep.runner import TIMING_COLUMNS, read_results

SUITE = """
name = "imazu-short"
seed = 7
plant = "analytic"
controllers = [{ name = "no-avoidance", kind = "los", set = { "controller.crab_compensation" = false } },
               "sbmpc", "vo", { name = "starboard30", kind = "my_colav:Starboard30" }]
[conditions.calm]
[[tasks]]
name = "encounters"
base = "paper"
set = { "control_period" = 0.02 }
imazu = { cases = [1, 2], k_R = 10.0, duration_T = 1.25 }
"""

PLUGIN = '''
"""A user's avoidance law in a folder of its own: 30 deg to starboard, at full speed, while another
vessel is within 10 own lengths; its path follower and its view of the traffic are usv_mj's."""
import math

from usv_mj.controllers.los import LOSController, path_errors
from usv_mj.controllers.sbmpc import AvoidanceOverLOS, SBMPCGains


class Starboard30(AvoidanceOverLOS):
    name = "starboard30"
    options = SBMPCGains    # the LOS keys, replan_period_s, d_relevant_L, stand_on, ...

    @classmethod
    def from_scenario(cls, gains, scenario):
        follower = LOSController.from_scenario(gains.los_gains(), scenario)
        return cls(gains, follower, float(scenario.vessel.model.dimensions.L))

    def kernel(self):
        return self._kernel()

    def _choose(self, state, reference, targets, codes, length, speed, duty):
        near = any(math.hypot(x - state[0], y - state[1]) < 10.0 * length for x, y, *_ in targets)
        offset = -math.radians(30.0) if near and not duty else 0.0
        return offset, 1.0, path_errors(state, reference)[0] + offset, 0.0
'''

CONTROLLERS = ["no-avoidance", "sbmpc", "vo", "starboard30"]


def _metrics(rows):
    """The rows without the columns that time the machine."""
    return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in rows]


def test_a_plugin_is_ranked_beside_the_built_ins_and_two_workers_equal_one(tmp_path, monkeypatch):
    folder = tmp_path / "plug"
    folder.mkdir()
    (folder / "my_colav.py").write_text(textwrap.dedent(PLUGIN))
    # as a user would: PYTHONPATH=folder usv-mj bench suite.toml (the workers inherit the environment)
    monkeypatch.syspath_prepend(str(folder))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(folder), os.environ.get("PYTHONPATH", "")]))
    (tmp_path / "suite.toml").write_text(SUITE)
    suite = load_suite(tmp_path / "suite.toml")
    assert len(suite.plan.runs) == 2 * len(CONTROLLERS)

    one = run_bench(suite, tmp_path / "one", workers=1, progress=False, echo=None, draw=False)
    two = run_bench(suite, tmp_path / "two", workers=2, progress=False, echo=None, draw=False)
    assert one.complete and two.complete
    a, _ = read_results(tmp_path / "one" / "results.parquet")
    b, _ = read_results(tmp_path / "two" / "results.parquet")
    assert all(r["status"] == "ok" for r in a), [r.get("reason") for r in a]
    assert _metrics(a) == _metrics(b)
    assert (tmp_path / "one" / "report.md").read_text() == (tmp_path / "two" / "report.md").read_text()
    assert (tmp_path / "one" / "leaderboard.json").read_text() == (tmp_path / "two" / "leaderboard.json").read_text()

    # the plug-in is on the leaderboard, ranked over the same tables and metrics as the built-ins
    board = json.loads((tmp_path / "one" / "leaderboard.json").read_text())
    assert set(board["ranking"]) == set(CONTROLLERS)
    assert len({board["ranking"][c]["ranked"] for c in CONTROLLERS}) == 1
    report = (tmp_path / "one" / "report.md").read_text()
    assert all(f"`{c}`" in report for c in CONTROLLERS)

    # and it did its own thing: it turned away to starboard and kept clear where "no avoidance" collided
    rows = {(r["vary.situation"], r["vary.controller"]): r for r in a}
    for case in (1, 2):
        assert rows[(case, "no-avoidance")]["m.collision"] is True
        mine = rows[(case, "starboard30")]
        assert mine["m.collision"] is False and mine["m.path_deviation_m"] > 1.98
        assert mine["m.min_range_m"] != rows[(case, "sbmpc")]["m.min_range_m"]
