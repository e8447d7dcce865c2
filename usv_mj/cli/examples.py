"""``usv-mj examples``: the example scenarios and sweeps shipped with the package."""

from __future__ import annotations

from usv_mj.cli.args import EXIT_OK
from usv_mj.cli.commands import COMMANDS


@COMMANDS.register("examples", help="list the example scenarios and sweeps",
                   description="The example scenarios and sweeps shipped with the package, each found by its "
                   "name: usv-mj run --scenario harbour_gap, usv-mj sweep quick (a path works too).")
def run(args) -> int:
    from usv_mj.support.example_files import listing

    print(listing())
    return EXIT_OK
