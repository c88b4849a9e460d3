"""The product speaks of the product: no development diary in what a user reads.

The installed package's source (docstrings, comments, messages), the help of every command
and the README must not speak of the work periods that made them or of temporary paths: why a
default was chosen is stated as a fact with its measurement, in docs/design/. (The words are
assembled below, so that a search of the repository for them finds no hit here.)
"""

import argparse
import re
from pathlib import Path

import pytest

import gromov
from gromov.cli import build_parser

WORD, TMP = "sess" + "ion", "/" + "tmp/"
#: WORD or its plural as a word, any case; a path under TMP.
FORBIDDEN = re.compile(rf"\b{WORD}s?\b|{TMP}", re.IGNORECASE)

PACKAGE = Path(gromov.__file__).resolve().parent
README = Path(__file__).resolve().parents[1] / "README.md"


def _hits(text: str, where: str) -> list[str]:
    return [f"{where}:{n}: {line.strip()}" for n, line in enumerate(text.splitlines(), 1)
            if FORBIDDEN.search(line)]


def _parsers(parser: argparse.ArgumentParser, name: str = "gromov"):
    """``(command, parser)`` for the parser and every subcommand below it."""
    yield name, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub_name, sub in action.choices.items():
                yield from _parsers(sub, f"{name} {sub_name}")


def test_the_pattern_finds_what_it_must_and_nothing_else():
    w, W = WORD, WORD.capitalize()
    text = f"chosen in {W} 17\n{w}s 14-15\nout {TMP}s20/x"
    assert _hits(text, "t") == [f"t:1: chosen in {W} 17", f"t:2: {w}s 14-15", f"t:3: out {TMP}s20/x"]
    assert _hits(f"ob{w}; {w}_id; pos{w}\ntmp/ and /tmpdir", "t") == []


def test_package_source_has_no_development_diary():
    files = sorted(PACKAGE.rglob("*.py"))
    assert len(files) > 20, f"package source not found under {PACKAGE}"
    hits = [h for f in files for h in _hits(f.read_text(encoding="utf-8"), str(f.relative_to(PACKAGE)))]
    assert not hits, "\n".join(hits)


def test_command_help_has_no_development_diary():
    commands = list(_parsers(build_parser()))
    names = {name for name, _ in commands}
    assert {"gromov match", "gromov pairwise", "gromov reproduce"} <= names, names
    hits = [h for name, p in commands for h in _hits(p.format_help(), f"{name} --help")]
    assert not hits, "\n".join(hits)


def test_readme_has_no_development_diary():
    if not README.is_file():
        pytest.fail(f"{README} is missing")
    hits = _hits(README.read_text(encoding="utf-8"), "README.md")
    assert not hits, "\n".join(hits)
