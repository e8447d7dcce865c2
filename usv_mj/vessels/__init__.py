"""Vessels: a hull written once, as the packed parameters every plant and controller kernel reads.

A scenario names its hull by ``[vessel] kind`` (:data:`usv_mj.core.registry.VESSELS`; docs/vessels.md):

- ``paper``: the paper's ship (:mod:`usv_mj.vessels.paper`), whose options are the keys of
  :class:`usv_mj.physics.ship.ShipParams` (``[ship]`` is the same table under its old name);
- ``cybership2``, ``otter``: data files of ``usv_mj/vessels/data/`` (:mod:`usv_mj.vessels.datafile`),
  the hydrodynamic derivatives of their sources in Fossen's notation;
- ``clarke83``: a ship from its main dimensions (:mod:`usv_mj.vessels.clarke83`);
- ``kvlcc2``: the KVLCC2 7 m model by the MMG standard method, rudder and propeller as its inputs
  (:mod:`usv_mj.vessels.kvlcc2`, :mod:`usv_mj.physics.mmg`);
- a data file of the user's (``kind = "path/to/boat.toml"``) or a module (``"pkg.mod:Name"``, an
  entry point of the group ``usv_mj.vessels``).

A vessel kind's factory returns a :class:`Vessel`: the packed hull (:class:`~usv_mj.physics.ship.ShipParams`:
total mass M, damping D(nu), the masses of C(nu), cross-flow drag), the rigid body MuJoCo carries
(:class:`~usv_mj.physics.ship.RigidBodySplit`), the main dimensions (the MJCF hull is sized from them) and
optionally the vessel's own ``[actuators]`` table. :func:`from_derivatives` is the one map from
Fossen's derivatives to that layout.

Conventions: SI units; body x forward, y to port, z up (README, Conventions). The sources write the
marine NED frame (y to starboard); M, C(nu) nu and D(nu) nu of a port/starboard-symmetric hull are
unchanged by the mirror y -> -y (usv_mj.physics.ship), so their derivatives are used as printed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from usv_mj.physics.channels import FORCES, Channels
from usv_mj.physics.ship import RigidBodySplit, ShipParams

__all__ = ["Dimensions", "Vessel", "from_derivatives", "PAPER_DIMENSIONS"]


@dataclass(frozen=True)
class Dimensions:
    """Main dimensions: length L, beam B, draught T [m] (the MJCF hull is scaled to them)."""

    L: float
    B: float
    T: float

    def __post_init__(self) -> None:
        for name in ("L", "B", "T"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"vessel.{name} must be a length > 0 m, got {value!r}")


#: the hull of models/usv.xml as drawn (the paper prints no dimensions): 1.98 m from the transom
#: (x = -0.98) to the bow (x = 1.0), 0.76 m wide, 0.20 m deep; a vessel of these dimensions gets the
#: model file's geoms unchanged
PAPER_DIMENSIONS = Dimensions(1.98, 0.76, 0.20)
#: what C(nu) holds (:func:`from_derivatives`)
CORIOLIS = ("full", "rigid", "none")


@dataclass(frozen=True)
class Vessel:
    """A resolved vessel (module docstring).

    Attributes
    ----------
    kind: its kind.
    ship: the packed hull (total M, D(nu), C(nu)'s masses, cross-flow) every kernel reads.
    split: the rigid body MuJoCo carries (m, x_g, I_z); the callback adds M - M_RB.
    dimensions: L, B, T [m].
    actuators: an ``[actuators]`` table (usv_mj.physics.actuators.ActuatorSpec keys) or None (the scenario's).
    source: where its numbers come from (one line; docs/vessels.md has the full citation).
    notes: what its model leaves out or approximates (one line each).
    channels: the two input channels the plant receives (:class:`usv_mj.physics.channels.Channels`):
        the surge force tau_u [N] and yaw moment tau_r [N m] (:data:`~usv_mj.physics.channels.FORCES`),
        or a ruddered ship's propeller revolutions n_P [1/s] and rudder angle delta [rad] (positive
        to port) with the allocation a force command reaches them through (usv_mj.physics.mmg).
    limitations: what the vessel's model cannot do, {feature: why} (features: "sea", and a
        manoeuvre's kind such as "stopping"); a scenario that asks for one is refused with the reason.
    actuators_merged: a scenario's ``[actuators]`` keys change the vessel's own ``actuators`` one by
        one (a steering gear that belongs to the ship) instead of replacing the table.
    scale: the model's scale 1:scale of a full-scale ship (IMO's criteria then apply to that ship), or None.
    nominal_rps: a ruddered vessel's propeller revolutions near its service speed [1/s] (where the
        manoeuvres' search for the n_P that holds the approach speed starts).
    manoeuvre: the vessel's own defaults of the standard manoeuvres' options ({key: value}, e.g.
        approach_speed, yaw_moment; a data file's ``[manoeuvre]`` table), each applied to every manoeuvre
        that has the option, and {manoeuvre kind: {key: value}} for one kind only (these win), or None: the paper hull's
        Froude-scaled to its length (usv_mj.scenario.manoeuvre.vessel_defaults).
    """

    kind: str
    ship: ShipParams
    split: RigidBodySplit = RigidBodySplit()
    dimensions: Dimensions = PAPER_DIMENSIONS
    actuators: dict | None = None
    source: str = ""
    notes: tuple = ()
    channels: Channels = FORCES
    limitations: dict = field(default_factory=dict)
    actuators_merged: bool = False
    scale: float | None = None
    nominal_rps: float | None = None
    manoeuvre: dict | None = None

    def rigid_body(self) -> tuple[float, float, float]:
        """(m [kg], x_g [m], I_z about the origin [kg m^2]) that MuJoCo carries."""
        return self.split.rigid_body(self.ship)

    def mass_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(M_RB, M_A) [kg, kg m, kg m^2], 3x3, body frame: M_RB = [[m, 0, 0], [0, m, m x_g],
        [0, m x_g, I_z]] and M_A = M - M_RB."""
        m, x_g, iz = self.rigid_body()
        m_rb = np.array([[m, 0.0, 0.0], [0.0, m, m * x_g], [0.0, m * x_g, iz]])
        return m_rb, self.split.added_mass(self.ship)


def from_derivatives(m, x_g, I_z, X_udot, Y_vdot, Y_rdot, N_vdot, N_rdot,
                     X_u=0.0, X_uu=0.0, X_uuu=0.0, Y_v=0.0, Y_vv=0.0, Y_rv=0.0, Y_r=0.0, Y_vr=0.0, Y_rr=0.0,
                     N_v=0.0, N_vv=0.0, N_rv=0.0, N_r=0.0, N_vr=0.0, N_rr=0.0,
                     coriolis="full", crossflow_k=0.0, crossflow_L=0.0, strips=20, uncertainty_scale=0.0,
                     where="vessel") -> tuple[ShipParams, RigidBodySplit]:
    """The packed hull and the rigid body of a vessel given by Fossen's derivatives (SI units).

    Rigid body: m [kg], x_g [m] (COM ahead of the origin), I_z [kg m^2] about the origin. Added
    mass: X_udot, Y_vdot, Y_rdot, N_vdot, N_rdot (< 0 by Fossen's sign). Damping: the forces
    X = X_u u + X_uu |u| u + X_uuu u^3, Y = (Y_v + Y_vv |v| + Y_rv |r|) v + (Y_r + Y_vr |v| + Y_rr |r|) r,
    N likewise with N_* (Fossen's Y_|v|v is Y_vv here, Y_|r|v is Y_rv, Y_|v|r is Y_vr, Y_|r|r is Y_rr).

    Mapped onto usv_mj.physics.ship's layout: m11 = m - X_udot, m22 = m - Y_vdot, m23 = m x_g - Y_rdot
    (= m x_g - N_vdot: the layout's M is symmetric; a source with Y_rdot != N_vdot is given its
    symmetric part by the caller, see clarke83), m33 = I_z - N_rdot; d11 = -(X_u, X_uu, X_uuu),
    d22 = -(Y_v, Y_vv, Y_rv), d23 = -(Y_r, Y_vr, Y_rr), d32 = -(N_v, N_vv, N_rv), d33 = -(N_r, N_vr, N_rr),
    exactly (the kernels' d11 = c0 + c1|u| + c2 u^2, d_ij = c0 + c1|v| + c2|r|).

    ``coriolis``: "full" (C = C_RB + C_A with the Munk moment, Fossen's nonlinear model), "rigid"
    (C = C_RB: the damping derivatives hold C_A's terms) or "none" (C = 0: a linear manoeuvring
    model M nu_dot + N(U) nu = tau whose N(U) holds the linearized C(U) as well, as Clarke 1983's).
    ``crossflow_k`` = 0.5 rho T C_d [kg/m^2] over ``crossflow_L`` [m] in ``strips`` strips (0: none).
    ``uncertainty_scale``: the paper's Delta on this hull (0: none, the vessels' default).
    """
    if Y_rdot != N_vdot:
        raise ValueError(f"{where}: Y_rdot = {Y_rdot!r} and N_vdot = {N_vdot!r} differ; the mass matrix must be "
                         f"symmetric (give both their mean)")
    if coriolis not in CORIOLIS:
        raise ValueError(f"{where}: coriolis must be one of {', '.join(CORIOLIS)}, got {coriolis!r}")
    split = RigidBodySplit(rigid=(float(m), float(x_g), float(I_z)))
    ship = ShipParams(
        m11=m - X_udot, m22=m - Y_vdot, m23=m * x_g - Y_rdot, m33=I_z - N_rdot,
        d11=(-X_u, -X_uu, -X_uuu), d22=(-Y_v, -Y_vv, -Y_rv), d23=(-Y_r, -Y_vr, -Y_rr),
        d32=(-N_v, -N_vv, -N_rv), d33=(-N_r, -N_vr, -N_rr), uncertainty_scale=uncertainty_scale,
        coriolis_masses={"full": None, "rigid": (m, m, m * x_g), "none": (0.0, 0.0, 0.0)}[coriolis],
        crossflow=(crossflow_k, crossflow_L, strips) if crossflow_k > 0 else (0.0, 0.0, 0.0))
    return ship, split
