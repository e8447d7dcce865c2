"""The package's worker processes (video renderers, the run log's writer, the environment's
renderer) start from any main module: a script with no ``if __name__ == "__main__":`` guard, and
``python -`` reading its program from stdin (a main module with no file). Before, the first ran
again in every worker and the second made every worker fail at start, which the render pool
answered by starting another, forever."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

PROGRAM = """\
import numpy as np
from usv_mj import envs, load_scenario, simulate
from usv_mj.outputs.render import render_run
from usv_mj.outputs.log import RunLogWriter, read_run

env = envs.load("track")
env.reset()
image = env.physics.render(height=36, width=64)
sc = load_scenario(preset="paper", overrides={"duration": 1, "plant": {"kind": "analytic"}})
with RunLogWriter(OUT + "/run.mcap", sc) as writer:
    rec = simulate(sc, sinks=[writer.sink()])
info = render_run(rec, OUT + "/run.mp4", width=96, height=64, workers=2, progress=False)
back = read_run(OUT + "/run.mcap")
print("DONE", image.shape, info["frames"], np.array_equal(back.record.data, rec.data, equal_nan=True))
"""


@pytest.mark.parametrize("how", ["script", "stdin"])
def test_workers_start_from_an_unguarded_script_and_from_stdin(tmp_path, how):
    program = f"OUT = {str(tmp_path)!r}\n" + PROGRAM
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    env.pop("MUJOCO_GL", None)   # the renderers then run in spawned workers
    if how == "script":
        script = tmp_path / "unguarded.py"
        script.write_text(program)
        args, stdin = [sys.executable, str(script)], None
    else:
        args, stdin = [sys.executable, "-"], program
    proc = subprocess.run(args, input=stdin, cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=180)
    assert proc.returncode == 0, proc.stderr[-2000:]
    done = [line for line in proc.stdout.splitlines() if line.startswith("DONE")]
    assert done == ["DONE (36, 64, 3) 30 True"], proc.stdout   # printed once: the script ran once


LATER = """\
import threading, time
import multiprocessing
from usv_mj.support.spawning import spawn_context

def start(ctx, out):
    p = ctx.Process(target=time.sleep, args=(0,))
    p.start()
    p.join(60)
    out.append(p.exitcode)

codes = []
for ctx in (spawn_context(), multiprocessing.get_context("spawn")):
    t = threading.Thread(target=start, args=(ctx, codes))   # as a pool's thread starts a replacement
    t.start()
    t.join()
print("EXIT CODES", codes)
"""


def test_a_process_started_later_from_another_thread_skips_the_main_module_too():
    """A pool replaces a dead worker from its own thread, long after it was made: every process of
    spawn_context() starts without the main module, whenever and from wherever it is started (the
    stdlib's spawn context, beside it, fails from stdin: its child cannot find '<stdin>')."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run([sys.executable, "-"], input=LATER, env=env, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "EXIT CODES [0, 1]" in proc.stdout, (proc.stdout, proc.stderr[-2000:])
