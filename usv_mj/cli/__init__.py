"""Commands: the command line ``usv-mj`` (argparse lives here and nowhere else in the package).

:mod:`usv_mj.cli.main` is the program (``entry``, ``main``, ``build_parser``); :mod:`usv_mj.cli.commands`
the registry every command registers itself in; :mod:`usv_mj.cli.args` the flags the commands share,
each declared once; one module per command (``run``, ``presets``, ``examples``, ``compare``,
``inspect``, ``plot``, ``render``, ``sweep``, ``capability``, ``bench``, ``env``, ``kinds``, ``scene``,
``view``, ``manoeuvre``), each with its flags and a ``run(args) -> int`` that reads them and calls
the library (jobs, outputs, envs) with plain values. Building the parser imports no numba and no
MuJoCo: a command imports the library inside its ``run``.
"""
