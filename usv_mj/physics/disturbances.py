"""The disturbances a scenario's ``[disturbance] kind`` can name (:data:`usv_mj.core.registry.DISTURBANCES`).

A disturbance is a parameter dataclass whose ``as_array()`` packs it for the plants' kernels
(:func:`usv_mj.physics.ship.disturbance_force`). The paper's d(t) of Eq. 46 is the one built in.
"""

from __future__ import annotations

from usv_mj.core.registry import DISTURBANCES
from usv_mj.physics.ship import PaperDisturbance

DISTURBANCES.register("paper", options=PaperDisturbance, doc="the paper's d(t), Eq. 46, times `scale`")(PaperDisturbance)
