"""The hydrodynamics as a reusable piece: put the water under a hull in anyone's MuJoCo model.

MuJoCo alone sees the hull of ``models/usv.xml`` as a rigid body in a vacuum: 100 N of surge for
10 s gives 7.05 m/s instead of the 0.83 m/s of the paper's ship. The water (added mass, its
Coriolis, damping, the uncertainty Delta, the disturbance d(t) and a sea state; docs/model.md §1,
docs/sea.md §6) is the passive-force callback of :mod:`usv_mj.plants.mujoco_callback`. This module
is the one place that writes that callback's parameters into a model; the MuJoCo plant uses it too
(:class:`usv_mj.plants.mujoco_plant.MuJoCoPlant`), so a user's scene and the plant run the same
physics::

    import mujoco, usv_mj
    model = mujoco.MjModel.from_xml_path("scene.xml")      # e.g. from `usv-mj scene --out scene.xml`
    data = mujoco.MjData(model)
    water = usv_mj.attach_hydrodynamics(model, data, body="hull", scenario="paper")
    data.ctrl[:] = (100.0, 0.0)                              # surge [N], yaw [N m]
    while data.time < 10.0:
        mujoco.mj_step(model, data)                          # the hull now floats in the paper's water

Requirements on the model (checked, one clear line if not met):

- the named body moves on three joints of its own, in this order: a slide along world x, a slide
  along world y and a hinge about world z (the body a child of the world, not rotated), and these
  are the model's first three degrees of freedom (put the vessel first in ``<worldbody>``; other
  bodies and joints may follow);
- or on a free joint (``<freejoint/>``), the model's first joint, which the call then **holds to
  the plane**: the hull forces and the added mass act on the free joint's x, y and yaw (its
  world-frame linear and body-frame angular velocity read as the planar joints'), and heave, roll
  and pitch are held by the callback itself, no constraint of the user's needed: each gets a lock
  inertia of :data:`HOLD_LOCK` times the hull's mass (heave) or yaw inertia (roll, pitch) on its
  diagonal of MuJoCo's mass matrix, and a critically damped spring of period
  :data:`HOLD_PERIOD_S` to the level attitude at the body's height in the model (its ``qpos0``).
  Whatever else pushes on the hull out of the plane (gravity, contacts, the user's forces), a load
  F moves it by at most F / k (k = (K + rigid) (2 pi / period)^2: the hull's weight, 2.5e-13 m),
  so the planar motion is the planar joints' (docs/attach.md); the body must not be MuJoCo-"simple"
  (give it an ``<inertial>`` off its origin, e.g. ``pos="0.04 0 0"``: the call writes the values);
- ``<size nuserdata="N"/>`` with N >= :data:`N_USERDATA` (the parameters live in ``d.userdata``);
- the thrust is the user's: any actuators (``models/usv.xml`` has body-frame motors "surge" and
  "yaw" on the site "thruster").

What the call changes: the body's inertial becomes the rigid part of the scenario's ship
(:class:`usv_mj.physics.ship.RigidBodySplit`: mass m11, COM x_g = m23/m11 ahead of the origin, yaw inertia
m33 about the origin) and ``d.userdata`` holds the ship, the disturbance and the sea; the process's
``mjcb_passive`` is set to the native callback while any attachment or plant lives (a model
without the marker in ``d.userdata`` is left alone by it). qpos, qvel, ctrl and time are kept.
Any integrator works; RK4 (``models/usv.xml``'s) is what the plant uses and reproduces its
trajectory to round-off (tests/test_attach.py: 1e-9 m over 10 s), on planar joints and on a free
joint held to the plane alike.
"""

from __future__ import annotations

import math
import threading
import weakref

import mujoco
import numpy as np

from usv_mj.core.errors import expected
from usv_mj.physics.disturbances import packed_disturbance
from usv_mj.physics.sea.environment import run_sea
from usv_mj.physics.ship import RigidBodySplit
from usv_mj.plants import mujoco_callback as mcb

N_USERDATA = mcb.N_USERDATA
SEA_HORIZON_S = 3600.0  # default: the sea's OU grids of an attachment are made this far ahead [s]
HOLD_LOCK = 1e12        # a free hull's heave / roll, pitch lock inertia: this times its mass / yaw inertia [-]
HOLD_PERIOD_S = 1.0     # period of the hold's springs on heave, roll and pitch (critically damped) [s]

_SLIDE, _HINGE = mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_HINGE
_PLANAR = ((_SLIDE, (1.0, 0.0, 0.0), "a slide along x"), (_SLIDE, (0.0, 1.0, 0.0), "a slide along y"),
           (_HINGE, (0.0, 0.0, 1.0), "a hinge about z"))


