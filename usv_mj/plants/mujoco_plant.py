"""The MuJoCo plant: the paper's ship on MuJoCo's rigid-body engine plus a hydrodynamic callback.

MuJoCo integrates the hull of ``models/usv.xml`` (joints x, y, yaw; RK4) with the rigid-body part
of :class:`usv_mj.physics.ship.RigidBodySplit`; the passive-force callback of
:mod:`usv_mj.plants.mujoco_callback` adds the added mass (exactly, through the mass matrix), the
Coriolis of the added mass, damping, the uncertainty Delta and the disturbance d(t) (docs/model.md §1). The
thrust enters through the two body-frame motors "surge" [N] and "yaw" [N m] and is held over each
control period (zero-order hold), exactly as in :class:`usv_mj.plants.analytic.AnalyticPlant`.

The passive callback is process-global in MuJoCo. This module installs it when the first plant is
made and removes it (restoring what was there before) when the last one is closed. The native
callback (numba ``cfunc``, the default) reads every parameter from the mjData it is called with,
so any number of plants with different ships coexist; the Python callback (``callback="python"``,
a reference and fallback) looks plants up by their mjData address and hands mjData it does not
know to the native callback.

Sea state (docs/sea.md §6): with a non-calm :class:`usv_mj.physics.sea.Environment` the callback's hydrodynamic
term becomes :func:`usv_mj.physics.sea.sea_force` (current through nu_r in C and D, wave, drift and wind
loads, M nu_c_dot); the C_RB nu and exact added-mass terms are as in calm water. Calm (None or a
calm environment) takes exactly the path of before the sea existed (bit-identical runs).
"""

from __future__ import annotations

import math
import os
import re
import weakref

import mujoco
import numpy as np

from usv_mj.physics.ship import PaperDisturbance, RigidBodySplit, ShipParams

from usv_mj.plants import attach
from usv_mj.plants import mujoco_callback as mcb
from usv_mj.plants.base import PlantBase
from usv_mj.scene.hull import scale_hull

DEFAULT_MODEL = os.path.join(mcb.MODELS_DIR, "usv.xml")

_BAD_WARNINGS = ((mujoco.mjtWarning.mjWARN_BADQPOS, "qpos"), (mujoco.mjtWarning.mjWARN_BADQVEL, "qvel"),
                 (mujoco.mjtWarning.mjWARN_BADQACC, "qacc"))
_mj_step = mujoco.mj_step
CTRL_OPEN = 1e10  # ctrlrange of a side without a limit [N, N m] (past limits.max_force's default)
SEA_HORIZON_AHEAD_S = 120.0  # the environment's OU grids are kept this far ahead of the plant time [s]


def _release(plant_id, data_address, userdata):
    """Finalizer: unmark the mjData (the callback then ignores it) and unregister the plant."""
    userdata[mcb.U_MAGIC] = 0.0
    mcb.CALLBACKS.remove(plant_id, data_address)


def _check_actuator_limits(limits):
    """None, or (tau_u_min, tau_u_max, tau_r_min, tau_r_max) with min < 0 < max (inf: open)."""
    if limits is None:
        return None
    limits = tuple(float(v) for v in limits)
    if len(limits) != 4 or not (limits[0] < 0 < limits[1] and limits[2] < 0 < limits[3]):
        raise ValueError(f"MuJoCoPlant: actuator_limits must be (tau_u_min < 0 < tau_u_max, "
                         f"tau_r_min < 0 < tau_r_max), got {limits!r}")
    return limits


