"""``python -m usv_mj.jobs.sweep SWEEP.toml --out DIR ...`` and ``python -m usv_mj.jobs.sweep capability --load ...``."""

import argparse
import sys

from usv_mj.jobs.sweep import add_arguments, add_capability_arguments, capability_command, run_command


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "capability":
        parser = argparse.ArgumentParser(prog="python -m usv_mj.jobs.sweep capability")
        add_capability_arguments(parser)
        return capability_command(parser.parse_args(argv[1:]))
    parser = argparse.ArgumentParser(prog="python -m usv_mj.jobs.sweep")
    add_arguments(parser)
    return run_command(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