def hull_body(model: mujoco.MjModel, body: str = "hull", where: str = "the model") -> int:
    """The id of ``body`` after checking that it is a hull the callback can act on, on planar joints
    or on a free joint (module docstring); ValueError naming what is wrong otherwise."""
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    if bid < 0:
        raise ValueError(f"attach_hydrodynamics: no body {body!r} in {where}")
    if model.nuserdata < N_USERDATA:
        raise ValueError(f"attach_hydrodynamics: {where} has nuserdata = {model.nuserdata}; the hydrodynamics need "
                         f"<size nuserdata=\"{N_USERDATA}\"/> or more")
    j0, nj = int(model.body_jntadr[bid]), int(model.body_jntnum[bid])
    if nj == 1 and model.jnt_type[j0] == mujoco.mjtJoint.mjJNT_FREE:
        return _free_hull(model, bid, j0, body, where)
    if nj != 3:
        raise ValueError(f"attach_hydrodynamics: body {body!r} in {where} has {nj} joints; it needs exactly three "
                         f"(slide x, slide y, hinge yaw) or one free joint")
    for k, (kind, axis, label) in enumerate(_PLANAR):
        j = j0 + k
        if model.jnt_type[j] != kind or not np.allclose(model.jnt_axis[j], axis, atol=1e-12):
            raise ValueError(f"attach_hydrodynamics: joint {k + 1} of body {body!r} in {where} must be {label}")
        if model.jnt_dofadr[j] != k or model.jnt_qposadr[j] != k:
            raise ValueError(f"attach_hydrodynamics: the joints of body {body!r} in {where} must be the model's first "
                             f"three degrees of freedom (put the vessel first in <worldbody>)")
    if model.body_parentid[bid] != 0 or not np.allclose(model.body_quat[bid], (1.0, 0.0, 0.0, 0.0), atol=1e-12):
        raise ValueError(f"attach_hydrodynamics: body {body!r} in {where} must be a child of the world, not rotated")
    if list(model.M_rownnz[:3]) != [1, 2, 3]:
        raise ValueError(f"attach_hydrodynamics: the mass matrix of body {body!r} in {where} must be dense 3x3 "
                         f"(M_rownnz = {list(model.M_rownnz[:3])})")
    return bid


def is_free_hull(model: mujoco.MjModel, body: int) -> bool:
    """Whether ``body`` (checked by :func:`hull_body`) moves on a free joint (held to the plane)."""
    return int(model.body_jntnum[body]) == 1 and model.jnt_type[model.body_jntadr[body]] == mujoco.mjtJoint.mjJNT_FREE


def _free_hull(model: mujoco.MjModel, bid: int, joint: int, body: str, where: str) -> int:
    if model.jnt_dofadr[joint] != 0 or model.jnt_qposadr[joint] != 0:
        raise ValueError(f"attach_hydrodynamics: the free joint of body {body!r} in {where} must be the model's "
                         f"first joint (put the vessel first in <worldbody>)")
    if model.body_simple[bid] or list(model.M_rownnz[:6]) != [1, 2, 3, 4, 5, 6]:
        raise ValueError(f"attach_hydrodynamics: body {body!r} in {where} is 'simple' to MuJoCo (its mass matrix is "
                         f"diagonal: M_rownnz = {list(model.M_rownnz[:6])}), with no room for the ship's centre of "
                         f"mass ahead of its origin; give it an <inertial> off its origin, e.g. "
                         f"<inertial pos=\"0.04 0 0\" mass=\"1\" diaginertia=\"1 1 1\"/> (the call writes the ship's)")
    return bid


def hold_parameters(model: mujoco.MjModel, body: int) -> np.ndarray:
    """The hold of a free hull (``d.userdata[U_HOLD:U_HOLD + 10]``, :func:`mujoco_callback.held_free_body_terms`):
    z0 [m] (the body's height in the model), then for heave, roll and pitch the lock inertia K
    (:data:`HOLD_LOCK` times the mass [kg] or the yaw inertia about the origin [kg m^2]), the
    stiffness k = J w^2 and the damping c = 2 J w (critical), with J = K + the rigid body's own
    diagonal of the mass matrix (m; I_xx; I_yy + m x_g^2: COM on the body's x axis) and
    w = 2 pi / :data:`HOLD_PERIOD_S`, so that each held dof alone is the oscillator
    e'' + 2 w e' + w^2 e = F / J (docs/attach.md)."""
    m = float(model.body_mass[body])
    x_g = float(model.body_ipos[body][0])
    ixx, iyy, izz = (float(v) for v in model.body_inertia[body])
    iz_origin = izz + m * x_g * x_g
    w = 2.0 * math.pi / HOLD_PERIOD_S
    out = [float(model.qpos0[2])]
    for lock, rigid in ((HOLD_LOCK * m, m), (HOLD_LOCK * iz_origin, ixx), (HOLD_LOCK * iz_origin, iyy + m * x_g * x_g)):
        j = lock + rigid
        out += [lock, j * w * w, 2.0 * j * w]
    return np.array(out)


