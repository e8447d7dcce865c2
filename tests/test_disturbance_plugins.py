"""A disturbance kind of a user's own is a real part (issue 33 item 3): its d(t) runs in both plants
and both loops, at every RK4 stage time, and equals a hand integration of it.

The plug-in is a squall, a gust in yaw: f_n = A for 20 s <= t < 40 s, else 0 (no surge or sway
force), written here twice, as a module in tmp_path named ``"squall_plugin:Squall"`` and as a
kind registered by decorator. With the open-loop controller (tau_u = 20 N, tau_r = 0, no
quantizer), calm water and no paper d(t), each route runs on both plants and both loops:

- the loops give the same record bit for bit; the plants agree to compare's open-loop tolerances
  (1e-6 m, 1e-6 rad: tests/test_compare.py);
- the run differs from the one without the squall by metres;
- it equals a hand integration of d/dt (eta, nu) = (J(psi) nu, M^-1 (tau + d(t) + Delta - C nu -
  D nu)): scipy's solve_ivp (rtol 1e-10) on usv_mj.physics.ship.state_derivative (the hull, no
  d(t)) plus M^-1 (0, 0, f_n(t)) written here, split at the gust's edges.

The gust's edges lie on step boundaries (20 s and 40 s are multiples of h = 1 ms, and the stage
times land on them exactly). Classic RK4 samples a jump there with its last stage, at the step's
end t_k + h, which sees the value after the jump: the step before 20 s gains A h/6 of yaw impulse
and the step before 40 s loses it, so in effect the gust blows from 20 - h/6 to 40 - h/6 s (a
plant that held d(t) over the step would show no shift: the shift is the proof that d(t) is
evaluated at the stage times). The plants equal the hand integration of that gust to 1e-6 m, and
the hand integration of the gust at 20..40 s to the O(h) of the shift (docs/model.md, "d(t)").

A kind that breaks the contract (a kernel that is not njit, an ``as_array()`` longer than 16
words, invalid options, a kernel that does not compile) is refused with one line naming the kind
and what is wrong; from the command line that is exit 2, not an internal error.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from numba import njit
from scipy.integrate import solve_ivp

from usv_mj import load_scenario, simulate
from usv_mj.core.errors import PluginContractError, ScenarioError
from usv_mj.core.registry import DISTURBANCES
from usv_mj.physics.disturbances import D_MAX_WORDS, Disturbance, evaluate_disturbance
from usv_mj.physics.ship import PaperDisturbance, packed_disturbance, state_derivative

REPO = Path(__file__).resolve().parents[1]
A = 2.0                      # [N m] the gust's yaw moment
START, END = 20.0, 40.0      # [s]
DURATION = 60.0              # [s]
DT = 1e-3                    # [s] control period = RK4 step (substeps = 1)
TAU_U = 20.0                 # [N] the open-loop surge force
STATE = ("x", "y", "psi", "u", "v", "r")

SQUALL_MODULE = '''
from dataclasses import dataclass

import numpy as np
from numba import njit


@njit(cache=False)
def squall_kernel(dp, t):
    if dp[1] <= t < dp[2]:
        return 0.0, 0.0, dp[0]
    return 0.0, 0.0, 0.0


@dataclass(frozen=True)
class Squall:
    moment: float = 1.0   # [N m]
    start: float = 0.0    # [s]
    end: float = 1.0      # [s]

    kernel = squall_kernel

    def __post_init__(self):
        if not self.start < self.end:
            raise ValueError(f"disturbance.end must be after start, got {self.end!r}")

    def as_array(self):
        return np.array([self.moment, self.start, self.end])
'''


# --- the same squall, registered by decorator ----------------------------------------------------

@njit
def _gust(dp, t):
    if dp[1] <= t < dp[2]:
        return 0.0, 0.0, dp[0]
    return 0.0, 0.0, 0.0


@dataclass(frozen=True)
class DecoratedSquall(Disturbance):
    moment: float = 1.0   # [N m] yaw moment while the gust blows
    start: float = 0.0    # [s]
    end: float = 1.0      # [s]

    kernel = _gust

    def as_array(self):
        return np.array([self.moment, self.start, self.end])


@pytest.fixture
def routes(tmp_path, monkeypatch):
    """kind name by route: the module in tmp_path ("module:Name") and the decorator's kind."""
    (tmp_path / "squall_plugin.py").write_text(SQUALL_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    DISTURBANCES.register("test-squall")(DecoratedSquall)
    try:
        yield {"module:Name": "squall_plugin:Squall", "decorator": "test-squall"}
    finally:
        DISTURBANCES.unregister("test-squall")
        DISTURBANCES.unregister("squall_plugin:Squall")
        sys.modules.pop("squall_plugin", None)


def _scenario(plant: str, disturbance: dict):
    return load_scenario(preset="paper", overrides={
        "duration": DURATION, "control_period": DT,
        "initial": {"eta": [0.0, 0.0, 0.0], "nu": [0.0, 0.0, 0.0]},
        "plant": {"kind": plant, "substeps": 1},
        "controller": {"kind": "open_loop", "tau_u": TAU_U, "tau_r": 0.0},
        "quantizer": {"enabled": False}, "baseline": {"enabled": False},
        "disturbance": disturbance})


def _states(record) -> np.ndarray:
    return np.column_stack([record[c] for c in STATE])


def _hand_integration(ship, t_rows: np.ndarray, start: float, end: float) -> np.ndarray:
    """The squall's ODE by solve_ivp, split at its edges: the hull of ship.py with no d(t) (its
    paper vector at scale 0) plus M^-1 (0, 0, A) while the gust blows."""
    p = ship.as_array()
    no_d = PaperDisturbance(scale=0.0).as_array()
    gust = np.linalg.solve(ship.mass_matrix(), np.array([0.0, 0.0, A]))

    def rhs(t, x, on):
        dx = state_derivative(p, no_d, t, x, TAU_U, 0.0)
        if on:
            dx[3:] += gust
        return dx

    out = np.empty((t_rows.size, 6))
    x = np.zeros(6)
    for a, b, on in ((0.0, start, False), (start, end, True), (end, DURATION, False)):
        sol = solve_ivp(rhs, (a, b), x, args=(on,), rtol=1e-10, atol=1e-12, dense_output=True)
        rows = (t_rows >= a) & ((t_rows < b) if b < DURATION else (t_rows <= b))
        out[rows] = sol.sol(t_rows[rows]).T
        x = sol.sol(b)
    return out


@pytest.mark.parametrize("route", ["module:Name", "decorator"])
def test_a_squall_changes_the_run_on_both_plants_and_both_loops_and_equals_a_hand_integration(routes, route):
    kind = routes[route]
    squall = {"kind": kind, "moment": A, "start": START, "end": END}
    runs = {}
    for plant in ("analytic", "mujoco"):
        scenario = _scenario(plant, squall)
        assert type(scenario.disturbance).__name__ in ("Squall", "DecoratedSquall")
        for loop in ("python", "auto"):
            record = simulate(scenario, loop=loop)
            assert record.status == "completed"
            assert record.metadata["loop"] == ("python" if loop == "python" else "compiled")
            runs[plant, loop] = record
    first = runs["analytic", "python"]
    t = first["t"]
    assert np.all(first["f_u"] == TAU_U) and np.all(first["f_r"] == 0.0)  # the inputs the reference takes

    # the loops: bit for bit; the plants: compare's open-loop tolerances
    for plant in ("analytic", "mujoco"):
        np.testing.assert_array_equal(_states(runs[plant, "python"]), _states(runs[plant, "auto"]))
    an, mj = _states(runs["analytic", "auto"]), _states(runs["mujoco", "auto"])
    assert np.abs(an[:, :2] - mj[:, :2]).max() < 1e-6
    assert np.abs(an[:, 2] - mj[:, 2]).max() < 1e-6

    # the squall moves the run: nothing before 20 s, metres after
    calm = _states(simulate(_scenario("analytic", {"scale": 0.0}), loop="auto"))
    before = t <= START
    np.testing.assert_array_equal(an[before & (t < START - DT)], calm[before & (t < START - DT)])
    assert np.abs(an[:, :2] - calm[:, :2]).max() > 1.0
    assert np.abs(an[:, 2] - calm[:, 2]).max() > 1.0

    # the hand integration: the stage times land on the edges, so RK4 sees them h/6 early (module docstring)
    assert (round(START / DT) - 1) * DT + DT == START and (round(END / DT) - 1) * DT + DT == END
    ship = _scenario("analytic", squall).ship
    seen = _hand_integration(ship, t, START - DT / 6, END - DT / 6)
    exact = _hand_integration(ship, t, START, END)
    for (plant, loop), record in runs.items():
        x = _states(record)
        assert np.abs(x[:, :2] - seen[:, :2]).max() < 1e-6, (plant, loop)
        assert np.abs(x[:, 2] - seen[:, 2]).max() < 1e-6, (plant, loop)
        # against the gust at 20..40 s: the O(h) of RK4's sampling of the jumps, A h/6 of impulse
        assert np.abs(x[:, :2] - exact[:, :2]).max() < 5e-4, (plant, loop)
    # the shift is there (a plant holding d(t) over each step would match `exact` instead)
    assert np.abs(an[:, :2] - exact[:, :2]).max() > 10 * np.abs(an[:, :2] - seen[:, :2]).max()


def test_the_python_face_and_the_packed_vector_call_the_one_kernel(routes):
    """force(t) (Disturbance), evaluate_disturbance and the plants' packed vector (through the
    cfunc's address) give the kernel's d(t); the paper's packed vector dispatches to its own
    kernel (word D_MAX_WORDS = 0) and gives what its bare vector gives, bit for bit."""
    from usv_mj.physics.ship import disturbance_force, disturbance_terms

    squall = DecoratedSquall(moment=A, start=START, end=END)
    dp = packed_disturbance(squall)
    assert dp.shape == (D_MAX_WORDS + 1,) and dp[D_MAX_WORDS] != 0.0 and float(dp[D_MAX_WORDS]).is_integer()
    for t in (0.0, 19.999, 20.0, 30.0, 39.999, 40.0, 55.0):
        want = np.array([0.0, 0.0, A if START <= t < END else 0.0])
        np.testing.assert_array_equal(squall.force(t), want)
        np.testing.assert_array_equal(evaluate_disturbance(squall, t), want)
        np.testing.assert_array_equal(disturbance_force(dp, t), want)
    paper = PaperDisturbance(scale=1e-3)
    packed = packed_disturbance(paper)
    assert packed[D_MAX_WORDS] == 0.0 and PaperDisturbance.kernel is disturbance_terms
    for t in np.linspace(0.0, 50.0, 11):
        np.testing.assert_array_equal(disturbance_force(packed, t), disturbance_force(paper.as_array(), t))
        np.testing.assert_array_equal(paper.force(t), disturbance_force(paper.as_array(), t))
        s = 1e-3  # Eq. 46 by hand
        by_hand = [s * a * (math.cos(wc * t) + math.sin(ws * t))
                   for a, wc, ws in zip(paper.amplitudes, paper.cos_frequencies, paper.sin_frequencies)]
        np.testing.assert_allclose(paper.force(t), by_hand, rtol=1e-14, atol=1e-15)


# --- the contract --------------------------------------------------------------------------------

BROKEN = {
    "not_njit": ('''
import numpy as np
from dataclasses import dataclass

def plain(dp, t):
    return 0.0, 0.0, dp[0]

@dataclass(frozen=True)
class Kind:
    moment: float = 1.0   # [N m]
    kernel = plain
    def as_array(self):
        return np.array([self.moment])
''', "its kernel must be an @numba.njit function"),
    "too_long": ('''
import numpy as np
from dataclasses import dataclass
from numba import njit

@njit
def k(dp, t):
    return 0.0, 0.0, dp[0]

@dataclass(frozen=True)
class Kind:
    moment: float = 1.0   # [N m]
    kernel = k
    def as_array(self):
        return np.full(17, self.moment)
''', "as_array() must give 1 to 16 finite numbers (usv_mj.physics.disturbances.D_MAX_WORDS), got 17 words"),
    "own_force": ('''
import numpy as np
from dataclasses import dataclass
from numba import njit

@njit
def k(dp, t):
    return 0.0, 0.0, dp[0]

@dataclass(frozen=True)
class Kind:
    moment: float = 1.0   # [N m]
    kernel = k
    def as_array(self):
        return np.array([self.moment])
    def force(self, t):
        return np.array([0.0, 0.0, 2 * self.moment])
''', "defines its own force(t) beside its kernel"),
}


@pytest.mark.parametrize("case", list(BROKEN))
def test_a_kind_that_breaks_the_contract_is_one_line_naming_it(case, tmp_path, monkeypatch):
    source, words = BROKEN[case]
    module = f"broken_{case}"
    (tmp_path / f"{module}.py").write_text(textwrap.dedent(source))
    monkeypatch.syspath_prepend(str(tmp_path))
    kind = f"{module}:Kind"
    try:
        with pytest.raises(PluginContractError) as info:
            load_scenario(preset="paper", overrides={"disturbance": {"kind": kind}})
        msg = str(info.value)
        assert f"disturbance kind {kind!r}" in msg and words in msg and "\n" not in msg
    finally:
        DISTURBANCES.unregister(kind)
        sys.modules.pop(module, None)


def test_invalid_options_and_a_kernel_that_does_not_compile_name_the_kind(routes):
    with pytest.raises(ScenarioError, match=r"preset paper: disturbance kind 'squall_plugin:Squall': "
                                            r"disturbance.end must be after start, got 10.0"):
        load_scenario(preset="paper", overrides={"disturbance": {"kind": routes["module:Name"], "start": 20.0,
                                                                 "end": 10.0}})
    with pytest.raises(ScenarioError, match=r"disturbance kind 'test-squall': unknown key 'disturbance.amplitude'"):
        load_scenario(preset="paper", overrides={"disturbance": {"kind": "test-squall", "amplitude": 1.0}})

    @njit
    def returns_a_string(dp, t):
        return "gust"

    @dataclass(frozen=True)
    class Wrong(Disturbance):
        moment: float = 1.0   # [N m]
        kernel = returns_a_string

        def as_array(self):
            return np.array([self.moment])

    DISTURBANCES.register("test-wrong")(Wrong)
    try:
        scenario = load_scenario(preset="paper", overrides={"disturbance": {"kind": "test-wrong"},
                                                            "plant": {"kind": "analytic"}})
        with pytest.raises(PluginContractError, match=r"disturbance kind 'test-wrong': its kernel .*returns_a_string "
                                                      r"does not compile as kernel\(dp: float64\[:\], t: float64\)"):
            simulate(scenario)
    finally:
        DISTURBANCES.unregister("test-wrong")


def test_the_command_line_says_it_in_one_line_and_exits_2(tmp_path):
    (tmp_path / "broken_cli.py").write_text(textwrap.dedent(BROKEN["not_njit"][0]))
    scenario = tmp_path / "s.toml"
    scenario.write_text('duration = 1.0\n[disturbance]\nkind = "broken_cli:Kind"\n')
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(REPO)])}
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "usv_mj.cli.main", "run", "--scenario", str(scenario), "--out",
                           str(out), "--no-video"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "disturbance kind 'broken_cli:Kind'" in lines[0] and "numba.njit" in lines[0]
    assert "Traceback" not in proc.stderr and not out.exists()


