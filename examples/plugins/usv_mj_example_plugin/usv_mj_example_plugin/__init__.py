"""An example plug-in package for usv_mj (README, "Write a plug-in").

- :mod:`.pd`: the ``example-pd`` controller, a PD law on the pose error with typed gains and a
  pose-tolerance success criterion;
- :mod:`.lawnmower`: the ``lawnmower`` trajectory, back-and-forth lanes joined by half circles,
  with its own ``[trajectory]`` keys (``lane_length``, ``lane_spacing``);
- :mod:`.squall`: the ``squall`` disturbance, a gust in yaw from ``start`` to ``end`` (a d(t) of
  your own: an options dataclass, ``as_array()`` and a numba kernel).

Installed (``pip install .``), the entry points of ``pyproject.toml`` make the kinds known to
every command; uninstalled, a scenario names them as ``"usv_mj_example_plugin.pd:ExamplePD"``,
``"usv_mj_example_plugin.lawnmower:LawnmowerReference"`` and ``"usv_mj_example_plugin.squall:Squall"``
with this folder on ``PYTHONPATH``.
Importing this package imports none of them (the registries import a module when its kind is named).
"""
