"""Controllers for usv_mj: the paper's adaptive PPC law, the PI baseline and the hysteresis quantizer.

Every controller follows :class:`usv_mj.controllers.base.Controller`; the quantizer is the actuator channel
that the simulation loop applies to any controller's output.
"""

from .base import DIAG, DIAG_FIELDS, N_DIAG, REF_FIELDS, Controller
from .hysteresis_quantizer import HysteresisQuantizer, QuantizerParams
from .performance_funnel import PerformanceFunnel, error_transform, funnel_bound
from .pi_baseline import PIController, PIGains
from .ppc import PPCController, PPCGains

__all__ = [
    "DIAG", "DIAG_FIELDS", "N_DIAG", "REF_FIELDS", "Controller", "HysteresisQuantizer", "QuantizerParams",
    "PerformanceFunnel", "error_transform", "funnel_bound", "PIController", "PIGains", "PPCController",
    "PPCGains",
]
