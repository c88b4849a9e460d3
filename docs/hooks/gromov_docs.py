"""MkDocs hooks: the CLI reference, generated from the parser, and Sphinx roles in docstrings.

- docs/cli.md holds the marker ``<!-- cli-reference -->``; it is replaced, at build time, by
  ``gromov --help`` and ``gromov <command> --help`` for every subcommand of
  :func:`gromov.cli.build_parser`, so the reference is the parser itself and cannot drift from it.
- The docstrings are numpydoc, written with Sphinx roles (``:func:`match```, ``:math:`d_t```)
  and ``.. math::`` directives, which Markdown leaves as literal text around the code they
  mark. The rendered pages keep the code and drop the role (``~a.b.c`` shows ``c``, as in
  Sphinx); a ``.. math::`` line is dropped and its formula shown as a code block.
"""

from __future__ import annotations

import argparse
import os
import re

MARKER = "<!-- cli-reference -->"
WIDTH = "80"    # the help text's line width, whatever the terminal that builds the site
ROLE = re.compile(r":(?:py:)?(?:func|meth|class|mod|attr|data|obj|exc|const|math|ref|term):<code>(~?)([^<]*)</code>")
DIRECTIVE = re.compile(r"<p>\.\. math::</p>\n?")
INLINE_DIRECTIVE = re.compile(r"<p>\.\. math::\s+(.+?)</p>", re.DOTALL)


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _summaries(parser: argparse.ArgumentParser) -> dict[str, str]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return {a.dest: a.help or "" for a in action._choices_actions}
    return {}


def render() -> str:
    """The CLI reference in Markdown: the top-level help, then each subcommand's."""
    from gromov.cli import build_parser

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = WIDTH
    try:
        parser = build_parser()
        out = ["## gromov", "", "```text", parser.format_help().rstrip(), "```", ""]
        summaries = _summaries(parser)
        for name, sub in _subcommands(parser).items():
            out += [f"## gromov {name}", "", summaries.get(name, "").capitalize() + ".", "",
                    "```text", sub.format_help().rstrip(), "```", ""]
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old
    return "\n".join(out)


def on_page_markdown(markdown: str, page, config, files) -> str:
    if page.file.src_uri == "cli.md":
        if MARKER not in markdown:
            raise ValueError(f"docs/cli.md has lost its {MARKER} marker")
        markdown = markdown.replace(MARKER, render())
    return markdown


def _unrole(m: re.Match) -> str:
    text = m.group(2).rsplit(".", 1)[-1] if m.group(1) else m.group(2)
    return f"<code>{text}</code>"


def strip_roles(html: str) -> str:
    """The rendered docstrings without the Sphinx roles and directives Markdown left as text."""
    html = INLINE_DIRECTIVE.sub(r'<div class="highlight"><pre><code>\1</code></pre></div>', html)
    return DIRECTIVE.sub("", ROLE.sub(_unrole, html))


def on_page_content(html: str, page, config, files) -> str:
    return strip_roles(html)
