"""The documentation site builds without a warning, and the release is one version everywhere."""

import argparse
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import gromov
from gromov.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """``mkdocs build --strict`` into a temporary folder: its output and the folder."""
    pytest.importorskip("mkdocs", reason="the docs extra is not installed (make test installs it)")
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    p = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file",
                        str(ROOT / "mkdocs.yml"), "--site-dir", str(out)],
                       capture_output=True, text=True, cwd=ROOT, env=env, timeout=120)
    return p, out


def test_site_builds_without_warnings(site):
    p, out = site
    log = p.stdout + p.stderr
    assert p.returncode == 0, log
    assert "WARNING" not in log, log
    for page in ("index.html", "getting-started/index.html", "cli/index.html", "benchmarks/index.html",
                 "api/match/index.html", "guide/match/index.html", "design/index.html"):
        assert (out / page).is_file(), page


def test_cli_reference_is_every_subcommands_help(site):
    """docs/cli.md is generated from the parser: every subcommand and every option is there."""
    _, out = site
    html = (out / "cli" / "index.html").read_text(encoding="utf-8")
    assert "cli-reference" not in html
    subs = _subparsers(build_parser())
    assert {"match", "pairwise", "reproduce", "perturb", "info", "distances", "demo"} <= set(subs)
    for name, sub in subs.items():
        assert f"usage: gromov {name}" in html, name
        for action in sub._actions:
            for flag in action.option_strings:
                assert flag in html, f"gromov {name} {flag}"


def test_api_pages_render_the_docstrings(site):
    _, out = site
    html = (out / "api" / "match" / "index.html").read_text(encoding="utf-8")
    for name in ("gromov.match", "gromov.MatchResult", "gromov.ShapeMetric"):
        assert name in html, name
    assert gromov.match.__doc__.splitlines()[0].strip() in html
    for page in ("match", "metrics", "shapes", "evaluate", "perturb", "experiments"):
        text = (out / "api" / page / "index.html").read_text(encoding="utf-8")
        # Sphinx roles are reduced to the code they mark
        assert not re.search(r":(func|class|meth|mod|attr|data|math):<code>", text), page
        assert ".. math::" not in text, page


def test_role_stripping():
    sys.path.insert(0, str(ROOT / "docs" / "hooks"))
    try:
        import gromov_docs
    finally:
        sys.path.remove(str(ROOT / "docs" / "hooks"))
    html = ("see :func:<code>match</code> and :class:<code>~gromov.mesh.Mesh</code>, "
            ":math:<code>d_t</code>\n<p>.. math:: a = b</p>\n<p>.. math::</p>\n<pre>x</pre>")
    assert gromov_docs.strip_roles(html) == (
        "see <code>match</code> and <code>Mesh</code>, <code>d_t</code>\n"
        '<div class="highlight"><pre><code>a = b</code></pre></div>\n<pre>x</pre>')


def test_one_version_everywhere(capsys):
    """pyproject.toml, gromov.__version__, ``gromov --version`` and the CHANGELOG's latest
    release name the same version."""
    pyproject = (ROOT / "pyproject.toml").read_text()
    version = re.search(r'^version = "([^"]+)"$', pyproject, re.MULTILINE).group(1)
    assert gromov.__version__ == version
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"gromov {version}"
    changelog = (ROOT / "CHANGELOG.md").read_text()
    releases = re.findall(r"^## \[(\d+\.\d+\.\d+)\] - (\d{4}-\d{2}-\d{2})$", changelog, re.MULTILINE)
    assert releases and releases[0][0] == version, releases
    assert [v for v, _ in releases] == sorted({v for v, _ in releases}, reverse=True,
                                              key=lambda v: tuple(map(int, v.split("."))))


def test_readme_is_a_front_door():
    text = README.read_text(encoding="utf-8")
    lines = text.splitlines()
    assert len(lines) <= 200, len(lines)
    assert "make demo" in text and "make test" in text and "make docs" in text
    # every relative link and image of the README points at a file of the repository
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    local = [t for t in targets if "://" not in t]
    assert "docs/images/cats-dense.png" in local
    missing = [t for t in local if not (ROOT / t).exists()]
    assert not missing, missing
    image = ROOT / "docs" / "images" / "cats-dense.png"
    assert image.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and image.stat().st_size < 300_000


def test_docs_pages_have_no_development_diary():
    """Every page of the site speaks of the product: no work sessions, temporary paths or
    unmet targets (the README has the same check in tests/test_product_text.py)."""
    pages = sorted((ROOT / "docs").rglob("*.md"))
    assert len(pages) >= 16
    bad = re.compile(r"\bsessions?\b|/tmp/|target not met", re.IGNORECASE)
    hits = [f"{p.relative_to(ROOT)}:{n}" for p in pages
            for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if bad.search(line)]
    assert not hits, hits
