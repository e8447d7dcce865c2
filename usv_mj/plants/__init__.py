"""Plants: the ship integrated analytically (RK4) or by MuJoCo, behind one interface (:mod:`.base`)."""

from usv_mj.plants.analytic import AnalyticPlant
from usv_mj.plants.base import Plant

__all__ = ["AnalyticPlant", "Plant"]
