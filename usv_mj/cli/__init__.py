"""Commands: the command line ``usv-mj`` (argparse lives here and nowhere else in the package).

:mod:`usv_mj.cli.main` is the program (``entry``); one module per command.
"""
