"""A plug-in's controller at the compiled speed (issue 37, item 3): the example plug-in's ``example-pd``
writes its law once as a numba function (``pd_law``), calls it from ``__call__`` and hands it as its
``kernel()``; the compiled loop then runs it, and its records are the same bit for bit as the Python
loop's, on both plants. An edited plug-in law gets a new generated loop (its source's size and
time are in the generated module's header), so a stale compiled loop never runs the old law.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parent.parent
PLUGIN = REPO / "examples" / "plugins" / "usv_mj_example_plugin"
PD = "usv_mj_example_plugin.pd:ExamplePD"


@pytest.fixture
def plugin_path(monkeypatch):
    monkeypatch.syspath_prepend(str(PLUGIN))


def _scenario(plant):
    from usv_mj import load_scenario

    return load_scenario(overrides={"duration": 20.0, "control_period": 0.001, "baseline": {"enabled": False},
                                    "plant": {"kind": plant}, "trajectory": {"kind": "circle", "speed": 0.8},
                                    "controller": {"kind": PD, "kp_yaw": 18.0}})


@pytest.mark.parametrize("plant", ["analytic", "mujoco"])
def test_the_plugin_runs_compiled_and_its_record_is_the_python_loops_bit_for_bit(plugin_path, plant):
    from usv_mj import simulate

    sc = _scenario(plant)
    compiled = simulate(sc, loop="auto")
    python = simulate(sc, loop="python")
    assert compiled.metadata["loop"] == "compiled", compiled.metadata.get("loop_reason")
    assert python.metadata["loop"] == "python"
    assert compiled.status == python.status == "completed"
    assert compiled.column_names == python.column_names
    assert {"along_track_error", "cross_track_error", "heading_error"} <= set(compiled.column_names)
    for name in compiled.column_names:
        np.testing.assert_array_equal(compiled[name], python[name], err_msg=name)
    # the law did its work: on the circle after 20 s, well inside the plug-in's 2 m tolerance
    assert math.hypot(compiled["x"][-1] - compiled["x_d"][-1], compiled["y"][-1] - compiled["y_d"][-1]) < 2.0


def test_the_call_and_the_kernel_are_one_function(plugin_path):
    from usv_mj.builder import make_controller
    from usv_mj.core.kernels import kernel_of

    ctrl = make_controller(_scenario("analytic"))
    k = kernel_of(ctrl)()
    from usv_mj_example_plugin import pd

    assert k.fn is pd.pd_kernel and k.args[0] is ctrl._g and k.args[2] is ctrl._diag
    x = np.array([1.0, -2.0, 0.3, 0.5, 0.05, -0.02])
    ref = np.array([3.0, 1.0, 0.1, 0.6, 0.06, 0.01, 0.6, 0.0, 0.0, 0.0])
    tau_u, tau_r, diag = ctrl(0.0, x, ref)
    d = diag.copy()
    a, b, dk = pd.pd_kernel(0.0, x, ref, *k.args)
    assert (a, b) == (tau_u, tau_r) and np.array_equal(dk, d)
    # by hand: e_x, e_y in the body frame, psi_c = psi_d + atan(e_y / 3), tau_r = 18 e_psi + 26 (r_d - r)
    c, s = math.cos(0.3), math.sin(0.3)
    ex, ey = c * 2.0 + s * 3.0, -s * 2.0 + c * 3.0
    e_psi = 0.1 + math.atan(ey / 3.0) - 0.3
    assert d[0] == pytest.approx(ex, abs=1e-12) and d[1] == pytest.approx(ey, abs=1e-12)
    assert tau_r == pytest.approx(18.0 * e_psi + 26.0 * (0.01 + 0.02), abs=1e-9)


def test_an_edited_plugin_kernel_gets_a_new_generated_loop(tmp_path, monkeypatch):
    import importlib
    import os
    import time

    from usv_mj.loop import generate as gen

    pkg = tmp_path / "edited_law"
    pkg.mkdir()
    law = pkg / "__init__.py"
    body = ("from numba import njit\n\n@njit(cache=True)\ndef k(t, x, ref, g):\n    return {}, 0.0, g\n")
    law.write_text(body.format("1.0"))
    monkeypatch.syspath_prepend(str(tmp_path))
    mod = importlib.import_module("edited_law")
    first = gen._outside_sources(["edited_law"])
    assert "edited_law" in first and str(law.stat().st_size) in first
    law.write_text(body.format("2.50"))
    st = law.stat()
    os.utime(law, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    assert gen._outside_sources(["edited_law"]) != first
    # the package's own modules are covered by the package fingerprint, not listed
    assert gen._outside_sources(["usv_mj.controllers.pi_baseline", "usv_mj.references.trajectories"]) == ""
    del mod, time
