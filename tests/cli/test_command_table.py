"""The command table (pip's commands_dict): --help from the table alone, and a command built only when named."""

from __future__ import annotations

import argparse
import importlib
import re

import pytest

from torchmeshmetric import cli
from torchmeshmetric.cli import COMMANDS, CommandInfo, build_parser, main


def _subparsers(parser: argparse.ArgumentParser) -> argparse._SubParsersAction:
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))


def test_every_command_is_added_by_its_entry_under_its_name_with_the_tables_summary():
    sub = _subparsers(build_parser())
    assert list(sub.choices) == list(COMMANDS)
    helps = {action.dest: action.help for action in sub._choices_actions}
    assert helps == {name: info.summary for name, info in COMMANDS.items()}
    for name, info in COMMANDS.items():
        module = importlib.import_module(info.module_path)
        assert callable(getattr(module, info.add_function)), name
        assert callable(sub.choices[name].get_default("func")), name


def test_only_the_named_command_is_built():
    sub = _subparsers(cli._parser(["evaluate"]))
    assert list(sub.choices) == list(COMMANDS)  # all listed (usage, errors), one with its options
    for name, parser in sub.choices.items():
        options = {o for a in parser._actions for o in a.option_strings}
        assert ("--original" in options) == (name == "evaluate"), name
    assert cli._named_command(["--help"]) == [] and cli._named_command(["nope"]) == []
    assert cli._named_command(["-h", "demo", "--frames", "3"]) == ["demo"]


def test_a_command_of_another_module_joins_with_one_entry(tmp_path, monkeypatch, capsys):
    """How a new command (e.g. ``ctc`` in ``torchmeshmetric/cli/ctc.py``) is added: one line in the table."""
    (tmp_path / "extra_command_for_table_test.py").write_text(
        "def add_hello_command(sub):\n"
        "    p = sub.add_parser('hello', help='say hello', description='Say hello.')\n"
        "    p.add_argument('--name', default='world', help='who')\n"
        "    p.set_defaults(func=lambda args: print(f'hello {args.name}') or 0)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    entry = CommandInfo("extra_command_for_table_test", "add_hello_command", "say hello")
    monkeypatch.setitem(COMMANDS, "hello", entry)
    assert main(["hello", "--name", "table"]) == 0
    assert capsys.readouterr().out == "hello table\n"
    with pytest.raises(SystemExit):
        main(["--help"])
    # the column width follows the longest command name (ctc-face-errors)
    assert re.search(r"^ +hello +say hello$", capsys.readouterr().out, re.M)
