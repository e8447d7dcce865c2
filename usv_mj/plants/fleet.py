"""Several hulls in one sea, stepped together: the plants of a scenario's ``[[vessels]]`` (issue 35).

The vessel index is a dimension of the plant: :meth:`reset_vessel` (i, eta, nu), :meth:`step_vessels`
(forces, one row (f_u, f_r) per vessel held over the control period) and :attr:`states` (one row
(x, y, psi, u, v, r) per vessel).

- :class:`SeparateHulls` (the analytic plant's fleet, and any plant kind's without one of its own):
  one plant per vessel, each its own hull, in the same sea; hulls do not touch (a collision is a
  geometric event of the encounter log). A vessel in it runs its single run's record bit for bit.
- :class:`MuJoCoFleet`: one MuJoCo model of the scene (``models/scene.xml``) with every vessel's hull
  of ``models/usv.xml`` attached under its name (``own/hull``, ``own/x`` ...), each on its own planar
  joints, scaled to its dimensions, its rigid body its own; the water acts on each through the one
  passive-force callback, which walks one userdata block per hull (:data:`usv_mj.plants.mujoco_callback.U_NEXT`);
  the hulls' collision geoms collide with each other and with the scenario's obstacles (contacts on,
  :class:`usv_mj.scene.compose.ContactParams`), so a collision is a contact force in MuJoCo.
"""

from __future__ import annotations

import math
import weakref

import mujoco
import numpy as np

from usv_mj.physics.ship import RigidBodySplit
from usv_mj.plants import attach
from usv_mj.plants import mujoco_callback as mcb
from usv_mj.scene.compose import ContactParams
from usv_mj.scene.hull import HULL_COLLISION_GEOMS, scale_hull
from usv_mj.support.assets import model_path

SEA_HORIZON_AHEAD_S = 120.0
#: the hulls' collision classes in a fleet: a hull collides with the other hulls and the obstacles
FLEET_HULL_CONTYPE, FLEET_HULL_CONAFFINITY = 1, 3


