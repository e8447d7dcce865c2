"""An example plug-in package for usv_mj (README, "Write a plug-in").

- :mod:`.pd`: the ``example-pd`` controller, a PD law on the pose error with typed gains and a
  pose-tolerance success criterion;
- :mod:`.lawnmower`: the ``lawnmower`` trajectory, back-and-forth lanes joined by half circles,
  with its own ``[trajectory]`` keys (``lane_length``, ``lane_spacing``).

Installed (``pip install .``), the entry points of ``pyproject.toml`` make both kinds known to
every command; uninstalled, a scenario names them as ``"usv_mj_example_plugin.pd:ExamplePD"`` and
``"usv_mj_example_plugin.lawnmower:LawnmowerReference"`` with this folder on ``PYTHONPATH``.
Importing this package imports neither module (the registries import them when a kind is named).
"""
