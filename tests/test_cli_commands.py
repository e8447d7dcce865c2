"""The command line's structure (issue 33, What to build 4): commands registered by decorator, each
shared flag declared once with its choices from the registries, a command that cannot be imported
said in one line, and a --help that imports neither numba nor MuJoCo."""

from __future__ import annotations

import argparse
import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

from usv_mj.cli.commands import BUILT_IN, COMMANDS, names
from usv_mj.cli.main import build_parser, main
from usv_mj.core.registry import PLANTS, VESSELS

ROOT = Path(__file__).resolve().parent.parent


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


def _flag(p: argparse.ArgumentParser, flag: str):
    return next((a for a in p._actions if flag in a.option_strings), None)


@pytest.mark.parametrize("name", COMMANDS.kinds())
def test_every_registered_command_answers_help(name, capsys):
    """Each kind of the command registry is a subcommand whose --help prints its usage (exit 0)."""
    with pytest.raises(SystemExit) as done:
        build_parser().parse_args([name, "--help"])
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: usv-mj {name}")
    entry = COMMANDS.get(name)
    assert entry.source == "built-in" and entry.obj.__module__ == BUILT_IN[name]   # registered by its own module
    assert main([name, "--help"]) == 0 and capsys.readouterr().out == out


def test_the_parser_has_exactly_the_registered_commands_and_bare_usage_lists_them(capsys):
    assert list(_subparsers(build_parser())) == names()
    assert set(names()) == set(COMMANDS.kinds())
    assert main([]) == 2
    listed = capsys.readouterr().err.split("commands:", 1)[1].split("\n  usv-mj", 1)[0]
    assert [w.strip(" ,\n") for w in listed.split(",")] == names()


def test_plant_choices_are_the_plant_registry_and_follow_it():
    """--plant's choices are PLANTS.kinds() in every command that has the flag, a kind registered
    at runtime included (no hand-kept list); --vessel's help lists VESSELS.kinds()."""
    with_plant = {n: _flag(p, "--plant") for n, p in _subparsers(build_parser()).items() if _flag(p, "--plant")}
    assert {"run", "manoeuvre", "capability", "scene", "view"} <= set(with_plant)
    for name, action in with_plant.items():
        assert tuple(action.choices) == PLANTS.kinds(), name

    @PLANTS.register("test-cli-plant")
    def factory(options, scenario, **context):  # pragma: no cover - never built
        raise AssertionError

    try:
        choices = _flag(_subparsers(build_parser())["run"], "--plant").choices
        assert "test-cli-plant" in choices and tuple(choices) == PLANTS.kinds()
    finally:
        PLANTS.unregister("test-cli-plant")
    helps = {n: _flag(p, "--vessel").help for n, p in _subparsers(build_parser()).items() if _flag(p, "--vessel")}
    assert {"run", "compare", "env", "manoeuvre"} <= set(helps)
    for name, text in helps.items():
        assert f"({', '.join(VESSELS.kinds())};" in text, name


