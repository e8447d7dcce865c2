"""Plants: the ship integrated analytically (RK4) or by MuJoCo, behind one interface (:mod:`.base`)."""

from .analytic import AnalyticPlant
from .base import Plant

__all__ = ["AnalyticPlant", "Plant"]