def hold_invweights(model: mujoco.MjModel, body: int, hold: np.ndarray) -> None:
    """MuJoCo's inverse weights at qpos0 (``body_invweight0`` of the hull and the bodies on it,
    ``dof_invweight0`` of its free joint), recomputed as ``mj_setConst`` computes them but on the mass
    matrix with the hold's lock inertia: the constraint solver scales a contact's softness (its
    impedance R) by them, and with the lock they are the planar joints' (the same R on the hull)."""
    d = mujoco.MjData(model)
    d.qpos[:] = model.qpos0
    mujoco.mj_kinematics(model, d)
    mujoco.mj_comPos(model, d)
    mujoco.mj_crb(model, d)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, d, full)
    full[2, 2] += hold[1]
    full[3, 3] += hold[4]
    full[4, 4] += hold[7]
    inverse = np.linalg.inv(full)
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    for b in range(1, model.nbody):
        if model.body_rootid[b] != body:
            continue
        mujoco.mj_jacBodyCom(model, d, jacp, jacr, b)
        jac = np.vstack((jacp, jacr))
        a = jac @ inverse @ jac.T
        model.body_invweight0[b] = (np.trace(a[:3, :3]) / 3.0, np.trace(a[3:, 3:]) / 3.0)
    diagonal = np.diag(inverse)
    model.dof_invweight0[0:3] = diagonal[0:3].mean()
    model.dof_invweight0[3:6] = diagonal[3:6].mean()


def set_rigid_body(model: mujoco.MjModel, body: int, ship, split) -> None:
    """Write the rigid part of ``ship`` (``split.rigid_body``: mass [kg], COM offset x_g [m], yaw
    inertia about the origin [kg m^2]) into ``body``'s inertial. Roll and pitch inertias play no
    role in planar motion: plausible values meeting the triangle inequality (0.33 + 0.78 > 1)."""
    m, x_g, iz_origin = split.rigid_body(ship)
    i_cm = iz_origin - m * x_g * x_g
    if not i_cm > 0:
        raise ValueError(f"usv_mj hydrodynamics: the split leaves no yaw inertia about the COM (I_cm = {i_cm:g} kg m^2)")
    model.body_mass[body] = m
    model.body_ipos[body] = (x_g, 0.0, 0.0)
    model.body_iquat[body] = (1.0, 0.0, 0.0, 0.0)
    model.body_inertia[body] = (0.33 * i_cm, 0.78 * i_cm, i_cm)


def write_parameters(ud: np.ndarray, ship, disturbance, split, packed_sea=None) -> None:
    """The callback's parameters into ``d.userdata`` (layout ``mujoco_callback.U_*``): rigid mass
    and COM, the added mass of ``split``, the ship and disturbance arrays, the sea (``packed_sea``:
    ``Environment.packed``, or None for calm water) and last the marker."""
    m, x_g, _ = split.rigid_body(ship)
    ud[:] = 0.0
    ud[mcb.U_MASS] = m
    ud[mcb.U_XG] = x_g
    ud[mcb.U_MA:mcb.U_MA + 9] = split.added_mass(ship).ravel()
    p = ship.as_array()
    ud[mcb.U_P:mcb.U_P + mcb.N_SHIP_PARAMS] = p[:mcb.N_SHIP_PARAMS]
    if len(p) > mcb.N_SHIP_PARAMS:  # an MMG hull's constants (usv_mj.physics.mmg) after the layout
        if len(ud) < mcb.N_USERDATA_MMG:
            raise ValueError(f"usv_mj hydrodynamics: an MMG hull needs nuserdata >= {mcb.N_USERDATA_MMG}, "
                             f"got {len(ud)}")
        ud[mcb.U_MMG:mcb.U_MMG + len(p) - mcb.N_SHIP_PARAMS] = p[mcb.N_SHIP_PARAMS:]
    ud[mcb.U_DP:mcb.U_DP + mcb.N_DIST_WORDS] = packed_disturbance(disturbance)  # any kind's d(t), dispatch word last
    write_sea(ud, packed_sea)
    ud[mcb.U_MAGIC] = mcb.MAGIC


