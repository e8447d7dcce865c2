"""Fixtures shared by several test files."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def drift_scenario():
    """``drift_scenario(duration, speed, toward_deg)``: the paper scenario made an unpowered hull at
    the origin heading east (a registered controller "idle" that commands no thrust, no d(t)) in a
    current of ``speed`` [m/s] setting toward ``toward_deg`` (compass), on the analytic plant. The
    controller kind is registered for the test and removed after it."""
    from usv_mj import CONTROLLERS, load_scenario

    class Idle:
        name, diagnostic_fields = "idle", ()

        @classmethod
        def from_scenario(cls, gains, scenario):
            return cls()

        def reset(self):
            pass

        def __call__(self, t, x, ref):
            return 0.0, 0.0, np.zeros(0)

    CONTROLLERS.register("idle")(Idle)

    def make(duration: float, speed: float, toward_deg: float):
        return load_scenario(preset="paper", overrides={
            "duration": duration, "plant": {"kind": "analytic"}, "controller": {"kind": "idle"},
            "disturbance": {"scale": 0.0}, "initial": {"eta": [0.0, 0.0, 0.0]},
            "sea": {"current": {"speed": speed, "toward_deg": toward_deg}}})

    try:
        yield make
    finally:
        CONTROLLERS.unregister("idle")
