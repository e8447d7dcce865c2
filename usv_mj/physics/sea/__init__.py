"""Sea state for usv_mj: waves, current and wind as pure functions of (t, eta, nu) (docs/sea.md).

Public API::

    from usv_mj.physics.sea import Environment, SeaSettings, load_sea_preset
    env = Environment(load_sea_preset("moderate"), t_max=300.0)
    env.elevation(x, y, t); env.elevation_grid(xs, ys, t, origin); env.current(t); env.wind(t)
    env.loads(t, eta, nu) -> EnvLoads(nu_c, nu_c_dot, tau_wind, tau_wave1, tau_drift)
    ep, waves, cgrid, wgrid = env.packed      # arrays for the numba kernels
    sea_state_derivative(p, dp, ep, waves, cgrid, wgrid, t, x, tau_u, tau_r)
    sea_force(p, dp, ep, waves, cgrid, wgrid, t, eta, nu)   # all but thrust (MuJoCo callback)
"""

from usv_mj.physics.sea.dynamics import (sea_body_acceleration, sea_force, sea_rk4_advance, sea_rk4_trajectory,
                       sea_state_derivative)
from usv_mj.physics.sea.environment import EnvLoads, Environment, PackedEnvironment, environment_loads
from usv_mj.physics.sea.settings import (CurrentSettings, HullGeometry, SeaSettings, SeaSettingsError, WaveSettings,
                       WindSettings, load_sea_preset, sea_preset_names, sea_preset_table)
from usv_mj.physics.sea.waves import WaveComponents, jonswap_spectrum

__all__ = [
    "CurrentSettings", "EnvLoads", "Environment", "HullGeometry", "PackedEnvironment", "SeaSettings",
    "SeaSettingsError", "WaveComponents", "WaveSettings", "WindSettings", "environment_loads",
    "jonswap_spectrum", "load_sea_preset", "sea_body_acceleration", "sea_force", "sea_preset_names",
    "sea_preset_table", "sea_rk4_advance", "sea_rk4_trajectory", "sea_state_derivative",
]
