"""The MuJoCo plant in a harbour: the composed scene (hull + obstacles + contacts) behind the plant interface.

:class:`HarbourPlant` loads the scene :func:`usv_mj.scene.compose.compose_scene` makes (written to a
temporary MJCF file, so the plant's checks and callback installation are reused unchanged) and adds
the obstacles' geom and mocap indices, the rangefinders and :meth:`HarbourPlant.move_obstacles`.
"""

from __future__ import annotations

import tempfile

import mujoco
import numpy as np

from usv_mj.core.registry import PLANTS
from usv_mj.physics.ship import PaperDisturbance, RigidBodySplit, ShipParams
from usv_mj.plants.fleet import mujoco_fleet
from usv_mj.plants.mujoco_plant import MuJoCoPlant
from usv_mj.scene.compose import ContactParams, compose_scene, export_scene, obstacle_geom_name
from usv_mj.scene.hull import HULL_COLLISION_GEOMS


class HarbourPlant(MuJoCoPlant):
    """:class:`usv_mj.plants.mujoco_plant.MuJoCoPlant` on the composed harbour model.

    It only adds the composition (written to a temporary MJCF file that the plant loads, so the
    plant's checks and callback installation are reused unchanged), the geom/mocap indices and
    :meth:`move_obstacles`. Name ``"mujoco"``: it is the MuJoCo plant.

    Attributes
    ----------
    obstacles: the :class:`ObstacleSpec` tuple, in model order.
    hull_geoms: geom ids of the hull's collision geoms.
    obstacle_geoms: geom id of each obstacle.
    obstacle_mocap: mocap index of each obstacle (-1: static).
    model_xml_path: the composed file (kept while the plant lives).
    ray_angles: the rangefinders' body-frame angles [rad] (empty: none); read with :meth:`rangefinders`.
    render_model_path: the same scene without the rangefinder sites (MuJoCo draws rangefinder rays),
        for ``usv_mj.outputs.render``; the model file itself when there are none.
    """

    #: what the plant's kernel does not stand in for (both loops call them alike): the kernel
    #: stays MuJoCoPlant's (usv_mj.core.kernels)
    KERNEL_NEUTRAL = frozenset({"rangefinder_adr", "rangefinders", "move_obstacles", "close"})

    def __init__(self, ship: ShipParams, disturbance: PaperDisturbance, obstacles=(), control_period: float = 1e-3,
                 substeps: int = 1, contact: ContactParams = ContactParams(), safety_radii=None,
                 split: RigidBodySplit = RigidBodySplit(), callback: str = "native", environment=None,
                 actuator_limits=None, rangefinders=(), dimensions=None):
        self.obstacles = tuple(obstacles)
        self.contact = contact
        if contact.solref[0] < 2.0 * control_period / substeps:
            raise ValueError(f"HarbourPlant: contact.solref[0] = {contact.solref[0]} s is under twice the MuJoCo "
                             f"time step ({control_period / substeps} s)")
        self.ray_angles = np.asarray(rangefinders, dtype=float).reshape(-1)
        self._tmp = tempfile.TemporaryDirectory(prefix="usv_mj_harbour_")
        self.model_xml_path = export_scene(compose_scene(self.obstacles, contact, safety_radii,
                                                         rangefinders=self.ray_angles), self._tmp.name)
        self.render_model_path = self.model_xml_path
        if self.ray_angles.size:
            self.render_model_path = export_scene(compose_scene(self.obstacles, contact, safety_radii),
                                                  tempfile.mkdtemp(dir=self._tmp.name))
        super().__init__(ship, disturbance, control_period, substeps, split, self.model_xml_path, callback,
                         environment=environment, actuator_limits=actuator_limits, dimensions=dimensions)
        m = self.model
        gid = lambda n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n)  # noqa: E731
        self.hull_geoms = np.array([gid(n) for n, *_ in HULL_COLLISION_GEOMS], dtype=np.int64)
        self.obstacle_geoms = np.array([gid(obstacle_geom_name(o)) for o in self.obstacles], dtype=np.int64)
        self.obstacle_mocap = np.full(len(self.obstacles), -1, dtype=np.int64)
        for i, o in enumerate(self.obstacles):
            if o.moving:
                body = m.geom_bodyid[self.obstacle_geoms[i]]
                self.obstacle_mocap[i] = m.body_mocapid[body]
        self._moving_list = np.flatnonzero(self.obstacle_mocap >= 0).tolist()
        self._velocity = np.array([o.velocity for o in self.obstacles], dtype=float).reshape(-1, 2)
        self._center0 = np.array([o.center for o in self.obstacles], dtype=float).reshape(-1, 2)
        self._sensor_adr = np.array([m.sensor_adr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, f"range_{i}")]
                                     for i in range(self.ray_angles.size)], dtype=np.int64)

    @property
    def rangefinder_adr(self) -> np.ndarray:
        """Where each rangefinder's reading is in ``data.sensordata`` (int64, :attr:`ray_angles` order)."""
        return self._sensor_adr

    def rangefinders(self) -> np.ndarray:
        """Rangefinder readings [m] along :attr:`ray_angles` (-1: nothing hit) at the current state:
        kinematics, then MuJoCo's position-stage sensors (after ``mj_step`` the sensor data are
        those of the last step's start)."""
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_sensorPos(self.model, self.data)
        return self.data.sensordata[self._sensor_adr].copy()

    def move_obstacles(self, t: float) -> None:
        """Put every moving obstacle at center + velocity t (held during the next step)."""
        for i in self._moving_list:
            j = self.obstacle_mocap[i]
            self.data.mocap_pos[j, 0] = self._center0[i, 0] + self._velocity[i, 0] * t
            self.data.mocap_pos[j, 1] = self._center0[i, 1] + self._velocity[i, 1] * t

    def close(self) -> None:
        super().close()
        self._tmp.cleanup()


@PLANTS.register("mujoco", rangefinders=True, fleet=mujoco_fleet)
def mujoco_plant(options, scenario, environment=None, obstacles=(), contact=None, safety_radii=None, rangefinders=()):
    """The MuJoCo plant of ``scenario`` (``options``: None, it has none): the hull of
    ``models/usv.xml`` in open water (:class:`MuJoCoPlant`), or the scene composed from the hull
    and ``obstacles`` (with its contact model) when there are any or when ``rangefinders``
    (body-frame ray angles [rad]) asks for range sensors on the hull (:class:`HarbourPlant`); the
    sea ``environment`` acts on the hull in both."""
    if not (len(obstacles) or len(rangefinders)):
        return MuJoCoPlant.from_scenario(options, scenario, environment=environment)
    vessel = scenario.vessel.model  # its rigid body and dimensions (scenario.ship: its packed hull)
    return HarbourPlant(scenario.ship, scenario.disturbance, obstacles, scenario.control_period,
                        scenario.plant.substeps, contact or ContactParams(), safety_radii,
                        split=vessel.split, environment=environment,
                        actuator_limits=scenario.actuators.generalized_limits(), rangefinders=rangefinders,
                        dimensions=vessel.dimensions)
