"""The explicit table of ``rod-sim`` subcommands (rod_sim.tools.cli.COMMANDS): every entry
imports, has a one-line help and a parser, and ``rod-sim --help`` lists exactly the table."""
import argparse
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from rod_sim.tools import cli

ROOT = Path(__file__).resolve().parents[1]


def subparsers(parser: argparse.ArgumentParser) -> dict:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


@pytest.mark.parametrize("name", sorted(cli.COMMANDS))
def test_every_command_imports_and_has_help_a_parser_and_a_run(name):
    module = cli.command_module(name)
    named = cli.COMMANDS[name]      # a module of rod_sim.tools, or a full name (a package's)
    assert module.__name__ == (named if "." in named else f"rod_sim.tools.{named}")
    assert isinstance(module.HELP, str) and module.HELP and "\n" not in module.HELP
    assert callable(module.configure) and callable(module.run)
    parser = argparse.ArgumentParser(prog=f"rod-sim {name}")
    module.configure(parser)
    assert "usage: rod-sim " + name in parser.format_usage()


def test_the_parser_has_exactly_the_commands_of_the_table_in_its_order():
    assert list(subparsers(cli.build_parser())) == list(cli.COMMANDS)


def test_help_lists_every_command_of_the_table():
    done = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "--help"], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    listed = [line.split()[0] for line in done.stdout.split("COMMAND\n", 2)[-1].splitlines()
              if line.startswith("    ") and not line.startswith("     ")]
    assert listed == list(cli.COMMANDS)


def test_an_unknown_command_is_a_usage_error():
    with pytest.raises(SystemExit) as stop:
        cli.build_parser().parse_args(["no-such-command"])
    assert stop.value.code == 2
    with pytest.raises(KeyError):
        cli.command_module("no-such-command")


def test_commands_are_found_without_reading_source_files(tmp_path):
    """A zipped install (setup.py: zip_safe=True) has no .py files to scan: the table alone
    finds every command."""
    archive = tmp_path / "rod_sim.zip"
    with zipfile.ZipFile(archive, "w") as z:
        for path in (ROOT / "rod_sim").rglob("*.py"):
            z.write(path, path.relative_to(ROOT).as_posix())
    code = ("import sys; sys.path.insert(0, sys.argv[1]); from rod_sim.tools import cli; "
            "assert cli.__file__.startswith(sys.argv[1]), cli.__file__; "
            "print(len(cli.plugin_modules()))")
    done = subprocess.run([sys.executable, "-I", "-c", code, str(archive)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert int(done.stdout) == len(cli.COMMANDS)
