"""Controllers for usv_mj: the paper's adaptive PPC law, the PI baseline and the hysteresis quantizer.

Every controller follows :class:`usv_mj.controllers.base.Controller`; the quantizer is the actuator channel
that the simulation loop applies to any controller's output.
"""

from importlib import import_module

# name -> submodule; imported on first use, so that the record's field names (base) come without
# the laws' numba kernels (a log writer or render worker starts in a fraction of the time)
_WHERE = {
    "DIAG": "base", "DIAG_FIELDS": "base", "N_DIAG": "base", "REF_FIELDS": "base", "Controller": "base",
    "HysteresisQuantizer": "hysteresis_quantizer", "QuantizerParams": "hysteresis_quantizer",
    "PerformanceFunnel": "performance_funnel", "error_transform": "performance_funnel",
    "funnel_bound": "performance_funnel", "PIController": "pi_baseline", "PIGains": "pi_baseline",
    "PPCController": "ppc", "PPCGains": "ppc",
}
__all__ = list(_WHERE)


def __getattr__(name):
    if name in _WHERE:
        value = getattr(import_module(f"{__name__}.{_WHERE[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
