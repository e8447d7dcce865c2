"""The one angle wrap, usv_mj.physics.ship.wrap_angle: [-pi, pi), a ufunc from Python and from njit kernels,
compiled when first called (importing the physics starts no compiler)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
from numba import njit

from usv_mj.physics.ship import wrap_angle

ROOT = Path(__file__).resolve().parent.parent


def test_values_by_hand_on_scalars_lists_and_arrays():
    # a + 2 pi k wraps to a; pi itself wraps to -pi (the interval is closed below, open above)
    assert wrap_angle(0.0) == 0.0 and wrap_angle(math.pi) == -math.pi and wrap_angle(-math.pi) == -math.pi
    assert math.isclose(wrap_angle(1.5 * math.pi), -0.5 * math.pi, abs_tol=1e-15)
    assert math.isclose(wrap_angle(-7.0), -7.0 + 2 * math.pi, abs_tol=1e-15)
    assert math.isclose(wrap_angle(3), 3.0) and isinstance(wrap_angle(3), float)   # an int is an angle too
    angles = np.linspace(-50.0, 50.0, 10001)
    out = wrap_angle(angles)
    assert out.dtype == np.float64 and out.shape == angles.shape
    assert np.all(out >= -math.pi) and np.all(out < math.pi)
    assert np.allclose(np.cos(out), np.cos(angles), atol=1e-12) and np.allclose(np.sin(out), np.sin(angles), atol=1e-12)
    assert np.array_equal(wrap_angle(list(angles[:5])), out[:5])
    assert np.array_equal(wrap_angle(angles.astype(np.float32)), wrap_angle(angles.astype(np.float32).astype(np.float64)))


def test_callable_from_an_njit_kernel_with_the_same_values():
    @njit
    def kernel(x):
        out = np.empty_like(x)
        for i in range(x.size):
            out[i] = wrap_angle(x[i])
        return out, wrap_angle(x)

    x = np.array([-10.0, -math.pi, 0.5, math.pi, 12.0])
    each, whole = kernel(x)
    assert np.array_equal(each, wrap_angle(x)) and np.array_equal(whole, wrap_angle(x))


def test_importing_the_physics_compiles_nothing():
    code = ("import json\n"
            "from usv_mj.physics.ship import wrap_angle\n"
            "print(json.dumps(len(wrap_angle.types)))\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.strip().splitlines()[-1]) == 0   # no loop compiled until a call
