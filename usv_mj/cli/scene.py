"""``usv-mj scene``: write the MuJoCo scene a scenario runs in, as one MJCF file.

The scene is the one the build makes (:func:`usv_mj.build`): ``models/usv.xml`` in open water, or
the harbour composed with the scenario's obstacles (:mod:`usv_mj.scene.compose`), with the
hull's inertial, the time step and the motors' ranges the plant loaded (:meth:`MuJoCoPlant.scene_xml`).
MuJoCo alone sees no water in it; :func:`usv_mj.attach_hydrodynamics` puts the water back::

    usv-mj scene --scenario examples/scenarios/harbour_gap.toml --out scene.xml
    python -m mujoco.viewer --mjcf=scene.xml        # the scene, hull in a vacuum
    python -m usv_mj.cli.view --scenario ...           # the scene with water, controller and sea
"""

from __future__ import annotations

from pathlib import Path

from usv_mj.core.errors import ScenarioError


def add_arguments(p) -> None:
    from usv_mj.cli.args import add_scenario_arguments

    add_scenario_arguments(p)
    p.add_argument("--out", metavar="FILE", default="scene.xml", help="the MJCF file to write (default scene.xml)")
    p.add_argument("--plant", choices=("mujoco",), default="mujoco", help="the scene is the MuJoCo plant's (the only choice)")


def run_command(args) -> int:
    from usv_mj.builder import build
    from usv_mj.cli.args import scenario_from_args

    out = Path(args.out)
    if not str(args.out).strip() or out.is_dir():
        raise ScenarioError(f"--out {args.out!r}: name an .xml file to write")
    if out.suffix.lower() != ".xml":
        raise ScenarioError(f"--out {args.out!r}: an MJCF file ends in .xml")
    scenario = scenario_from_args(args)
    with build(scenario, duration=min(scenario.duration, 1.0)) as parts:
        text = parts.plant.scene_xml()
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    print(f"usv-mj scene: wrote {out} (the {scenario.source} scene; no water until usv_mj.attach_hydrodynamics)")
    return 0
