"""Planning around many obstacles (issue 27, item 2): the pruned visibility graph finds the
shortest path of the full one, keeps clear of every grown obstacle, is planned once per job, and
a Ctrl-C stops it at once."""

from __future__ import annotations

import itertools
import math
import signal
import subprocess
import sys
import textwrap
import time
from collections import OrderedDict

import networkx as nx
import numpy as np
import pytest
import shapely

from usv_mj.scenario.obstacles import from_tables
from usv_mj.references.planner import _merged_obstacles, visibility_path


def _circles(count, seed, half, keep_out=((0.0, 0.0), (45.0, 0.0)), clear=8.0):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        x, y = rng.uniform(22.5 - half, 22.5 + half), rng.uniform(-half, half)
        if min(math.hypot(x - a, y - b) for a, b in keep_out) < clear:
            continue
        out.append({"center": [float(x), float(y)], "radius": float(rng.uniform(0.3, 1.0))})
    return from_tables(out)


def _brute_force_length(start, goal, polygons):
    """The oracle: every pair of nodes (start, goal, every vertex) joined when the segment misses
    the obstacles' interiors, asked one segment at a time; Dijkstra's shortest length."""
    blocked = shapely.union_all([p.buffer(-1e-6) for p in polygons])
    nodes = [tuple(start), tuple(goal)] + [tuple(c) for p in polygons for c in np.asarray(p.exterior.coords)[:-1]]
    graph = nx.Graph()
    for a, b in itertools.combinations(range(len(nodes)), 2):
        if not blocked.intersects(shapely.LineString([nodes[a], nodes[b]])):
            graph.add_edge(a, b, weight=math.dist(nodes[a], nodes[b]))
    return nx.dijkstra_path_length(graph, 0, 1)


def _length(polyline):
    return float(np.sum(np.linalg.norm(np.diff(polyline, axis=0), axis=1)))


@pytest.mark.parametrize("seed", range(6))
def test_the_pruned_graph_finds_the_brute_force_shortest_path(seed):
    obstacles = _circles(14, seed, 16.0, clear=4.0)
    obstacles += from_tables([{"kind": "box", "center": [22.0, 0.5 * seed - 1.0], "size": [3.0, 6.0], "yaw": 0.3}])
    polygons = _merged_obstacles(obstacles, np.full(len(obstacles), 1.5))
    start, goal = (0.0, 0.0), (45.0, 0.0)
    path = visibility_path(start, goal, polygons)
    assert len(path) > 2  # the box is in the way: the path bends
    assert _length(path) == pytest.approx(_brute_force_length(start, goal, polygons), rel=1e-12, abs=1e-9)


def test_a_path_through_300_circles_keeps_clear_of_every_grown_circle():
    obstacles = _circles(300, 1, 0.5 * math.sqrt(300 * 60.0))  # one buoy per 60 m^2
    inflation = 2.0
    polygons = _merged_obstacles(obstacles, np.full(len(obstacles), inflation))
    t0 = time.process_time()
    path = visibility_path((0.0, 0.0), (45.0, 0.0), polygons)
    assert time.process_time() - t0 < 5.0  # the full graph: about 40 s of STRtree queries
    assert len(path) > 2
    # independently of shapely: the distance of every segment to every centre >= r + inflation
    a, b = path[:-1], path[1:]
    centers = np.array([o.center for o in obstacles])
    radius = np.array([o.radius for o in obstacles])
    d = b - a
    w = np.clip(np.einsum("sk,sck->sc", d, centers[None] - a[:, None]) / np.einsum("sk,sk->s", d, d)[:, None], 0, 1)
    closest = a[:, None] + w[..., None] * d[:, None]
    assert np.min(np.linalg.norm(closest - centers[None], axis=2) - radius - inflation) > -1e-6
    # and no shorter path exists among the grown circles near the line (the oracle on them)
    near = [p for p in polygons if p.distance(shapely.LineString([(0, 0), (45, 0)])) < 15.0]
    assert _length(path) <= _brute_force_length((0.0, 0.0), (45.0, 0.0), near) + 1e-9


def test_a_job_plans_once_and_the_half_step_check_runs_the_main_plan(monkeypatch, tmp_path):
    from usv_mj.jobs.run import run_job
    from usv_mj.references import planner
    from usv_mj.scenario.spec import load_scenario

    calls = []
    real = planner.plan_reference

    def counting(*args, **kwargs):
        calls.append(args[6])  # the horizon [s]
        return real(*args, **kwargs)

    monkeypatch.setattr("usv_mj.obstacles.hooks.plan_reference", counting)
    monkeypatch.setattr("usv_mj.obstacles.hooks._plans", OrderedDict())  # none from other tests
    sc = load_scenario("examples/scenarios/harbour_gap.toml").with_overrides(
        {"duration": 21.0, "plant": {"kind": "analytic"}, "guidance": {"margin_m": 0.3125}})
    result = run_job(sc, tmp_path / "run", video=False, log=False, progress=False)
    assert calls == [21.0]
    assert result.summary["step_check"]["max_position_m"] < 0.01
    changed = sc.with_overrides({"guidance": {"margin_m": 0.375}})
    run_job(changed, tmp_path / "again", video=False, log=False, progress=False)
    assert calls == [21.0, 21.0]  # another margin is another plan, never the cached one


def test_ctrl_c_stops_planning_at_once(tmp_path):
    script = textwrap.dedent("""
        import math, sys
        import numpy as np
        sys.path.insert(0, "tests")
        from test_planning_scale import _circles
        from usv_mj.references.planner import _merged_obstacles, visibility_path
        obstacles = _circles(1000, 2, 0.5 * math.sqrt(1000 * 60.0))
        polygons = _merged_obstacles(obstacles, np.full(len(obstacles), 2.0))
        visibility_path((0.0, 0.0), (45.0, 0.0), polygons)
        try:   # entered before the line that lets the test send the signal (no window outside it)
            print("planning", flush=True)
            while True:
                visibility_path((0.0, 0.0), (90.0, 0.0), polygons)  # about 1 s each
        except KeyboardInterrupt:
            print("interrupted", flush=True)
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "planning"
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    line = proc.stdout.readline()  # the interpreter's exit afterwards takes its own time
    honoured = time.monotonic() - sent
    proc.communicate(timeout=60)
    assert line.strip() == "interrupted"
    assert honoured < 5.0   # one batch of STRtree queries (ms), never a whole plan (~1 s here, 20 s before)