def write_sea(ud: np.ndarray, packed) -> None:
    """Point the callback at the sea's packed arrays (docs/sea.md §6), or calm (``U_SEA_ON`` = 0) for
    None. The caller keeps the arrays alive while their addresses are in ``ud``."""
    if packed is None:
        ud[mcb.U_SEA_ON:mcb.U_SEA_NWG + 1] = 0.0
        return
    ep, waves, cgrid, wgrid = packed
    for name, arr, ndim in (("ep", ep, 1), ("waves", waves, 2), ("current_grid", cgrid, 2),
                            ("wind_grid", wgrid, 2)):
        if not (isinstance(arr, np.ndarray) and arr.dtype == np.float64 and arr.ndim == ndim
                and arr.flags.c_contiguous):
            raise ValueError(f"usv_mj hydrodynamics: environment array {name} must be C-contiguous float64 with "
                             f"{ndim} dimensions")
    if ep.shape != (mcb.N_ENV_PARAMS,) or waves.shape[0] != mcb.N_WAVE_COLS or cgrid.shape[1] != 2 \
            or wgrid.shape[1] != 1:
        raise ValueError(f"usv_mj hydrodynamics: environment arrays have unexpected shapes ep {ep.shape}, waves "
                         f"{waves.shape}, current_grid {cgrid.shape}, wind_grid {wgrid.shape}")
    ud[mcb.U_SEA_EP] = float(ep.ctypes.data)
    ud[mcb.U_SEA_WAVES] = float(waves.ctypes.data)
    ud[mcb.U_SEA_NWAVES] = float(waves.shape[1])
    ud[mcb.U_SEA_CG] = float(cgrid.ctypes.data)
    ud[mcb.U_SEA_NCG] = float(cgrid.shape[0])
    ud[mcb.U_SEA_WG] = float(wgrid.ctypes.data)
    ud[mcb.U_SEA_NWG] = float(wgrid.shape[0])
    ud[mcb.U_SEA_ON] = 1.0


_OWNER: dict[int, int] = {}
"""mjData address -> id of the :class:`Hydrodynamics` whose water it holds: an mjData holds one
attachment, the latest; an earlier handle on the same mjData is superseded and leaves it alone."""
_OWNER_LOCK = threading.Lock()


def _release(handle_id, data_address, userdata):
    """Finalizer (``detach`` or garbage collection): unmark the mjData only if it still holds this
    handle's water (a later attach on the same mjData took it over), then unregister the handle."""
    with _OWNER_LOCK:
        if _OWNER.get(data_address) == handle_id:
            del _OWNER[data_address]
            userdata[mcb.U_MAGIC] = 0.0
    mcb.CALLBACKS.remove(handle_id, data_address)


