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

from usv_mj.cli import args as flags
from usv_mj.cli.commands import COMMANDS
from usv_mj.core.errors import ScenarioError


def add_arguments(p) -> None:
    flags.add_scenario_arguments(p)
    flags.add_out_argument(p, "the MJCF file to write (default scene.xml)", default="scene.xml", metavar="FILE")
    flags.add_overwrite_argument(p, "--out when an earlier usv-mj scene wrote it")
    flags.add_plant_argument(p, default="mujoco", help="the scene is the MuJoCo plant's (the only choice)")


@COMMANDS.register(
    "scene", arguments=add_arguments,
    help="write the scenario's MuJoCo scene (obstacles included) as one MJCF file",
    description="Write the MuJoCo scene the scenario runs in (the hull, the harbour and its obstacles, the\n"
                "time step and the hull's inertial) as one MJCF file. MuJoCo alone sees no water in it:\n"
                "usv_mj.attach_hydrodynamics(model, data, scenario=...) attaches the hull forces and the sea.")
def run(args) -> int:
    from usv_mj.builder import build
    from usv_mj.outputs.outdir import check_file, write_file

    flags.only_mujoco(args.plant, "the scene is the MuJoCo plant's")
    out = Path(args.out)
    if not str(args.out).strip() or out.is_dir():
        raise ScenarioError(f"--out {args.out!r}: name an .xml file to write")
    if out.suffix.lower() != ".xml":
        raise ScenarioError(f"--out {args.out!r}: an MJCF file ends in .xml")
    # a file usv_mj did not write (or a link) is refused, before anything is built or written
    check_file(out, args.overwrite, suffix=".xml", companions=())
    scenario = flags.scenario_from_args(args)
    with build(scenario, duration=min(scenario.duration, 1.0)) as parts:
        text = parts.plant.scene_xml()
    out.parent.mkdir(parents=True, exist_ok=True)
    write_file(out, text)      # whole or not at all, then listed in the folder's manifest
    print(f"usv-mj scene: wrote {out} (the {scenario.source} scene; no water until usv_mj.attach_hydrodynamics)")
    return 0
