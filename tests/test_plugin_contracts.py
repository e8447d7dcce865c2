"""Issue 38: plug-in contracts checked when the plug-in is loaded, and a plug-in's failure named as
the plug-in's (its module and class, the contract, the fix), never as "internal error ... a
defect of usv_mj" nor as a bare AttributeError deep inside.

- cause 16: a plug-in's success criterion. Declared by a controller it is checked and registered
  when the controller is loaded (no need to add it to CRITERIA by hand; a broken one is refused
  before the run); the record names its class, so a later process (``usv-mj plot``) imports it
  back, or judges "not judged" and says why; an ``evaluate`` that raises or returns what the
  contract does not allow (None, NaN) leaves the run not judged with the error in its block; a
  ``first_violation_s`` of None (allowed) reads in every output.
- cause 17: a plug-in's factory (usv_mj.core.registry.Entry.make) is held to its registry's
  contract: a signature that cannot take (options, scenario, **context) (a trajectory without
  ``duration=``), an exception of its own, a part without the registry's interface (an entry-point
  vessel factory returning a dict) raise PluginContractError naming it; a subclass of a registered
  class named by ``module:Name`` without ``options`` takes its registered parent's; numba's
  compiler errors read as one line (what failed, where), naming a plug-in's kernel.
- cause 10's refusal at load: a controller whose kernel's diagnostics do not fit its declared
  fields is refused by ``usv-mj run`` before anything is written.
"""

from __future__ import annotations

import sys
import textwrap

import numpy as np
import pytest

import usv_mj
from usv_mj.core.errors import PluginContractError
from usv_mj.record import criteria
from usv_mj.record.criteria import criterion_of, criterion_of_record, judge
from usv_mj.record.summary import outcome_sentence, summarize, verdict
from usv_mj.scenario.spec import load_scenario