class Hydrodynamics:
    """An attachment made by :func:`attach_hydrodynamics`: keeps the sea's arrays alive and the
    callback installed until :meth:`detach` (or until it is garbage-collected).

    Attributes: ``model``, ``data``, ``body`` (the hull's body id), ``free`` (True: a free joint
    held to the plane), ``environment`` (the
    :class:`usv_mj.physics.sea.Environment`, None in calm water), ``horizon`` (plant time [s] up to which
    the sea is made; :meth:`extend` makes more).
    """

    callback = "native"  # what the callback registry of the MuJoCo plant reads

    def __init__(self, model, data, body: int, ship, disturbance, split, environment, horizon: float):
        if not ship.inputs_are_forces:  # its inputs are ctrl = (n_P, delta) on gearless motors: the MuJoCo plant's build
            raise ValueError("attach_hydrodynamics: a hull whose inputs are not forces (the MMG's KVLCC2) runs on "
                             "usv_mj's MuJoCo plant only")
        self.model, self.data, self.body = model, data, body
        self.ship, self.disturbance, self.split = ship, disturbance, split
        self.environment = environment if environment is not None and not environment.calm else None
        self._sea = None
        self.horizon = math.inf
        self._finalizer = None
        saved = (data.qpos.copy(), data.qvel.copy(), data.act.copy(), data.ctrl.copy(), data.time)
        set_rigid_body(model, body, ship, split)
        mujoco.mj_setConst(model, data)
        data.qpos[:], data.qvel[:], data.act[:], data.ctrl[:], data.time = saved
        mcb.check_offsets(model, data)
        write_parameters(data.userdata, ship, disturbance, split, None)
        self.free = is_free_hull(model, body)
        if self.free:  # held to the plane (module docstring)
            hold = hold_parameters(model, body)
            hold_invweights(model, body, hold)
            data.userdata[mcb.U_HOLD:mcb.U_HOLD + 10] = hold
            data.userdata[mcb.U_LAYOUT] = mcb.LAYOUT_FREE
        if self.environment is not None:
            self._extend(horizon)
        mcb.CALLBACKS.add(self)
        with _OWNER_LOCK:   # the mjData's water is this handle's now (an earlier one is superseded)
            _OWNER[data._address] = id(self)
        self._finalizer = weakref.finalize(self, _release, id(self), data._address, data.userdata)
        mujoco.mj_forward(model, data)

    @property
    def attached(self) -> bool:
        """Whether the water of this handle is in its mjData: False after :meth:`detach` and after a
        later ``attach_hydrodynamics`` on the same mjData (which takes it over)."""
        return self._finalizer is not None and self._finalizer.alive and \
            _OWNER.get(self.data._address) == id(self)

    def extend(self, t_end: float) -> None:
        """Make the sea's OU grids reach plant time ``t_end`` [s] and re-point the callback at them."""
        if self.environment is None:
            return
        if not self.attached:
            raise ValueError("Hydrodynamics.extend: this handle's water is no longer in its MjData (detached, or "
                             "replaced by a later attach_hydrodynamics on the same data): extend that one")
        self._extend(t_end)

    def _extend(self, t_end: float) -> None:
        self.environment.ensure_horizon(float(t_end))
        self._sea = tuple(self.environment.packed)
        write_sea(self.data.userdata, self._sea)
        self.horizon = float(self.environment.horizon)

    def detach(self) -> None:
        """Remove the water: the callback leaves this mjData alone (and is uninstalled with the last one).
        A handle superseded by a later attach on the same mjData only unregisters itself: the later
        one's water stays. Detaching twice does nothing more."""
        self._finalizer()


def attach_hydrodynamics(model: mujoco.MjModel, data: mujoco.MjData | None = None, body: str = "hull",
                         scenario=None, *, horizon: float = SEA_HORIZON_S) -> Hydrodynamics:
    """Attach the paper's hydrodynamics (and the scenario's sea) to ``body`` of a user's model.

    Parameters
    ----------
    model, data:
        The user's ``mujoco.MjModel`` and its ``mujoco.MjData`` (None: a new one, ``handle.data``).
        Requirements and what is changed: the module docstring.
    body:
        Name of the hull's body (default "hull", as in ``models/usv.xml``).
    scenario:
        A :class:`usv_mj.scenario.spec.Scenario`, a preset name or a scenario TOML path (None: the paper
        preset): its ``[ship]``, ``[disturbance]`` and ``[sea]`` are used (through
        :func:`usv_mj.physics.sea.environment.run_sea`, the build's own sea).
    horizon:
        Plant time [s] up to which a sea's slowly varying parts (the OU grids of current and wind
        gusts) are made at once (calm: unused); past it they hold their last value (the waves go
        on); ``handle.extend(t)`` makes more.

    Returns the :class:`Hydrodynamics` handle; keep it while stepping (``handle.detach()`` ends it).
    """
    from usv_mj.scenario.spec import Scenario, load_scenario, preset_names

    if not isinstance(model, mujoco.MjModel):
        raise expected("attach_hydrodynamics", "model", "a mujoco.MjModel (mujoco.MjModel.from_xml_path(...))", model)
    if data is not None and not isinstance(data, mujoco.MjData):
        raise expected("attach_hydrodynamics", "data", "the model's mujoco.MjData, or None (a new one)", data)
    if not isinstance(body, str):
        raise expected("attach_hydrodynamics", "body", "the hull body's name (str)", body)
    if scenario is None or isinstance(scenario, str):
        if scenario is None or scenario in preset_names():
            scenario = load_scenario(preset=scenario)
        else:
            scenario = load_scenario(scenario)
    if not isinstance(scenario, Scenario):
        raise TypeError(f"attach_hydrodynamics: scenario must be a Scenario, a preset name or a TOML path, "
                        f"got {type(scenario).__name__}")
    if not (isinstance(horizon, (int, float)) and math.isfinite(horizon) and horizon > 0):
        raise ValueError(f"attach_hydrodynamics: horizon must be a finite number of seconds > 0, got {horizon!r}")
    bid = hull_body(model, body)
    data = mujoco.MjData(model) if data is None else data
    env = run_sea(scenario.sea, scenario.ship, float(horizon))
    return Hydrodynamics(model, data, bid, scenario.ship, scenario.disturbance, RigidBodySplit(), env, horizon)