def test_kinds_lists_a_disturbance_kind_with_its_options(routes):
    from usv_mj.cli.kinds import list_kinds

    table = list_kinds(["disturbance"])["disturbance"]
    rows = {row["kind"]: row for row in table["kinds"]}
    assert table["group"] == "usv_mj.disturbances"
    assert {o["name"]: o["unit"] for o in rows["test-squall"]["options"]} == {"moment": "N m", "start": "s",
                                                                              "end": "s"}
    assert [o["name"] for o in rows["paper"]["options"]] == ["scale", "amplitudes", "cos_frequencies",
                                                             "sin_frequencies"]


def test_the_example_squall_is_the_documented_kind():
    """examples/plugins/.../squall.py (the README's and docs/model.md's example) keeps the contract
    and gives the gust it documents."""
    plugin = REPO / "examples" / "plugins" / "usv_mj_example_plugin"
    sys.path.insert(0, str(plugin))
    try:
        scenario = load_scenario(preset="paper", overrides={"disturbance": {
            "kind": "usv_mj_example_plugin.squall:Squall", "moment": 3.0, "start": 1.0, "end": 2.0}})
        squall = scenario.disturbance
        assert [tuple(squall.force(t)) for t in (0.5, 1.0, 1.5, 2.0)] == [(0, 0, 0), (0, 0, 3.0), (0, 0, 3.0),
                                                                           (0, 0, 0)]
        dp = packed_disturbance(squall)
        assert dp[D_MAX_WORDS] != 0.0
    finally:
        sys.path.remove(str(plugin))
        DISTURBANCES.unregister("usv_mj_example_plugin.squall:Squall")
        DISTURBANCES.unregister("squall")
        for name in [m for m in sys.modules if m.startswith("usv_mj_example_plugin")]:
            sys.modules.pop(name)
