"""One implementation per part (issue 24 item 3, usv_mj.core.kernels): a kernel runs only for its own class.

For every built-in part with a kernel (every kind of every registry, built as a run builds it,
and the quantizer, the actuators and the obstacles' hook of those runs), a subclass overriding one
public method (calling super() and moving its result by 1e-3, so that a loop that ignored the
override would show) must run in the Python loop under ``loop="auto"`` and give the record of
``loop="python"`` bit for bit; the reason names the class and the method. And the trap of the
issue: a LineReference whose ``pose`` adds a 5 m sway gives y_d(15 s) = 5 sin(1.5 rad) in both loops.

Runs are short (0.25 s, analytic plant; one MuJoCo run).
"""

from __future__ import annotations

import inspect
import math
from pathlib import Path

import numpy as np
import pytest

from usv_mj import build, load_scenario, simulate
from usv_mj.core.errors import PluginContractError
from usv_mj.core.kernels import kernel_blocker, kernel_of
from usv_mj.record.run_record import COL
from usv_mj.core.registry import CONTROLLERS, PLANTS, TRAJECTORIES

from test_compiled_loop import assert_same_run

EPS = 1e-3
DURATION = 0.25
BLOCK = 97
SCENARIOS = Path(__file__).resolve().parents[1] / "examples" / "scenarios"
#: the methods a subclass may define and keep the kernel (usv_mj.core.kernels): not overridden here
NOT_OVERRIDDEN = {"kernel", "from_scenario", "from_spec", "__init__"}


def _perturbed(value):
    """``value`` moved by EPS in its first float (a copy for arrays); others unchanged."""
    if isinstance(value, (float, np.floating)) and not isinstance(value, bool):
        return value + EPS
    if isinstance(value, np.ndarray) and value.dtype.kind == "f" and value.size:
        out = value.copy()
        out.flat[0] += EPS
        return out
    if isinstance(value, tuple):
        for i, v in enumerate(value):
            moved = _perturbed(v)
            if moved is not v:
                return value[:i] + (moved,) + value[i + 1:]
    return value


def public_methods(cls) -> list[str]:
    """The methods and properties of ``cls`` a user would override: public ones and ``__call__``."""
    names = []
    for name in dir(cls):
        if name in NOT_OVERRIDDEN or (name.startswith("_") and name != "__call__"):
            continue
        raw = inspect.getattr_static(cls, name)
        if isinstance(raw, (property, type(lambda: 0))):
            names.append(name)
    return sorted(names)


def overriding(cls, name):
    """A subclass of ``cls`` whose ``name`` calls super()'s and perturbs the result."""
    raw = inspect.getattr_static(cls, name)
    if isinstance(raw, property):
        member = property(lambda self: _perturbed(raw.fget(self)))
    else:
        def member(self, *args, **kwargs):
            return _perturbed(getattr(super(sub, self), name)(*args, **kwargs))
    sub = type(f"Tweaked{cls.__name__}_{name.strip('_')}", (cls,), {name: member})
    return sub


def _scenario(**over):
    base = {"duration": DURATION, "baseline": {"enabled": False}, "plant": {"kind": "analytic"}}
    return load_scenario(preset="paper", overrides={**base, **over})


def _obstacle_scenario():
    return load_scenario(SCENARIOS / "harbour_gap.toml",
                         overrides={"duration": DURATION, "baseline": {"enabled": False}, "plant": {"kind": "analytic"}})


#: the parts of the control step (usv_mj/loop/step.py): a subclass that overrides their behaviour is
#: refused before the run, in either loop (the step is one compiled function reading their arrays)
CHANNEL_ROLES = ("surge quantizer", "actuators")

# role -> how to reach the part in a build; cases: (role, scenario maker, build keywords)
ROLES = {
    "reference": lambda parts: parts.reference,
    "controller": lambda parts: parts.controller,
    "plant": lambda parts: parts.plant,
    "surge quantizer": lambda parts: parts.quantizers[0],
    "actuators": lambda parts: parts.actuators,
    "hook": lambda parts: parts.hooks[0],
}


def _cases():
    cases = [(f"reference-{kind}", "reference", lambda kind=kind: _scenario(trajectory={"kind": kind}), {})
             for kind in TRAJECTORIES.kinds()]
    cases += [(f"controller-{kind}", "controller", _scenario, {"controller_kind": kind}) for kind in CONTROLLERS.kinds()]
    cases += [(f"plant-{kind}", "plant", _scenario, {"plant_kind": kind}) for kind in PLANTS.kinds()]
    cases += [("quantizer", "surge quantizer", _scenario, {}),
              ("actuators", "actuators", lambda: load_scenario(preset="paper-limited", overrides={
                  "duration": DURATION, "baseline": {"enabled": False}, "plant": {"kind": "analytic"}}), {}),
              ("hook-obstacles", "hook", _obstacle_scenario, {})]
    return cases


CASES = _cases()


def _record(make_scenario, kw, role, sub, loop):
    parts = build(make_scenario(), **kw)
    part = ROLES[role](parts)
    if sub is not None:
        part.__class__ = sub
    return simulate(parts, loop=loop, block=BLOCK)


def _same(a, b):
    assert_same_run((a, [], []), (b, [], []))


