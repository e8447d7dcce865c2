"""The paper's ship as a vessel: kind ``paper``, options :class:`usv_mj.physics.ship.ShipParams`.

Its options are the ``[ship]`` keys (total mass m11, m22, m23, m33 and the polynomial damping of
docs/model.md §1); ``[ship]`` stays their name in scenarios, presets and records. The rigid body is
the default :class:`~usv_mj.physics.ship.RigidBodySplit` (m = m11, x_g = m23/m11, I_z = m33) and the hull
is models/usv.xml as drawn, so a paper run is what it was before vessels existed, bit for bit.
"""

from __future__ import annotations

from usv_mj.core.registry import VESSELS
from usv_mj.physics.ship import RigidBodySplit, ShipParams

from usv_mj.vessels import PAPER_DIMENSIONS, Vessel


@VESSELS.register("paper", options=ShipParams)
def paper_vessel(options, scenario=None) -> Vessel:
    """The paper's ship with ``options`` (a ShipParams; None: the printed one)."""
    return Vessel("paper", options if options is not None else ShipParams(), RigidBodySplit(), PAPER_DIMENSIONS,
                  None, "Zhang et al., the paper (docs/model.md §1): total mass and polynomial damping")
