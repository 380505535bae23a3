"""The command line says what docs/commands.md's command table says: the same commands, positionals and options
both ways; README's short table names the same commands; every option has help text that states its default; bare
`touchanything` lists the commands."""
from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from touchanything.app.cli import build_parser, main
from touchanything.app.commands.eval_command import view_configurations
from touchanything.app.commands.replay_command import given_choice
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.core.view_sets import parse_view_set, view_set_name

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
COMMANDS_DOC = ROOT / "docs" / "commands.md"


def subcommands() -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def table_rows(doc: Path) -> dict[str, str]:
    """command → the usage cell of its row in the doc's command table (README's short table: no options)."""
    rows = {}
    for line in doc.read_text().splitlines():
        if match := re.match(r"\| `touchanything ([a-z-]+)(.*?)` \|", line):
            rows[match[1]] = match[2]
    return rows


def options(parser: argparse.ArgumentParser) -> set[str]:
    return {s for a in parser._actions for s in a.option_strings if s.startswith("--") and s != "--help"}


def positionals(parser: argparse.ArgumentParser) -> list[str]:
    return [a.metavar or a.dest.upper() for a in parser._actions if not a.option_strings]


@pytest.mark.parametrize("doc", [COMMANDS_DOC, README], ids=["docs/commands.md", "README.md"])
def test_the_command_tables_have_every_command_and_only_those(doc):
    assert set(table_rows(doc)) == set(subcommands())


@pytest.mark.parametrize("command", sorted(subcommands()))
def test_the_full_row_names_the_same_options_and_positionals_as_help(command):
    cell, parser = table_rows(COMMANDS_DOC)[command], subcommands()[command]
    assert set(re.findall(r"--[a-z0-9][a-z0-9-]*", cell)) == options(parser)
    for name in positionals(parser):
        assert re.search(rf"\b{re.escape(name)}\b", cell), f"{command}: positional {name} not in docs/commands.md's row"


@pytest.mark.parametrize("command", sorted(subcommands()))
def test_every_option_has_help_stating_its_default(command):
    for action in subcommands()[command]._actions:
        if not action.option_strings or action.dest == "help":
            continue
        assert action.help, f"{command} {action.option_strings[0]}: no help text"
        if action.default not in (None, False) and not action.required:
            assert "default" in action.help, f"{command} {action.option_strings[0]}: help does not state the default"


def test_bare_touchanything_lists_the_commands_as_help_does(capsys):
    assert main([]) == 0  # a request for the commands, not an error
    out = capsys.readouterr().out
    assert all(f"    {name}" in out for name in subcommands()) and "required" not in out


def test_view_names_are_one_set_for_every_command(tmp_path, capsys):
    assert parse_view_set("ego+left") == parse_view_set("wrist_left+ego") == ("ego", "wrist_left")
    assert parse_view_set("all") == VIEW_NAMES == parse_view_set("right+ego+left")
    assert view_set_name(("ego", "wrist_right")) == "ego+right" and view_set_name(("wrist_left",)) == "left"
    parser = build_parser()
    for spelling in (["ego", "wrist_left"], ["ego", "left"], ["ego+left"], ["left+ego"]):
        assert given_choice(parser.parse_args(["replay", "EP", "--views", *spelling])).setting.views == ("ego", "wrist_left")
    assert given_choice(parser.parse_args(["replay", "EP"])).setting.views == VIEW_NAMES
    evaluation = ["eval", "--checkpoint", "C", "--data", "D", "--views"]
    assert view_configurations(parser.parse_args([*evaluation, "ego+wrist_left", "all", "ego+left"]).views) == ["ego+left", "all"]
    assert view_configurations(parser.parse_args(evaluation[:-1]).views) == ["all"]
    assert main([*evaluation, "left"]) == 2
    assert "--views left: the official view configurations are ego, ego+left, ego+right, all" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["replay", str(tmp_path), "--views", "head"])
    assert "unknown view 'head'" in capsys.readouterr().err
