"""The MJCF models of usv_mj, installed as ``usv_mj.models`` (found through importlib.resources).

- ``usv.xml``: the hull on a planar joint set (slide x, slide y, hinge yaw) with its two actuators;
  MuJoCo carries the rigid body, the passive-force callback the added mass and hydrodynamics.
- ``scene.xml``: the hull in a scene (water plane, sky, light, cameras), as MuJoCo Menagerie lays out
  a model folder; the renderer and the obstacle composition start from it.
"""