class SeparateHulls:
    """A fleet of one plant per vessel (module docstring): the analytic plant's (:class:`AnalyticFleet`),
    and any plant kind's that brings no fleet of its own; ``plants``: one per vessel, in order."""

    def __init__(self, plants, names):
        self.plants = list(plants)
        self.names = tuple(names)
        self.name = getattr(self.plants[0], "name", "plant")
        self.control_period = self.plants[0].control_period

    @property
    def n_vessels(self) -> int:
        return len(self.plants)

    def reset_vessel(self, i: int, eta0, nu0, t0: float = 0.0) -> None:
        self.plants[i].reset(eta0, nu0, t0)

    def step_vessels(self, forces) -> None:
        """One control period of every vessel, row i of ``forces`` = (f_u, f_r) held by vessel i."""
        for plant, (f_u, f_r) in zip(self.plants, forces):
            plant.step(f_u, f_r)

    @property
    def states(self) -> np.ndarray:
        return np.array([p.state for p in self.plants])

    def contacts(self) -> np.ndarray:
        """The contact force [N] between each pair of hulls (i < j): none on the analytic plant."""
        n = len(self.plants)
        return np.zeros(n * (n - 1) // 2)

    def close(self) -> None:
        for p in self.plants:
            p.close()


AnalyticFleet = SeparateHulls


def mujoco_fleet(vessels, environment=None, obstacles=(), contact=None) -> "MuJoCoFleet":
    """The plant kind "mujoco"'s fleet (the registry's ``fleet`` factory): ``vessels`` = (name,
    scenario) of each vessel (its hull, disturbance, rigid body, dimensions, actuator limits)."""
    first = vessels[0][1]
    return MuJoCoFleet([(name, sc.ship, sc.disturbance, sc.vessel.model.split, sc.vessel.model.dimensions,
                         sc.actuators.generalized_limits()) for name, sc in vessels],
                       first.control_period, first.plant.substeps, environment, obstacles, contact or ContactParams())


class MuJoCoFleet:
    """The MuJoCo plant of a fleet (module docstring).

    ``vessels``: one (name, ship, disturbance, split, dimensions, actuator_limits) per vessel;
    ``environment``: the shared sea (or None); ``obstacles`` / ``contact``: the scene's standing
    and moving obstacles and the contact model. The model's hull of vessel ``name`` is the body
    ``name/hull`` on the joints ``name/x``, ``name/y``, ``name/yaw`` driven by the motors
    ``name/surge``, ``name/yaw``.
    """

    name = "mujoco"
    callback = "native"

    def __init__(self, vessels, control_period: float, substeps: int = 1, environment=None, obstacles=(),
                 contact: ContactParams = ContactParams()):
        if not vessels:
            raise ValueError("MuJoCoFleet: no vessels")
        self.names = tuple(v[0] for v in vessels)
        self.vessels = tuple(vessels)
        self.control_period = float(control_period)
        self.substeps = int(substeps)
        self.environment = environment if environment is not None and not environment.calm else None
        for name, ship, *_ in vessels:
            if self.environment is not None and ship.calm_water_only:
                raise ValueError(f"MuJoCoFleet: vessel {name!r}: its hull's model holds in calm water only (no [sea])")
        self.obstacles = tuple(obstacles)
        self.contact = contact
        self.model, self.data = self._compose()
        self._hulls = [mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, f"{n}/hull") for n in self.names]
        self._qadr = [int(self.model.jnt_qposadr[mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, f"{n}/x")])
                      for n in self.names]
        self._madr = [int(self.model.dof_Madr[q]) for q in self._qadr]
        self._cadr = [mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{n}/surge") for n in self.names]
        for name, q, m in zip(self.names, self._qadr, self._madr):
            rows = [int(r) for r in self.model.M_rownnz[q:q + 3]]
            if rows != [1, 2, 3]:
                raise ValueError(f"MuJoCoFleet: vessel {name!r}'s joints must be their own dense 3x3 block of M, "
                                 f"got M_rownnz {rows}")
        self._geoms = [[mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, f"{n}/{g[0]}") for g in
                        HULL_COLLISION_GEOMS] for n in self.names]
        self._stride = mcb.N_USERDATA + max(len(v[1].as_array()) - mcb.N_SHIP_PARAMS for v in vessels)
        self._sea_arrays = None
        self._sea_horizon = math.inf
        self._userdata = self.data.userdata
        mcb.check_offsets(self.model, self.data)
        self._closed = False
        self._t0, self._k = 0.0, 0
        self._write_parameters()
        mcb.CALLBACKS.add(self)
        self._finalizer = weakref.finalize(self, _release, id(self), self.data._address, self._userdata)

    # --- construction --------------------------------------------------------------------------

    def _compose(self):
        scene = mujoco.MjSpec.from_file(str(model_path("scene.xml")))
        scene.delete(scene.body("hull"))          # scene.xml includes the one hull: the fleet brings its own
        for a in list(scene.actuators):
            scene.delete(a)
        n = len(self.vessels)
        stride = mcb.N_USERDATA + max(len(v[1].as_array()) - mcb.N_SHIP_PARAMS for v in self.vessels)
        for name, ship, _, _, dims, limits in self.vessels:
            hull = mujoco.MjSpec.from_file(str(model_path("usv.xml")))
            body = hull.body("hull")
            common = dict(friction=list(self.contact.friction), solref=list(self.contact.solref),
                          solimp=list(self.contact.solimp), condim=self.contact.condim)
            for gname, kind, size, pos in HULL_COLLISION_GEOMS:
                g = body.add_geom(name=gname, size=list(size), pos=list(pos), contype=FLEET_HULL_CONTYPE,
                                  conaffinity=FLEET_HULL_CONAFFINITY, group=3, mass=0, density=0,
                                  rgba=[1, 0.2, 0.2, 0.35], **common)
                g.type = {"box": mujoco.mjtGeom.mjGEOM_BOX, "ellipsoid": mujoco.mjtGeom.mjGEOM_ELLIPSOID}[kind]
            scale_hull(hull, dims)   # the visual and the collision geoms, as the single plant's
            if not ship.inputs_are_forces:
                for act in hull.actuators:
                    act.gear = [0.0] * 6
            if limits is not None:
                for aname, lo, hi in (("surge", limits[0], limits[1]), ("yaw", limits[2], limits[3])):
                    act = next(a for a in hull.actuators if a.name == aname)
                    if math.isfinite(lo) or math.isfinite(hi):
                        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
                        act.ctrlrange = [max(lo, -1e10), min(hi, 1e10)]
            frame = scene.worldbody.add_frame()
            scene.attach(hull, prefix=f"{name}/", frame=frame)
        scene.option.disableflags = int(scene.option.disableflags) & ~int(mujoco.mjtDisableBit.mjDSBL_CONTACT) \
            & ~int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
        scene.nuserdata = max(int(scene.nuserdata), n * stride)
        model = scene.compile()
        model.opt.timestep = self.control_period / self.substeps
        model.opt.gravity[:] = 0.0
        return model, mujoco.MjData(model)

    def _write_parameters(self) -> None:
        """Each hull's rigid body (model) and its callback block (d.userdata), by the one path a
        single plant and a user's own model take (:mod:`usv_mj.plants.attach`)."""
        packed = None if self.environment is None else tuple(self.environment.packed)
        for i, (name, ship, disturbance, split, _, _) in enumerate(self.vessels):
            attach.set_rigid_body(self.model, self._hulls[i], ship, split or RigidBodySplit())
            blk = self._userdata[i * self._stride:(i + 1) * self._stride]
            attach.write_parameters(blk, ship, disturbance, split or RigidBodySplit(), packed)
            blk[mcb.U_NEXT] = self._stride if i + 1 < len(self.vessels) else 0.0
            blk[mcb.U_QADR], blk[mcb.U_MADR], blk[mcb.U_CADR] = self._qadr[i], self._madr[i], self._cadr[i]
        mujoco.mj_setConst(self.model, self.data)
        self._sea_arrays = packed
        self._sea_horizon = math.inf if self.environment is None else float(self.environment.horizon)

    def _extend_sea(self, t_end: float) -> None:
        self.environment.ensure_horizon(t_end + SEA_HORIZON_AHEAD_S)
        packed = tuple(self.environment.packed)
        for i in range(len(self.vessels)):
            attach.write_sea(self._userdata[i * self._stride:(i + 1) * self._stride], packed)
        self._sea_arrays = packed
        self._sea_horizon = float(self.environment.horizon)

    # --- plant interface -----------------------------------------------------------------------

    @property
    def n_vessels(self) -> int:
        return len(self.vessels)

    def reset(self, t0: float = 0.0) -> None:
        """Every hull at the origin at rest (then :meth:`reset_vessel` each), time ``t0`` [s]."""
        mujoco.mj_resetData(self.model, self.data)
        if self.environment is not None:
            self.environment.ensure_horizon(max(float(t0), 0.0) + SEA_HORIZON_AHEAD_S)
        self._write_parameters()
        self._t0, self._k = float(t0), 0
        self.data.time = self._t0

    def reset_vessel(self, i: int, eta0, nu0, t0: float = 0.0) -> None:
        """Vessel i at pose eta0 = (x, y, psi) and body velocity nu0 = (u, v, r)."""
        if i == 0:
            self.reset(t0)
        q = self._qadr[i]
        eta0 = np.asarray(eta0, dtype=float)
        nu0 = np.asarray(nu0, dtype=float)
        c, s = math.cos(eta0[2]), math.sin(eta0[2])
        self.data.qpos[q:q + 3] = eta0
        self.data.qvel[q:q + 3] = (c * nu0[0] - s * nu0[1], s * nu0[0] + c * nu0[1], nu0[2])
        mujoco.mj_forward(self.model, self.data)

    def step_vessels(self, forces) -> None:
        """One control period, row i of ``forces`` = (f_u, f_r) held by vessel i (its channels)."""
        t = self._t0 + self._k * self.control_period
        if t + self.control_period > self._sea_horizon:
            self._extend_sea(t + self.control_period)
        ctrl = self.data.ctrl
        for i, (f_u, f_r) in enumerate(forces):
            ctrl[self._cadr[i]] = f_u
            ctrl[self._cadr[i] + 1] = f_r
        self.data.time = t
        mujoco.mj_step(self.model, self.data, self.substeps)
        self._k += 1
        for i in range(len(self.vessels)):
            blk = self._userdata[i * self._stride:]
            if blk[mcb.U_STATUS] != 0.0:
                raise mcb.HydrodynamicCallbackError(
                    f"vessel {self.names[i]!r}: {mcb.STATUS_MESSAGES.get(blk[mcb.U_STATUS], 'callback failure')} "
                    f"at t = {blk[mcb.U_STATUS_TIME]:.4f} s")
        if not self.data.time > t:
            raise mcb.HydrodynamicCallbackError(f"MuJoCo reset the fleet's data (a non-finite state) at t = {t:.4f} s")

    @property
    def states(self) -> np.ndarray:
        out = np.empty((len(self.vessels), 6))
        for i, q in enumerate(self._qadr):
            out[i] = mcb.plant_state(self.data.qpos[q:q + 3], self.data.qvel[q:q + 3])
        return out

    def contacts(self) -> np.ndarray:
        """The normal contact force [N] between each pair of hulls (i < j, in pair order) now."""
        n = len(self.vessels)
        owner = {}
        for i, geoms in enumerate(self._geoms):
            for g in geoms:
                owner[g] = i
        out = np.zeros(n * (n - 1) // 2)
        force = np.zeros(6)
        for c in range(self.data.ncon):
            con = self.data.contact[c]
            a, b = owner.get(int(con.geom1)), owner.get(int(con.geom2))
            if a is None or b is None or a == b:
                continue
            i, j = min(a, b), max(a, b)
            mujoco.mj_contactForce(self.model, self.data, c, force)
            out[i * n - i * (i + 1) // 2 + (j - i - 1)] += abs(force[0])
        return out

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._finalizer()


def _release(plant_id, data_address, userdata):
    userdata[mcb.U_MAGIC] = 0.0
    mcb.CALLBACKS.remove(plant_id, data_address)
