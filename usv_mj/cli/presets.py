"""``usv-mj presets [NAME]``: the scenario and sea presets shipped with the package, or one's TOML."""

from __future__ import annotations

from usv_mj.cli.args import EXIT_OK
from usv_mj.cli.commands import COMMANDS


def add_arguments(p) -> None:
    p.add_argument("name", nargs="?", help="print this preset's TOML (a scenario preset or a sea preset)")


@COMMANDS.register("presets", arguments=add_arguments, help="list the presets or print one",
                   description="Presets are TOML data shipped with the package; a scenario file names one "
                   "with `preset = \"...\"` and overrides any key.")
def run(args) -> int:
    from importlib import resources

    from usv_mj.physics.sea.settings import describe_directions, sea_preset_names, sea_preset_table
    from usv_mj.scenario.spec import load_scenario, preset_names

    if args.name is None:
        for name in preset_names():
            first = (resources.files("usv_mj.scenario.presets") / f"{name}.toml").read_text().splitlines()[0]
            print(f"{name:15s} {first.lstrip('# ')}")
        print("\nsea presets (--sea NAME; directions as in docs/sea.md: compass degrees clockwise from north):")
        for name in sea_preset_names():
            print(f"{name:15s} {describe_directions(sea_preset_table(name))}")
        return EXIT_OK
    if args.name in sea_preset_names():
        print((resources.files("usv_mj.physics.sea.presets") / f"{args.name}.toml").read_text())
        return EXIT_OK
    load_scenario(preset=args.name)  # validates the name with a helpful message
    print((resources.files("usv_mj.scenario.presets") / f"{args.name}.toml").read_text())
    return EXIT_OK
