"""The batched loop (usv_mj.loop.batch, issue 36 item 1): a batch of mixed episodes gives each one the
record simulate() makes of it alone, bit for bit; the stacking rules (state per episode, equal
parameters once) checked on their own."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from numba import njit

from usv_mj import load_scenario, simulate
from usv_mj.core.kernels import Kernel
from usv_mj.loop.batch import signature, simulate_batch, stack, write_back
from usv_mj.physics.disturbances import D_KERNEL, Disturbance, packed_disturbance

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "examples" / "scenarios"


def _paper(plant, eta, duration=1.2, **over):
    return load_scenario(preset="paper", overrides={"duration": duration, "plant": {"kind": plant},
                                                     "initial": {"eta": list(eta)}, **over})


def _mixed():
    """(name, scenario, controller kind) of episodes that differ in every way a batch must keep apart."""
    eps = []
    for i in range(5):   # one group: start poses, and one with a different duration
        eps.append((f"paper-{i}", _paper("analytic", (2.0 + 0.7 * i, -3.0 + 0.4 * i, 0.1 * i),
                                         duration=1.2 if i < 4 else 0.8), None))
    eps.append(("paper-unquantized", _paper("analytic", (1.0, -2.0, 0.2), quantizer={"enabled": False}), None))
    eps.append(("paper-gains", _paper("analytic", (2.0, -3.0, 0.0), controller={"k1": 5.0, "gamma_u": 500.0}), None))
    eps.append(("paper-pi", _paper("analytic", (2.5, -2.0, 0.3)), "pi"))
    eps.append(("paper-pi-2", _paper("analytic", (3.5, -1.0, -0.3)), "pi"))
    eps.append(("limited", load_scenario(preset="paper-limited", overrides={
        "duration": 1.2, "plant": {"kind": "analytic"}, "initial": {"eta": [3.0, -4.0, 1.0]}}), None))
    eps.append(("otter-sea", load_scenario(preset="paper", overrides={
        "duration": 1.0, "plant": {"kind": "analytic"}, "vessel": {"kind": "otter"},
        "sea": {"preset": "moderate"}}), None))
    eps.append(("otter-sea-2", load_scenario(preset="paper", overrides={
        "duration": 1.0, "plant": {"kind": "analytic"}, "vessel": {"kind": "otter"},
        "sea": {"preset": "moderate", "wind": {"speed": 5.0, "from_deg": 180.0, "gust_sigma": 1.0,
                                                   "gust_time_constant": 2.0, "seed": 3}}, "initial": {"eta": [1.0, -1.0, 0.4]}}), None))
    eps.append(("otter-los", load_scenario(SCENARIOS / "los_circle.toml", overrides={
        "duration": 1.5, "plant": {"kind": "analytic"}, "vessel": {"kind": "otter"}}), None))
    eps.append(("kvlcc2-zigzag", load_scenario(SCENARIOS / "zigzag_10_10.toml", overrides={
        "duration": 2.0, "plant": {"kind": "analytic"}, "vessel": {"kind": "kvlcc2"}}), None))
    eps.append(("waypoints", _paper("analytic", (0.5, 0.5, 0.0), trajectory={
        "kind": "waypoints", "points": [[0.0, 0.0], [20.0, 0.0], [20.0, 20.0]], "speed": 0.6}), None))
    eps.append(("diverges", _paper("analytic", (2.0, -3.0, 0.0), limits={"max_distance": 3.7}), None))
    eps.append(("force-limit", _paper("analytic", (6.0, -3.0, 0.0), limits={"max_force": 30.0}), None))
    eps.append(("mujoco-0", _paper("mujoco", (2.0, -3.0, 0.0), duration=0.8), None))
    eps.append(("mujoco-1", _paper("mujoco", (4.0, -1.0, 0.5), duration=0.8), None))
    eps.append(("mujoco-otter-sea", load_scenario(preset="paper", overrides={
        "duration": 0.6, "plant": {"kind": "mujoco"}, "vessel": {"kind": "otter"},
        "sea": {"preset": "moderate"}}), None))
    eps.append(("harbour-hook", load_scenario(SCENARIOS / "harbour_gap.toml", overrides={
        "duration": 0.5, "plant": {"kind": "analytic"}}), None))   # a hook: runs alone, after the batch
    return eps


def _same_record(a, b, name):
    assert a.n_rows == b.n_rows, name
    assert a.column_names == b.column_names, name
    ra, rb = np.asarray(a.buffer[:a.n_rows]), np.asarray(b.buffer[:b.n_rows])
    assert np.array_equal(ra.view(np.uint64), rb.view(np.uint64)), name   # bit for bit, NaN rows included
    assert (a.status, a.stop_reason) == (b.status, b.stop_reason), name
    assert [(e.t, e.kind, e.message) for e in a.events] == [(e.t, e.kind, e.message) for e in b.events], name
    assert a.metadata["quantizer_switches"] == b.metadata["quantizer_switches"], name
    assert a.metadata["loop"] == b.metadata["loop"], name


def test_a_batch_of_mixed_episodes_equals_the_single_runs_bit_for_bit():
    eps = _mixed()
    kinds = {c for _, _, c in eps}
    batch = []
    for kind in kinds:   # the controller kind is a build option: one batch per kind, mixed inside
        idx = [i for i, (_, _, c) in enumerate(eps) if c == kind]
        recs = simulate_batch([eps[i][1] for i in idx], controller_kind=kind, block=300, n_threads=2)
        batch += list(zip(idx, recs))
    assert len(batch) == len(eps)
    statuses = set()
    for i, rec in batch:
        name, sc, kind = eps[i]
        alone = simulate(sc, controller_kind=kind)
        _same_record(rec, alone, name)
        statuses.add(rec.status)
    assert statuses == {"completed", "diverged"}   # both stops are in the batch
    assert dict(batch)[[n for n, _, _ in eps].index("diverges")].status == "diverged"


@njit(cache=True)
def _gust_kernel(dp, t):
    """A yaw gust: f_n = dp[0] for dp[1] <= t < dp[2] (no surge or sway force)."""
    if dp[1] <= t < dp[2]:
        return 0.0, 0.0, dp[0]
    return 0.0, 0.0, 0.0


@dataclasses.dataclass(frozen=True)
class _Gust(Disturbance):
    """A disturbance kind of the test's own (not registered: the scenario holds the object)."""

    moment: float = 1.0   # [N m]
    start: float = 0.0    # [s]
    end: float = 1.0      # [s]

    kernel = _gust_kernel

    def as_array(self):
        return np.array([self.moment, self.start, self.end])


