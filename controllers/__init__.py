"""Controllers for usv_mj: the paper's adaptive PPC law, the PI baseline and the hysteresis quantizer.

Every controller follows :class:`usv_mj.controllers.base.Controller`; the quantizer is the actuator channel
that the simulation loop applies to any controller's output.
"""

from usv_mj.core.lazy_names import lazy_names

# imported on first use, so that the record's field names (base) come without the laws' numba
# kernels (a log writer or render worker starts in a fraction of the time)
__getattr__, __dir__, __all__ = lazy_names(__name__, {
    "DIAG": ".base", "DIAG_FIELDS": ".base", "N_DIAG": ".base", "REF_FIELDS": ".base", "Controller": ".base",
    "HysteresisQuantizer": ".hysteresis_quantizer", "QuantizerParams": ".hysteresis_quantizer",
    "PerformanceFunnel": ".performance_funnel", "error_transform": ".performance_funnel",
    "funnel_bound": ".performance_funnel", "PIController": ".pi_baseline", "PIGains": ".pi_baseline",
    "PPCController": ".ppc", "PPCGains": ".ppc",
})