def test_the_env_task_and_the_manoeuvre_are_checked_against_their_lists(capsys):
    """The env task is one of usv_mj.envs.ALL_TASKS (read when the value is parsed, not for --help:
    usv_mj.envs imports gymnasium), the manoeuvre a kind of the MANOEUVRES registry: a bad one is
    argparse's one line listing them."""
    from usv_mj.envs import ALL_TASKS

    assert main(["env", "nosuch", "--video", "none"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "invalid choice: 'nosuch'" in err
    assert f"(choose from {', '.join(map(repr, ALL_TASKS))})" in err
    from usv_mj.core.registry import MANOEUVRES

    kind = next(a for a in _subparsers(build_parser())["manoeuvre"]._actions if a.dest == "kind")
    assert tuple(kind.choices) == MANOEUVRES.kinds() and "turning" in kind.choices
    assert main(["manoeuvre", "circle"]) == 2
    assert f"(choose from {', '.join(map(repr, MANOEUVRES.kinds()))})" in capsys.readouterr().err
    assert main(["manoeuvre", "--help"]) == 0
    assert f"the manoeuvre: {', '.join(MANOEUVRES.kinds())}" in " ".join(capsys.readouterr().out.split())


def test_each_shared_flag_is_one_declaration():
    """A flag that several commands have reads the same in each (its help text and type), apart from
    the words a command passes for what it writes or sets."""
    parsers = _subparsers(build_parser())
    # (capability's --scenario is a preset or a file in one flag, its own declaration: args.add_base_argument)
    for flag in ("--preset", "--set", "--duration", "--sea", "--plant", "--vessel", "--quiet",
                 "--overwrite", "--debug", "--log-rate", "--size", "--fps", "--speedup", "--camera", "--workers", "--gl",
                 "--live", "--live-port", "--live-wait", "--speed", "--scheduler", "--jobqueue", "--resume",
                 "--max-runs", "--json"):
        seen = {(a.option_strings[0], type(a).__name__, a.type, a.metavar, a.nargs, tuple(a.choices or ()))
                for p in parsers.values() for a in p._actions if flag in a.option_strings}
        assert len(seen) == 1, (flag, seen)
    for flag, text in (("--preset", "base preset"), ("--quiet", "no progress"), ("--overwrite", "usv_mj did not write"),
                       ("--size", "video size in pixels"), ("--workers", "worker processes")):
        assert all(text in a.help for p in parsers.values() for a in p._actions if flag in a.option_strings), flag
    # a bad value of a shared flag is the same one-line error in every command
    for argv in (["run", "--workers", "0"], ["render", "x.mcap", "--workers", "0"], ["sweep", "s.toml", "--workers", "0"]):
        with pytest.raises(SystemExit) as done:
            parsers[argv[0]].parse_args(argv[1:])
        assert done.value.code == 2


def _broken_command(monkeypatch, tmp_path, name: str, body: str) -> None:
    """Command ``name`` served by a module that fails on import with ``body``."""
    (tmp_path / f"broken_{name}_cmd.py").write_text(body)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(COMMANDS._builtins, name, f"broken_{name}_cmd")
    if name in COMMANDS._entries:
        monkeypatch.delitem(COMMANDS._entries, name)


def test_a_command_whose_module_fails_is_one_line_exit_1_and_the_others_still_run(monkeypatch, tmp_path, capsys):
    _broken_command(monkeypatch, tmp_path, "render", "raise RuntimeError('broken on purpose\\nsecond line')\n")
    assert main(["render", "x.mcap", "--size", "64x48"]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert err.startswith("usv-mj render: internal error:") and "RuntimeError: broken on purpose second line" in err
    assert main(["--help"]) == 0                       # listed, not dropped
    assert "render" in capsys.readouterr().out
    assert main(["render", "--help"]) == 1             # its help is the same one line
    assert "usv-mj render: internal error" in capsys.readouterr().err
    assert main(["presets"]) == 0                      # the other commands are untouched
    assert "paper" in capsys.readouterr().out


def test_a_command_missing_an_optional_extra_is_one_line_exit_2(monkeypatch, tmp_path, capsys):
    """An ImportError of an optional dependency (pyproject.toml's extras, usv_mj.core.errors.EXTRAS)
    says what to install, as the library does when it meets one (exit 2)."""
    _broken_command(monkeypatch, tmp_path, "env",
                    "raise ModuleNotFoundError(\"No module named 'gymnasium'\", name='gymnasium')\n")
    assert main(["env", "track"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == 'usv-mj env: error: usv-mj env needs gymnasium, which is not installed: pip install "usv_mj[gym]"'


def test_add_argument_nowhere_outside_the_command_line():
    """No module outside usv_mj/cli declares a flag or reads a parsed Namespace's parser: the calls of
    argparse's API (add_argument, add_argument_group, ArgumentParser, ...) are all in usv_mj/cli
    (tests/test_layers.py checks the imports of argparse; a module can call add_argument on a
    parser it is handed without importing argparse)."""
    api = {"add_argument", "add_argument_group", "add_mutually_exclusive_group", "add_subparsers", "add_parser",
           "parse_args", "parse_known_args", "ArgumentParser", "Namespace"}
    found = []
    for top in ("usv_mj", "controllers"):
        for path in sorted((ROOT / top).rglob("*.py")):
            if "cli" in path.relative_to(ROOT).parts[:2] or "__pycache__" in path.parts:
                continue
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                name = node.attr if isinstance(node, ast.Attribute) else node.id if isinstance(node, ast.Name) else None
                if name in api:
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno} {name}")
    assert not found, "\n".join(found)


def test_help_imports_neither_numba_nor_mujoco():
    """``usv-mj --help`` and every ``usv-mj COMMAND --help`` answer without the numerics (what made
    --help take 1.4-1.9 s was importing numba): checked by what a fresh interpreter has imported
    after building the parser and printing every help, not by a clock."""
    code = (
        "import contextlib, io, json, sys\n"
        "from usv_mj.cli.main import build_parser, main\n"
        "from usv_mj.cli.commands import names\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        "    codes = [main(['--help'])] + [main([n, '--help']) for n in names()]\n"
        "    build_parser().format_help()\n"
        "heavy = ('numba', 'mujoco', 'numpy', 'scipy', 'dm_control', 'gymnasium', 'dask', 'usv_mj.physics.ship',\n"
        "         'usv_mj.scenario.spec')\n"
        "print(json.dumps({'codes': codes, 'imported': [m for m in heavy if m in sys.modules],\n"
        "                  'chars': len(out.getvalue())}))\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["codes"] == [0] * (1 + len(names())) and result["chars"] > 1000
    assert result["imported"] == [], result