class MuJoCoPlant(PlantBase):
    """The ship of docs/model.md §1 integrated by MuJoCo (RK4) with a hydrodynamic passive-force callback.

    Parameters
    ----------
    ship, disturbance:
        The physics (:mod:`usv_mj.physics.ship`); the model's inertial is overwritten from ``ship`` and
        ``split`` at load, so ``models/usv.xml`` holds only defaults.
    control_period:
        Hold time of the input [s].
    substeps:
        RK4 steps (``mj_step`` calls) per control period (>= 1); MuJoCo's timestep is
        control_period/substeps.
    split:
        How the mass is shared between MuJoCo's rigid body and the callback's added mass; any valid
        split gives the same motion (tested).
    model_path:
        MJCF file with a body "hull" on slide joints "x", "y" and hinge "yaw" and motors "surge" and
        "yaw" (default ``models/usv.xml``; ``models/scene.xml`` works too). It is loaded through
        ``MjSpec`` so that ``nuserdata`` can be enlarged when needed.
    callback:
        "native" (numba cfunc, default) or "python" (the same physics kernel called from a Python
        callback: slower, useful as a reference).
    native_step:
        With the native callback, advance through :func:`mujoco_callback.mujoco_kernel` (mj_step
        called from compiled code, state computed there; the compiled loop's kernel of this plant)
        instead of the Python bindings; the result is identical, only faster.
    environment:
        A :class:`usv_mj.physics.sea.Environment` (waves, current, wind; docs/sea.md §1, §6) or None for calm
        water. The plant keeps it and its packed arrays alive, extends its OU grids ahead of the
        plant time (:data:`SEA_HORIZON_AHEAD_S`) and re-writes the arrays' addresses into
        ``d.userdata`` when they grow. A calm environment is treated as None.
    actuator_limits:
        (tau_u_min, tau_u_max, tau_r_min, tau_r_max) [N, N, N m, N m] written into the motors'
        ``ctrlrange`` (``ctrllimited``) at load, or None (the file's, unlimited); ``from_scenario``
        passes ``[actuators]``'s :meth:`~usv_mj.physics.actuators.ActuatorSpec.generalized_limits`.
    dimensions:
        The vessel's main dimensions (:class:`usv_mj.vessels.Dimensions`): the geoms, sites and
        cameras of body "hull" are scaled from the model file's hull
        (:data:`usv_mj.vessels.PAPER_DIMENSIONS`) to them at load (:func:`scale_hull`); None or
        the paper's: the file as it is. ``from_scenario`` passes the scenario's vessel's, and its
        rigid body as ``split``.

    A hull whose inputs are not forces (``ship.inputs_are_forces`` False: the MMG's KVLCC2) loads with the motors' gear set to zero and
    ``nuserdata`` >= ``N_USERDATA_MMG``: ``ctrl`` = (n_P [1/s], delta [rad]) is then the actuator
    input and the callback makes the propeller's and the rudder's force from it (usv_mj.physics.mmg).

    Attributes
    ----------
    model, data:
        The ``mujoco.MjModel`` / ``mujoco.MjData`` (for renderers and environments; ``data.qpos``
        = (x, y, psi), ``data.qvel`` = (x_dot, y_dot, r) in the world frame). After :meth:`step`
        the derived quantities (``xpos``, ``xmat``, ...) are those of the last RK4 stage, as always
        after ``mj_step``: call ``mujoco.mj_kinematics(model, data)`` before drawing from ``data``.
        Do not change ``userdata`` (the callback's parameters) or the inertial of body "hull".
    """

    name = "mujoco"

    def __init__(self, ship: ShipParams, disturbance: PaperDisturbance, control_period: float = 1e-3,
                 substeps: int = 1, split: RigidBodySplit = RigidBodySplit(), model_path: str | None = None,
                 callback: str = "native", native_step: bool = True, environment=None, actuator_limits=None,
                 dimensions=None):
        self.dimensions = dimensions
        self.actuator_limits = _check_actuator_limits(actuator_limits)
        if not (isinstance(control_period, (int, float)) and math.isfinite(control_period) and control_period > 0):
            raise ValueError(f"MuJoCoPlant: control_period must be a finite number > 0 s, got {control_period!r}")
        if int(substeps) != substeps or int(substeps) < 1:
            raise ValueError(f"MuJoCoPlant: substeps must be an integer >= 1, got {substeps!r}")
        if callback not in ("native", "python"):
            raise ValueError(f"MuJoCoPlant: callback must be 'native' or 'python', got {callback!r}")
        self.ship, self.disturbance, self.split = ship, disturbance, split
        self.control_period = float(control_period)
        self.substeps = int(substeps)
        self.callback = callback
        if environment is not None and not hasattr(environment, "packed"):
            raise TypeError(f"MuJoCoPlant: environment must be a usv_mj.physics.sea.Environment or None, "
                            f"got {type(environment).__name__}")
        self.environment = environment if environment is not None and not environment.calm else None
        if self.environment is not None and ship.calm_water_only:
            raise ValueError("MuJoCoPlant: this hull's model holds in calm water only (no [sea])")
        self._sea_arrays = None        # the packed arrays whose addresses are in d.userdata
        self._sea_horizon = math.inf   # plant time up to which they are valid [s]
        self.model_path = os.path.abspath(model_path or DEFAULT_MODEL)
        self.model, self.data = self._load(self.model_path)
        self._set_parameters()
        mcb.check_offsets(self.model, self.data)
        self._qpos, self._qvel, self._ctrl = self.data.qpos, self.data.qvel, self.data.ctrl
        self._userdata = self.data.userdata
        self._python_error: BaseException | None = None
        self._scratch = (np.zeros(3), np.zeros(6))
        self._closed = False
        self._t0, self._k = 0.0, 0
        self._x = None
        self._m_addr, self._d_addr = self.model._address, self.data._address
        # native stepping (no Python between mj_step and the state) with the native callback
        self._native_step = callback == "native" and bool(native_step)
        self._step_x = np.zeros(6)  # mujoco_kernel's (unused) state argument
        mcb.CALLBACKS.add(self)
        self._finalizer = weakref.finalize(self, _release, id(self), self.data._address, self._userdata)
        self.reset((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))

    # --- construction --------------------------------------------------------------------------

    def _load(self, path: str):
        if not os.path.isfile(path):
            raise FileNotFoundError(f"MuJoCoPlant: model file not found: {path}")
        spec = mujoco.MjSpec.from_file(path)
        scale_hull(spec, self.dimensions)
        need = mcb.N_USERDATA + len(self.ship.as_array()) - mcb.N_SHIP_PARAMS   # the packed hull's own words too
        if spec.nuserdata < need:
            spec.nuserdata = need
        if not self.ship.inputs_are_forces:  # the motors carry the hull's channels (n_P, delta); the callback makes the force
            for act in spec.actuators:
                act.gear = [0.0] * 6
        self._set_ctrlrange(spec)
        model = spec.compile()
        where = f"in {path}"
        names = {
            "body hull": (mujoco.mjtObj.mjOBJ_BODY, "hull"),
            "joint x": (mujoco.mjtObj.mjOBJ_JOINT, "x"),
            "joint y": (mujoco.mjtObj.mjOBJ_JOINT, "y"),
            "joint yaw": (mujoco.mjtObj.mjOBJ_JOINT, "yaw"),
            "actuator surge": (mujoco.mjtObj.mjOBJ_ACTUATOR, "surge"),
            "actuator yaw": (mujoco.mjtObj.mjOBJ_ACTUATOR, "yaw"),
        }
        ids = {}
        for label, (kind, name) in names.items():
            ids[label] = mujoco.mj_name2id(model, kind, name)
            if ids[label] < 0:
                raise ValueError(f"MuJoCoPlant: {label} not found {where}")
        if model.nq != 3 or model.nv != 3 or model.nu != 2:
            raise ValueError(f"MuJoCoPlant: the model {where} must have exactly the 3 joints x, y, yaw and the "
                             f"2 motors surge, yaw (nq = {model.nq}, nv = {model.nv}, nu = {model.nu})")
        if [model.jnt_qposadr[ids[f"joint {j}"]] for j in ("x", "y", "yaw")] != [0, 1, 2]:
            raise ValueError(f"MuJoCoPlant: joints x, y, yaw {where} must be in this order")
        if [ids["actuator surge"], ids["actuator yaw"]] != [0, 1]:
            raise ValueError(f"MuJoCoPlant: actuators surge, yaw {where} must be in this order")
        if model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4:
            raise ValueError(f"MuJoCoPlant: the model {where} must use integrator='RK4'")
        if list(model.M_rownnz) != [1, 2, 3]:
            raise ValueError(f"MuJoCoPlant: the mass matrix {where} must be dense 3x3 (hull body not 'simple'); "
                             f"M_rownnz = {list(model.M_rownnz)}")
        self._hull = ids["body hull"]
        self._spec = spec  # for scene_xml()
        data = mujoco.MjData(model)
        return model, data

    def scene_xml(self) -> str:
        """The MJCF text of the scene this plant runs: its model file (the composed harbour with its
        obstacles, or ``models/usv.xml``) with the hull's inertial, the time step, gravity and the
        motors' ranges as loaded. MuJoCo alone sees no water in it: attach the hydrodynamics with
        :func:`usv_mj.attach_hydrodynamics` (the same parameters as this plant's)."""
        self._check_open()
        spec, model = self._spec, self.model
        hull = spec.body("hull")
        hull.mass = float(model.body_mass[self._hull])
        hull.ipos = model.body_ipos[self._hull].copy()
        hull.iquat = model.body_iquat[self._hull].copy()
        hull.inertia = model.body_inertia[self._hull].copy()
        hull.explicitinertial = True
        spec.option.timestep = float(model.opt.timestep)
        spec.option.gravity = model.opt.gravity.copy()
        # MuJoCo writes 6 significant digits: the time step in full, so that 1e-3 / 3 s survives
        step = repr(float(model.opt.timestep))
        return re.sub(r'(<option\b[^>]*?\btimestep=")[^"]*(")', lambda mt: mt.group(1) + step + mt.group(2),
                      spec.to_xml(), count=1)

    def _set_ctrlrange(self, spec) -> None:
        """The motors' ``ctrlrange`` from the scenario's actuator limits (ctrllimited where a side is
        finite; an open side is +-CTRL_OPEN). The loop's actuator model (usv_mj.physics.actuators) has
        already limited the command, so MuJoCo's clamp does not change it: the model file shows the
        same vessel to a MuJoCo user (``spec.to_xml()``, ``model.actuator_ctrlrange``)."""
        if self.actuator_limits is None:
            return
        lo_u, hi_u, lo_r, hi_r = self.actuator_limits
        by_name = {a.name: a for a in spec.actuators}
        for name, lo, hi in (("surge", lo_u, hi_u), ("yaw", lo_r, hi_r)):
            act = by_name.get(name)
            if act is None or (math.isinf(lo) and math.isinf(hi)):
                continue
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrlrange = [max(lo, -CTRL_OPEN), min(hi, CTRL_OPEN)]

    def _set_parameters(self) -> None:
        """Write the rigid body (model) and the callback's parameters (d.userdata) from ship.py, by the
        one path a user's own model takes too (:mod:`usv_mj.plants.attach`)."""
        model = self.model
        attach.set_rigid_body(model, self._hull, self.ship, self.split)
        model.opt.timestep = self.control_period / self.substeps
        model.opt.gravity[:] = 0.0
        mujoco.mj_setConst(model, self.data)
        self._write_sea(self.data.userdata, sea_only=False)

    def _write_sea(self, ud, sea_only: bool = True) -> None:
        """Point the callback at the environment's packed arrays (docs/sea.md §6); calm: U_SEA_ON = 0.
        ``sea_only=False`` writes every parameter (``attach.write_parameters``)."""
        env = self.environment
        packed = None if env is None else tuple(env.packed)
        if sea_only:
            attach.write_sea(ud, packed)
        else:
            attach.write_parameters(ud, self.ship, self.disturbance, self.split, packed)
        self._sea_arrays = packed  # keeps them alive while their addresses are in userdata
        self._sea_horizon = math.inf if env is None else float(env.horizon)

    def _extend_sea(self, t_end: float) -> None:
        """Grow the environment's grids past ``t_end`` [s] and refresh the addresses in userdata."""
        self.environment.ensure_horizon(t_end + SEA_HORIZON_AHEAD_S)
        self._write_sea(self._userdata)

    # --- plant interface -----------------------------------------------------------------------

    def reset(self, eta0, nu0, t0: float = 0.0) -> None:
        """Pose eta0 = (x, y, psi) [m, m, rad], body velocity nu0 = (u, v, r), time t0 [s]."""
        self._check_open()
        eta0 = _vector3(eta0, "eta0")
        nu0 = _vector3(nu0, "nu0")
        if not math.isfinite(t0):
            raise ValueError(f"MuJoCoPlant.reset: t0 must be finite, got {t0!r}")
        mujoco.mj_resetData(self.model, self.data)
        if self.environment is not None:
            self.environment.ensure_horizon(max(float(t0), 0.0) + SEA_HORIZON_AHEAD_S)
        self._set_parameters()
        c, s = math.cos(eta0[2]), math.sin(eta0[2])
        self._qpos[:] = eta0
        self._qvel[:] = (c * nu0[0] - s * nu0[1], s * nu0[0] + c * nu0[1], nu0[2])
        self._ctrl[:] = 0.0
        self._t0, self._k = float(t0), 0
        self._x = None
        self.data.time = self._t0
        self._python_error = None
        mujoco.mj_forward(self.model, self.data)  # consistent derived quantities for renderers
        self._raise_if_failed()

    def step(self, tau_u: float, tau_r: float) -> None:
        """Advance one control period with surge force tau_u [N] and yaw moment tau_r [N m] held."""
        # time from the step count (as the analytic plant): no drift from summing dt
        t = self.time_at(self._k)
        if t + self.control_period > self._sea_horizon:
            self._extend_sea(t + self.control_period)
        if self._native_step:  # the kernel of the compiled loop, one step
            self._x, failed = mcb.mujoco_kernel(self._k, self._step_x, float(tau_u), float(tau_r), self._m_addr,
                                                self._d_addr, self._t0, self.control_period, self.substeps,
                                                *mcb.kernel_constants())
            self._k += 1
            if failed:
                self._raise_after_step(t)
            return
        ctrl = self._ctrl
        ctrl[0] = tau_u
        ctrl[1] = tau_r
        d = self.data
        d.time = t
        if self.substeps == 1:
            _mj_step(self.model, d)
        else:
            _mj_step(self.model, d, self.substeps)
        self._k += 1
        self._x = None
        # MuJoCo's NaN guard resets mjData (time back to 0) with a warning; the callback records
        # its own failures in userdata: both are checked with two cheap reads
        if self._userdata[mcb.U_STATUS] != 0.0 or self._python_error is not None or not d.time > t:
            self._raise_after_step(t)

    def kernel(self, t_end: float):
        """(mujoco_kernel, the model and data) for the compiled loop, steps up to ``t_end`` [s] (the
        sea's grids extended past it first); None with the Python callback."""
        from usv_mj.core.kernels import Kernel

        if self.callback != "native":
            return None
        self._check_open()
        if t_end + self.control_period > self._sea_horizon:
            self._extend_sea(t_end + self.control_period)

        def sync(k, x):
            self._k, self._x = k, x

        def fail(k):  # the k-th step failed: raise its error as step() does
            self._k = k + 1
            self._raise_after_step(self.time_at(k))

        return Kernel(mcb.mujoco_kernel, (self._m_addr, self._d_addr, self._t0, self.control_period, self.substeps,
                                          *mcb.kernel_constants()), sync, fail,
                      state=())   # it writes the mjData behind d_addr (one per plant), no argument

    def _raise_after_step(self, t: float) -> None:
        self._x = None
        if self._userdata[mcb.U_STATUS] != 0.0 or self._python_error is not None:
            self._raise_if_failed()
        if not self.data.time > t:
            self._raise_reset()

    @property
    def time(self) -> float:
        return self.time_at(self._k)

    @property
    def step_count(self) -> int:
        """Control periods stepped since the last :meth:`reset` (the ``k`` of :meth:`kernel`'s steps)."""
        return self._k

    def time_at(self, k: int) -> float:
        """The plant's :attr:`time` [s] after ``k`` steps from the last reset (t0 + k control periods)."""
        return self._t0 + k * self.control_period

    @property
    def state(self) -> np.ndarray:
        """(x, y, psi, u, v, r): pose [m, m, rad, psi unwrapped] and body velocity [m/s, m/s, rad/s].

        The state after the last :meth:`step` or :meth:`reset` (writes to ``data`` made in between
        are not seen until the next step). A copy: editing it moves nothing and changes nothing
        that the plant reports later, as on the analytic plant.
        """
        if self._x is not None:
            return self._x.copy()
        return mcb.plant_state(self._qpos, self._qvel)

    def body_acceleration(self, tau_u: float | None = None, tau_r: float | None = None) -> np.ndarray:
        """MuJoCo's body-frame acceleration nu_dot [m/s^2, m/s^2, rad/s^2] at the current state.

        Runs ``mj_forward`` (which calls the callback) with the given thrust (default: the held
        one) and maps qacc back: nu_dot = J^T qacc - r [-v, u, 0].
        """
        self._check_open()
        if tau_u is not None:
            self._ctrl[0] = tau_u
        if tau_r is not None:
            self._ctrl[1] = tau_r
        self.data.time = self.time
        if self.time > self._sea_horizon:
            self._extend_sea(self.time)
        mujoco.mj_forward(self.model, self.data)
        self._raise_if_failed()
        x = self.state
        c, s = math.cos(x[2]), math.sin(x[2])
        qa = self.data.qacc
        u, v, r = x[3], x[4], x[5]
        return np.array((c * qa[0] + s * qa[1] + r * v, -s * qa[0] + c * qa[1] - r * u, qa[2]))

    @classmethod
    def from_scenario(cls, options, scenario, environment=None, **_):
        """The MuJoCo plant of ``scenario`` in open water (``options``: None, it has none): the hull
        of ``models/usv.xml`` sized to the vessel, the sea ``environment`` acting on it. The plant
        kind "mujoco" (:func:`usv_mj.plants.harbour.mujoco_plant`) makes this or, with obstacles or
        rangefinders, a :class:`usv_mj.plants.harbour.HarbourPlant`."""
        vessel = scenario.vessel.model  # its rigid body and dimensions (scenario.ship: its packed hull)
        return cls(scenario.ship, scenario.disturbance, scenario.control_period, scenario.plant.substeps,
                   split=vessel.split, environment=environment, actuator_limits=scenario.actuators.generalized_limits(),
                   dimensions=vessel.dimensions)

    def close(self) -> None:
        """Unmark the mjData and remove the global callback if this was the last plant."""
        if not self._closed:
            self._closed = True
            self._finalizer()

    # --- errors --------------------------------------------------------------------------------

    def _python_passive(self, m, d) -> None:
        """Python callback body: the shared kernel, with every exception kept for after the step."""
        if self._python_error is not None:
            return
        try:
            qf, ma = self._scratch
            status = mcb.passive_terms(self._userdata, d.time, d.qpos, d.qvel, d.ctrl, qf, ma)
            if not mcb.record_call(self._userdata, status, d.time):
                return
            d.qfrc_passive[:] += qf
            d.M[:6] += ma
            mujoco.mj_factorM(m, d)
        except BaseException as exc:  # noqa: BLE001 - must not reach MuJoCo
            self._python_error = exc
            self._userdata[mcb.U_STATUS] = mcb.STATUS_EXCEPTION
            self._userdata[mcb.U_STATUS_TIME] = d.time

    def _raise_if_failed(self) -> None:
        ud = self._userdata
        status = float(ud[mcb.U_STATUS])
        if status == 0.0 and self._python_error is None:
            return
        t = float(ud[mcb.U_STATUS_TIME])
        exc = self._python_error
        ud[mcb.U_STATUS] = 0.0
        self._python_error = None
        message = mcb.STATUS_MESSAGES.get(status, f"status {status}")
        state = ", ".join(f"{v:.6g}" for v in self.state)
        text = (f"MuJoCoPlant: hydrodynamic callback failed at t = {t:.6f} s: {message}"
                + (f" ({type(exc).__name__}: {exc})" if exc is not None else "")
                + f"; state after the step (x, y, psi, u, v, r) = ({state})")
        raise mcb.HydrodynamicCallbackError(text) from exc

    def _raise_reset(self) -> None:
        w = self.data.warning
        found = [label for kind, label in _BAD_WARNINGS if w[kind].number]
        for kind, _ in _BAD_WARNINGS:
            w[kind].number = 0
        t = self.time - self.control_period
        raise mcb.HydrodynamicCallbackError(
            f"MuJoCoPlant: MuJoCo found a NaN, Inf or huge value in {' and '.join(found) or 'the state'} during the "
            f"step from t = {t:.6f} s and reset the simulation (inputs held: tau_u = {self._ctrl[0]!r} N, "
            f"tau_r = {self._ctrl[1]!r} N m)")

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("MuJoCoPlant: the plant is closed")


def _vector3(value, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"MuJoCoPlant.reset: {name} must be 3 numbers, got {value!r}") from exc
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"MuJoCoPlant.reset: {name} must be 3 finite numbers, got {value!r}")
    return arr