@pytest.mark.parametrize("label, role, make_scenario, kw", CASES, ids=[c[0] for c in CASES])
def test_a_subclass_overriding_any_public_method_runs_the_python_loop_bit_for_bit(label, role, make_scenario, kw):
    parts = build(make_scenario(), **kw)
    part = ROLES[role](parts)
    cls = type(part)
    has_kernel = kernel_of(part) is not None
    parts.close()
    if not has_kernel:  # no kernel of its own: the loop must run Python and say which part held it there
        rec = _record(make_scenario, kw, role, None, "auto")
        assert rec.metadata["loop"] == "python", rec.metadata
        assert f"({cls.__name__}) has no kernel" in rec.metadata["loop_reason"], rec.metadata["loop_reason"]
        return
    plain = _record(make_scenario, kw, role, None, "auto")
    assert plain.metadata["loop"] == "compiled", plain.metadata.get("loop_reason")
    methods = public_methods(cls)
    assert methods, cls
    if cls.__name__ == "MuJoCoPlant":  # one MuJoCo run (the state the loop reads); the rest by the rule alone
        for name in methods:
            sub = overriding(cls, name)
            assert kernel_blocker(object.__new__(sub)) == (
                f"MuJoCoPlant subclass {sub.__name__} overrides {name} (and has no kernel of its own)")
        methods = ["state"]
    if role in CHANNEL_ROLES:   # the one compiled control step reads their arrays, never their methods
        for name in methods:
            sub = overriding(cls, name)
            for loop in ("auto", "python"):
                with pytest.raises(PluginContractError, match=rf"^the {role}: {cls.__name__} subclass {sub.__name__} "
                                                              rf"overrides {name} \(and has no kernel of its own\): "
                                                              r"the control step .* is one compiled function"):
                    _record(make_scenario, kw, role, sub, loop)
        return
    for name in methods:
        sub = overriding(cls, name)
        auto = _record(make_scenario, kw, role, sub, "auto")
        python = _record(make_scenario, kw, role, sub, "python")
        assert auto.metadata["loop"] == "python", name
        assert auto.metadata["loop_reason"] == (
            f"the {role}: {cls.__name__} subclass {sub.__name__} overrides {name} (and has no kernel of its own)")
        _same(auto, python)


def test_the_perturbation_shows_where_the_loop_calls_the_method():
    """The subclasses above would catch a wrong loop: their records differ from the plain run's."""
    for role, kw, name in (("reference", {}, "pose"), ("controller", {}, "__call__"), ("plant", {}, "step")):
        plain = _record(_scenario, kw, role, None, "python")
        cls = type(ROLES[role](build(_scenario(), **kw)))
        moved = _record(_scenario, kw, role, overriding(cls, name), "python")
        if name == "step" and role == "plant":  # returns None: nothing moved, the same run
            _same(plain, moved)
            continue
        assert not np.array_equal(plain.data[:plain.n_rows], moved.data[:moved.n_rows]), (role, name)


def test_a_mixin_or_an_instance_attribute_also_keeps_the_python_loop():
    parts = build(_scenario(trajectory={"kind": "line"}))
    ref_cls = type(parts.reference)
    parts.close()

    class Mixin:
        def pose(self, t):
            x, y, *rest = super().pose(t)
            return (x, y + EPS, *rest)

    mixed = type("Mixed", (Mixin, ref_cls), {})
    assert kernel_blocker(object.__new__(mixed)) == "LineReference mixin Mixin overrides pose (and has no kernel of its own)"
    parts = build(_scenario(trajectory={"kind": "line"}))
    ref = parts.reference
    ref.pose = lambda t, pose=ref.pose: pose(t)
    rec = simulate(parts)
    assert rec.metadata["loop"] == "python"
    assert rec.metadata["loop_reason"] == "the reference: LineReference object has its own pose (instance attribute)"
    # plain data and a constructor keep the kernel
    class Options:  # what a registry may attach to a registered class
        pass

    quiet = type("Named", (ref_cls,), {"kind": "named", "Options": Options,
                                       "__init__": lambda self, *a, **k: ref_cls.__init__(self, *a, **k)})
    assert kernel_blocker(quiet()) is None
    # a class in the place of a method is behaviour
    assert "overrides pose" in kernel_blocker(object.__new__(type("Classy", (ref_cls,), {"pose": Options})))


def test_the_wavy_line_of_the_issue_gives_its_own_sway_in_both_loops():
    """LineReference + 5 sin(0.1 t) m of sway: y_d(15 s) = 5 sin(1.5) = 4.98747 m (heading 0 from
    the origin: the line itself stays on y = 0), whichever loop runs."""
    sc = _scenario(trajectory={"kind": "line"}, duration=15.0)
    cls = type(build(sc).reference)
    assert cls.__name__ == "LineReference"

    class WavyLine(cls):
        def pose(self, t):
            x, y, *rest = super().pose(t)   # (x, y, psi, r, u) and the accelerations (u_dot, r_dot)
            return (x, y + 5.0 * math.sin(0.1 * t), *rest)

    records = []
    for loop in ("auto", "python"):
        parts = build(sc)
        parts.reference.__class__ = WavyLine
        records.append(simulate(parts, loop=loop))
    auto, python = records
    assert auto.metadata["loop"] == "python"
    assert auto.metadata["loop_reason"] == ("the reference: LineReference subclass WavyLine overrides pose "
                                            "(and has no kernel of its own)")
    k = int(round(15.0 / sc.control_period))
    assert auto.data[k, COL["t"]] == pytest.approx(15.0, abs=1e-12)
    assert auto.data[k, COL["y_d"]] == pytest.approx(5.0 * math.sin(1.5), abs=1e-12)
    assert round(auto.data[k, COL["y_d"]], 4) == 4.9875
    _same(auto, python)