def test_each_episode_carries_its_own_packed_disturbance():
    """Episodes of one kernel combination whose d(t) differ (the paper's at two scales, a kind of the
    test's own at two strengths: one stacked packed vector, a dispatch word per row) each get the d(t)
    of their own run alone, on both plants; the gust's episodes differ from the paper's (its kernel ran)."""
    paper = _paper("analytic", (2.0, -3.0, 0.0), duration=0.6)
    eps = [paper, dataclasses.replace(paper, disturbance=dataclasses.replace(paper.disturbance, scale=0.0)),
           dataclasses.replace(paper, disturbance=_Gust(40.0, 0.1, 0.4)),
           dataclasses.replace(paper, disturbance=_Gust(-25.0, 0.2, 0.5))]
    mj = _paper("mujoco", (2.0, -3.0, 0.0), duration=0.4)
    eps += [mj, dataclasses.replace(mj, disturbance=_Gust(40.0, 0.1, 0.3))]
    words = np.array([packed_disturbance(sc.disturbance) for sc in eps[:4]])
    assert words[0, D_KERNEL] == 0.0 and words[2, D_KERNEL] != 0.0   # the paper's kernel, the gust's cfunc
    recs = simulate_batch(eps, block=150, n_threads=2)
    alone = [simulate(sc) for sc in eps]
    for i, (rec, one) in enumerate(zip(recs, alone)):
        _same_record(rec, one, f"episode {i}")
    for gust, paper_run in ((2, 0), (3, 0), (5, 4)):
        assert np.abs(recs[gust]["r"] - recs[paper_run]["r"]).max() > 1e-3, gust   # the gust turned it
    assert not np.array_equal(recs[0]["psi"], recs[1]["psi"])   # the paper's d(t) at scale 0 is not at 1e-4


def test_the_parts_are_left_where_the_single_run_leaves_them():
    """The batch writes each episode's state (PPC weights, quantizer levels) back into its parts."""
    from usv_mj import build
    from usv_mj.loop.batch import run_batch

    scs = [_paper("analytic", (2.0 + i, -3.0, 0.0), duration=0.6) for i in range(3)]
    parts = [build(sc) for sc in scs]
    run_batch(parts, block=250)
    for sc, p in zip(scs, parts):
        q = build(sc)
        simulate(q)
        assert np.array_equal(p.controller.weights, q.controller.weights)
        assert [x.k for x in p.quantizers] == [x.k for x in q.quantizers]
        assert np.array_equal(p.plant.state, q.plant.state)
        p.close()
        q.close()


@njit(cache=True)
def _toy(t, p, state, scale):
    state[0] += p[0] * scale
    return state[0]


def test_stacking_rules():
    """Written arguments once per episode (even the same object), equal parameters once,
    different ones stacked, scalars shared when equal; an undeclared kernel gets every array copied."""
    shared_p = np.array([1.0, 2.0])
    ks = [Kernel(_toy, (np.array([1.0, 2.0]), np.zeros(1), 2.0), state=(1,)) for _ in range(3)]
    s = stack(ks)
    assert s.mask == (False, True, False)   # equal values: one parameter; state per episode; equal scalar
    assert s.args[1].shape == (3, 1)
    ks[2] = Kernel(_toy, (np.array([1.0, 3.0]), ks[2].args[1], 4.0), state=(1,))
    s = stack(ks)
    assert s.mask == (True, True, True) and s.args[2].tolist() == [2.0, 2.0, 4.0]
    scratch = np.zeros(1)   # the same written array in every episode: each gets its own copy
    s = stack([Kernel(_toy, (shared_p, scratch, 1.0), state=(1,))] * 2)
    assert s.mask == (False, True, False) and [j for j, _ in s.back] == [1]
    undeclared = stack([Kernel(_toy, (shared_p, np.zeros(1), 1.0))] * 2)
    assert undeclared.mask == (True, True, False)   # not declared: copied (the parameter too)
    s = stack(ks)
    s.args[1][:] = [[5.0], [6.0], [7.0]]
    write_back(s, 1)
    assert ks[1].args[1][0] == 6.0 and ks[0].args[1][0] == 0.0
    assert signature(ks[0]) != signature(Kernel(_toy, (np.zeros(3), np.zeros(1), 1.0), state=(1,)))  # ragged: apart