PLUGIN = textwrap.dedent('''
    import math
    import os
    from dataclasses import dataclass

    import numpy as np

    from usv_mj.controllers.los import LOSController, LOSGains


    @dataclass(frozen=True)
    class EndClose:
        """Passed when the hull ends within radius_m of the reference point."""
        radius_m: float = 5.0
        kind = "end_close"
        noun = "the end radius"

        def describe(self):
            return f"the hull ends within {self.radius_m:g} m of the reference"

        def to_dict(self):
            return {"kind": self.kind, "radius_m": self.radius_m}

        def evaluate(self, record):
            mode = os.environ.get("END_CLOSE_MODE", "ok")
            if mode == "raise":
                raise ValueError("boom")
            if mode == "none":
                return None
            d = math.hypot(record["x"][-1] - record["x_d"][-1], record["y"][-1] - record["y_d"][-1])
            passed = bool(d < self.radius_m)
            if mode == "nan":
                passed = float("nan")
            return {"kind": self.kind, "noun": self.noun, "description": self.describe(), "passed": passed,
                    "violations": None if passed else 1, "first_violation_s": None, "judged_steps": 1,
                    "distance_m": float("nan") if mode == "nan-distance" else d}


    class Ctrl(LOSController):
        options = LOSGains
        criterion = EndClose()


    class Tight(LOSController):
        options = LOSGains
        criterion = EndClose(radius_m=1e-9)


    @dataclass(frozen=True)
    class NoKindInDict(EndClose):
        kind = "no_kind_in_dict"
        def to_dict(self):
            return {"radius_m": self.radius_m}


    class BadDict(LOSController):
        options = LOSGains
        criterion = NoKindInDict()


    @dataclass(frozen=True)
    class Impostor(EndClose):
        kind = "path_tolerance"            # a built-in's kind


    class Stealing(LOSController):
        options = LOSGains
        criterion = Impostor()
''')


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    (tmp_path / "crit_plugin.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    for kind in ("end_close", "no_kind_in_dict"):
        monkeypatch.delitem(criteria.CRITERIA, kind, raising=False)
    sys.modules.pop("crit_plugin", None)
    import crit_plugin
    yield crit_plugin
    for kind in ("end_close", "no_kind_in_dict"):
        criteria.CRITERIA.pop(kind, None)
    sys.modules.pop("crit_plugin", None)


def _scenario(kind, **over):
    return load_scenario(preset="paper", overrides={"duration": 1.0, "baseline": {"enabled": False},
                                                    "controller": {"kind": kind}, **over})


def _forget(plugin):
    """What a fresh process knows: the plug-in's criterion is neither registered nor imported."""
    criteria.CRITERIA.pop("end_close", None)
    sys.modules.pop("crit_plugin", None)


def test_a_criterion_not_added_by_hand_is_registered_at_load_and_named_in_the_record(plugin):
    rec = usv_mj.simulate(_scenario("crit_plugin:Ctrl"), plant_kind="analytic")
    assert criteria.CRITERIA["end_close"] is plugin.EndClose
    assert rec.metadata["criterion"] == {"kind": "end_close", "radius_m": 5.0, "class": "crit_plugin:EndClose"}
    s = summarize(rec)
    assert s["criterion"]["passed"] is True and verdict(s["criterion"]) == "passed"
    # another process: the class is imported back from the record
    _forget(plugin)
    back = criterion_of_record(rec)
    assert type(back).__name__ == "EndClose" and back.radius_m == 5.0


def test_a_log_of_a_criterion_that_cannot_be_imported_is_not_judged_with_the_reason(plugin):
    rec = usv_mj.simulate(_scenario("crit_plugin:Ctrl"), plant_kind="analytic")
    rec.metadata["criterion"] = {**rec.metadata["criterion"], "class": "gone_module:EndClose"}
    _forget(plugin)
    c = criterion_of_record(rec)
    assert c.kind == "not_judged"
    assert "success criterion 'end_close' of the plug-in gone_module:EndClose cannot be loaded here" in c.describe()
    assert summarize(rec)["criterion"]["passed"] is None


def test_plot_reads_the_log_of_a_plugin_criterion(plugin, tmp_path):
    from usv_mj.cli.main import main

    out = tmp_path / "run"
    assert main(["run", "--plant", "analytic", "--set", "controller.kind=crit_plugin:Ctrl", "--duration", "1",
                 "--no-baseline", "--no-video", "-q", "--out", str(out)]) == 0
    _forget(plugin)
    assert main(["plot", str(out / "run.mcap"), "--out", str(tmp_path / "plot")]) == 0
    assert ("judged by its own criterion: the hull ends within 5 m of the reference. Outcome: **passed**"
            in (tmp_path / "plot" / "report.md").read_text())


@pytest.mark.parametrize("mode, problem", [
    ("raise", "evaluate raised ValueError: boom"),
    ("none", "evaluate returned a NoneType instead of a dict"),
    ("nan", "evaluate returned passed = nan (True, False or None)"),
    ("nan-distance", "evaluate returned values that are not JSON (distance_m: write None)"),
])
def test_an_evaluate_that_breaks_the_contract_leaves_the_run_not_judged(plugin, monkeypatch, mode, problem):
    rec = usv_mj.simulate(_scenario("crit_plugin:Ctrl"), plant_kind="analytic")
    monkeypatch.setenv("END_CLOSE_MODE", mode)
    block = summarize(rec)["criterion"]
    assert block["passed"] is None
    assert block["error"] == (f"criterion 'end_close' (crit_plugin:EndClose) broke its contract: {problem} "
                              f"(the criterion contract: usv_mj.record.criteria)")
    assert verdict(block) == f"not judged: {block['error']}"
    assert outcome_sentence(block).startswith("The end radius could not be judged (criterion 'end_close'")


def test_a_first_violation_of_none_reads_in_every_output(plugin, tmp_path):
    from usv_mj.outputs.report import write_report

    rec = usv_mj.simulate(_scenario("crit_plugin:Tight"), plant_kind="analytic")
    s = summarize(rec)
    assert s["criterion"]["passed"] is False and s["criterion"]["first_violation_s"] is None
    assert verdict(s["criterion"]) == "not passed: 1 control steps outside"
    assert outcome_sentence(s["criterion"]) == "The end radius was lost (1 control steps outside)."
    assert "Outcome: **not passed: 1 control steps outside**" in write_report(tmp_path / "report.md", s).read_text()


def test_a_broken_criterion_is_refused_at_load(plugin, tmp_path, capsys):
    from usv_mj.builder import make_controller
    from usv_mj.cli.main import main

    sc = _scenario("crit_plugin:BadDict")
    with pytest.raises(PluginContractError, match=r"its criterion .*\(crit_plugin:NoKindInDict\): to_dict\(\) must "
                                                  r"return a dict with \"kind\": 'no_kind_in_dict'"):
        criterion_of(make_controller(sc))
    with pytest.raises(PluginContractError, match=r"kind 'path_tolerance' is already the criterion "
                                                  r"usv_mj.record.criteria:PathTolerance; give the class a kind of its own"):
        criterion_of(make_controller(_scenario("crit_plugin:Stealing")))
    out = tmp_path / "o"
    assert main(["run", "--plant", "analytic", "--set", "controller.kind=crit_plugin:BadDict", "--duration", "1",
                 "--no-baseline", "--no-video", "-q", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "usv-mj run: error: controller" in err[0] and "to_dict() must return" in err[0]
    assert not out.exists()


def test_judge_lets_a_builtin_error_through():
    from usv_mj.core.errors import ScenarioError
    from usv_mj.record.criteria import FunnelCriterion

    rec = usv_mj.simulate(_scenario("los"), plant_kind="analytic")
    with pytest.raises(ScenarioError, match="no funnel columns"):
        judge(FunnelCriterion(), rec)


# --- cause 17: plug-in factories, entry points, numba -----------------------------------------------

FACTORIES = textwrap.dedent('''
    import numpy as np
    from numba import njit

    from usv_mj.controllers.los import LOSController
    from usv_mj.references.trajectories import LineReference


    class NoDuration(LineReference):
        @classmethod
        def from_scenario(cls, options, scenario):          # the registry passes duration=
            return super().from_scenario(options, scenario, duration=scenario.duration)


    class SubLOS(LOSController):                             # no options: LOSController's
        pass


    class Orphan:                                            # no options, no registered parent
        name = "orphan"
        diagnostic_fields = ()

        @classmethod
        def from_scenario(cls, options, scenario):
            return cls(options.k1)


    class NotAController:
        @classmethod
        def from_scenario(cls, options, scenario):
            return object()


    def boat_one_argument(options):
        return None


    def boat_dict(options, scenario):
        return {"ship": None}


    @njit(cache=True)
    def bad_kernel(t, x, ref, diag):
        return 0.0, "oops" + 1, diag


    class BadKernel:
        name = "bad"
        diagnostic_fields = ()

        def __init__(self):
            self._diag = np.zeros(0)

        @classmethod
        def from_scenario(cls, options, scenario):
            return cls()

        def reset(self):
            pass

        def kernel(self):
            from usv_mj.core.kernels import Kernel
            return Kernel(bad_kernel, (self._diag,))

        def __call__(self, t, state, reference):
            return 0.0, 0.0, self._diag


    class ShortLOS(LOSController):
        diagnostic_fields = ("e_ct", "e_psi")
''')


@pytest.fixture
def factories(tmp_path, monkeypatch):
    (tmp_path / "fact_plugin.py").write_text(FACTORIES)
    monkeypatch.syspath_prepend(str(tmp_path))
    sys.modules.pop("fact_plugin", None)
    import fact_plugin
    yield fact_plugin
    sys.modules.pop("fact_plugin", None)


def test_a_trajectory_factory_without_duration_is_named(factories):
    from usv_mj.references.trajectories import make_reference

    sc = load_scenario(preset="paper", overrides={"trajectory": {"kind": "fact_plugin:NoDuration"}})
    with pytest.raises(PluginContractError, match=r"trajectory kind 'fact_plugin:NoDuration' \(fact_plugin.NoDuration"
                                                  r".from_scenario, module:Name\): its factory cannot be called as "
                                                  r"\(options, scenario, duration=...\): got an unexpected keyword "
                                                  r"argument 'duration'; a trajectory factory takes \(options, "
                                                  r"scenario, duration=...\)"):
        make_reference(sc.trajectory, sc.duration, sc)


def test_a_subclass_named_by_module_name_takes_its_parents_options(factories):
    from usv_mj.builder import make_controller
    from usv_mj.controllers.los import LOSController, LOSGains

    first = next(iter(LOSGains.__dataclass_fields__))          # a key of LOSGains: validated as the parent's
    value = 2 * getattr(LOSGains(), first)
    sc = load_scenario(preset="paper", overrides={"controller": {"kind": "fact_plugin:SubLOS", first: value}})
    assert isinstance(sc.controller.gains, LOSGains) and getattr(sc.controller.gains, first) == value
    c = make_controller(sc)
    assert isinstance(c, LOSController) and type(c).__name__ == "SubLOS"


def test_a_factory_that_fails_is_the_plugins_error(factories):
    from usv_mj.builder import make_controller

    sc = load_scenario(preset="paper", overrides={"controller": {"kind": "fact_plugin:Orphan"}})
    with pytest.raises(PluginContractError, match=r"controller kind 'fact_plugin:Orphan' .*: its factory raised "
                                                  r"AttributeError: 'NoneType' object has no attribute 'k1' at "
                                                  r"fact_plugin.py:\d+ \(a defect of the plug-in, not of usv_mj\); "
                                                  r"it was given options None: .* the class attribute `options`"):
        make_controller(sc)
    sc = load_scenario(preset="paper", overrides={"controller": {"kind": "fact_plugin:NotAController"}})
    with pytest.raises(PluginContractError, match=r"its factory returned object .* which has no name, "
                                                  r"diagnostic_fields, reset, __call__"):
        make_controller(sc)


def test_an_entry_point_vessel_factory_is_held_to_the_contract(factories, monkeypatch):
    from importlib.metadata import EntryPoint

    from usv_mj.core.errors import ScenarioError
    from usv_mj.core.registry import VESSELS

    eps = dict(VESSELS._eps())
    for name in ("boat_one_argument", "boat_dict"):
        eps[name] = EntryPoint(name=name, value=f"fact_plugin:{name}", group="usv_mj.vessels")
    monkeypatch.setattr(VESSELS, "_entry_points", eps)
    try:   # the scenario loader says which scenario (a ScenarioError, PluginContractError's parent)
        with pytest.raises(ScenarioError, match=r"vessel kind 'boat_one_argument' \(fact_plugin.boat_one_argument, "
                                                      r"entry point usv_mj.vessels .*\): its factory cannot be called as "
                                                      r"\(options, scenario\)"):
            load_scenario(preset="paper", overrides={"vessel": {"kind": "boat_one_argument"}})
        with pytest.raises(ScenarioError, match=r"its factory returned dict .*, which has no kind, ship, split, "
                                                      r"dimensions: a vessel has kind, ship, split, dimensions"):
            load_scenario(preset="paper", overrides={"vessel": {"kind": "boat_dict"}})
    finally:
        for name in ("boat_one_argument", "boat_dict"):
            VESSELS.unregister(name)


def test_numba_errors_read_as_one_line_naming_the_plugins_kernel(factories):
    from usv_mj.core.errors import compiler_summary, one_line

    sc = load_scenario(preset="paper", overrides={"duration": 0.2, "baseline": {"enabled": False},
                                                  "controller": {"kind": "fact_plugin:BadKernel"}})
    with pytest.raises(PluginContractError) as caught:
        usv_mj.simulate(sc, plant_kind="analytic")
    text = str(caught.value)
    assert "\x1b" not in text and "\n" not in text
    assert text.startswith("numba cannot compile the loop with the plug-in's controller kernel fact_plugin.bad_kernel: "
                           "No implementation of function Function(<built-in function add>) found for signature: "
                           ">>> add(")
    assert "fact_plugin.py, line " in text, text
    # a numba error raised in a plug-in's own Python call: one line, no escape codes
    try:
        factories.bad_kernel(0.0, np.zeros(6), np.zeros(7), np.zeros(0))
    except Exception as exc:
        line = one_line(exc)
    assert line.startswith("TypingError: No implementation of function") and "\x1b" not in line
    assert compiler_summary("an ordinary message") is None


def test_run_refuses_a_controller_whose_diagnostics_do_not_fit_before_writing(factories, tmp_path, capsys):
    from usv_mj.cli.main import main

    out = tmp_path / "o"
    assert main(["run", "--plant", "analytic", "--set", "controller.kind=fact_plugin:ShortLOS", "--duration", "1",
                 "--no-baseline", "--no-video", "-q", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "fact_plugin.ShortLOS returns 13 diagnostics but declares 2" in err[0]
    assert not out.exists() and not list(tmp_path.glob(".o*"))
