"""Every help text of the command line, word for word, against tests/fixtures/cli_help.json.

The fixture holds ``gromov --help``, each subcommand's ``--help`` and the help reached through
each value of a positional argument with choices (``gromov perturb weld --help``), printed at a
fixed width of 80 columns. A change to a help text shows here as a diff; when it is meant,
regenerate the fixture::

    .venv/bin/python tests/test_cli_help.py
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
from pathlib import Path

import pytest

FIXTURE = Path(__file__).resolve().parent / "fixtures" / "cli_help.json"
COLUMNS = "80"


def _commands(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """Every command line whose ``--help`` prints a help text: the parser's own, each
    subcommand's (recursively) and each choice of a positional argument before ``--help``."""
    out = [prefix]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out += _commands(sub, prefix + (name,))
        elif not action.option_strings and action.choices is not None:
            out += [prefix + (str(c),) for c in action.choices]
    return out


def _help(argv: list[str]) -> str:
    from gromov.cli import main

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pytest.raises(SystemExit) as exit_:
        main(argv + ["--help"])
    assert exit_.value.code == 0, argv
    return buf.getvalue()


def help_texts() -> dict[str, str]:
    """``{"gromov perturb weld --help": text}`` for every command line of :func:`_commands`."""
    from gromov.cli import build_parser

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = COLUMNS
    try:
        return {" ".join(("gromov",) + c + ("--help",)): _help(list(c)) for c in _commands(build_parser())}
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old


def test_every_help_text_is_unchanged():
    want = json.loads(FIXTURE.read_text(encoding="utf-8"))
    got = help_texts()
    assert sorted(got) == sorted(want)
    for command, text in want.items():
        assert got[command] == text, command


def test_the_fixture_has_every_subcommand_and_nested_help():
    want = json.loads(FIXTURE.read_text(encoding="utf-8"))
    for command in ("gromov --help", "gromov match --help", "gromov pairwise --help",
                    "gromov perturb --help", "gromov perturb weld --help", "gromov perturb holes --help",
                    "gromov perturb cut --help",
                    "gromov reproduce --help", "gromov demo --help"):
        assert command in want, command
    assert want["gromov --help"].startswith("usage: gromov ")


if __name__ == "__main__":   # regenerate the fixture from today's parser
    FIXTURE.write_text(json.dumps(help_texts(), indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    print(f"wrote {FIXTURE}")
