"""The interactive page of a dense map: the figure's facts, the file, and the page in a browser."""

from __future__ import annotations

import base64
import dataclasses
import json
import re
import shutil
import subprocess

import numpy as np
import pytest

import gromov
from gromov.experiments.report import coordinate_colours
from gromov.experiments.view import match_figure, write_match_html
from gromov.shapes import icosphere

from test_dense import bumpy_torus, permutation_of

pytest.importorskip("plotly")

BROWSERS = ("chromium", "chromium-browser", "google-chrome")


@pytest.fixture(scope="module")
def pair():
    """A torus of about 700 vertices, a moved and renumbered copy (vertex j is x's perm[j]), their map."""
    x = bumpy_torus()
    y, perm = permutation_of(x, 4)
    return x, y, perm, gromov.match(x, y, "geodesic", n_samples=20, resolution=None, dense=True)


def _rgb(strings) -> np.ndarray:
    return np.array([[int(c) for c in re.fullmatch(r"rgb\((\d+),(\d+),(\d+)\)", s).groups()]
                     for s in strings])


def _xyz(trace) -> np.ndarray:
    return np.column_stack([np.asarray(trace.x, dtype=float), np.asarray(trace.y, dtype=float),
                            np.asarray(trace.z, dtype=float)])


def _edge_lengths(p, faces) -> np.ndarray:
    return np.linalg.norm(p[faces] - p[np.roll(faces, 1, axis=1)], axis=2)


# ---------------------------------------------------------------------------- the figure
def test_y_is_painted_with_the_colours_of_x_carried_by_the_map(pair):
    x, y, perm, r = pair
    fig = match_figure(x, y, r)
    mx, my = fig.data[0], fig.data[1]
    assert (mx.type, my.type) == ("mesh3d", "mesh3d")
    assert len(mx.x) == x.n_vertices and len(my.x) == y.n_vertices
    np.testing.assert_array_equal(np.column_stack([mx.i, mx.j, mx.k]), x.faces)
    np.testing.assert_array_equal(np.column_stack([my.i, my.j, my.k]), y.faces)
    cx, cy = _rgb(mx.vertexcolor), _rgb(my.vertexcolor)
    np.testing.assert_array_equal(cx, np.rint(255 * coordinate_colours(x)))
    # vertex j of the copy is vertex perm[j] of x: it wears that vertex's colour
    assert np.mean(np.abs(cy - cx[perm]).max(axis=1) <= 2) > 0.95
    # the vertex numbering carries no hint: the colours do not follow it
    assert np.mean(np.abs(cy - cx).max(axis=1) <= 2) < 0.1


def test_given_colours_are_used_and_carried(pair):
    x, y, perm, r = pair
    red = np.tile([1.0, 0.0, 0.0], (x.n_vertices, 1))
    fig = match_figure(x, y, r, x_colours=red)
    assert set(fig.data[0].vertexcolor) == {"rgb(255,0,0)"}
    assert set(fig.data[1].vertexcolor) == {"rgb(255,0,0)"}


def test_both_shapes_keep_their_size_and_y_stands_right_of_x(pair):
    x, y, perm, r = pair
    fig = match_figure(x, y, r)
    px, py = _xyz(fig.data[0]), _xyz(fig.data[1])
    # a rigid motion each: every edge keeps its length (float32 coordinates in the page)
    np.testing.assert_allclose(_edge_lengths(px, x.faces), _edge_lengths(x.vertices, x.faces), rtol=1e-5)
    np.testing.assert_allclose(_edge_lengths(py, y.faces), _edge_lengths(y.vertices, y.faces), rtol=1e-5)
    assert py[:, 0].min() > px[:, 0].max()   # side by side, seen by one camera
    assert len(fig.layout.scene.annotations) == 2


def test_segments_join_each_shown_sample_to_its_image(pair):
    x, y, perm, r = pair
    for max_lines, shown in ((100, np.arange(20)), (20, np.arange(20)), (7, np.arange(0, 20, 3))):
        fig = match_figure(x, y, r, max_lines=max_lines)
        lines = fig.data[2]
        assert lines.mode == "lines" and lines.name.startswith(f"{len(shown)} of 20 samples")
        seg = _xyz(lines)
        assert seg.shape == (3 * len(shown), 3) and len(shown) <= max_lines
        assert np.isnan(seg[2::3]).all() and np.isfinite(seg[0::3]).all() and np.isfinite(seg[1::3]).all()
        px, py = _xyz(fig.data[0]), _xyz(fig.data[1])
        np.testing.assert_allclose(seg[0::3], px[x.from_input_ids(r.x_samples[shown])], atol=1e-6)
        np.testing.assert_allclose(seg[1::3], py[y.from_input_ids(r.x_to_y_vertex[shown])], atol=1e-6)
        assert len(fig.data[3].x) == len(fig.data[4].x) == len(shown)   # the markers
        assert f"{len(shown)} of the 20 samples" in fig.layout.title.text


def test_title_says_the_colours_are_carried_by_the_dense_map(pair):
    x, y, perm, r = pair
    fig = match_figure(x, y, r, titles=("cat0", "cat<1>"), title="a <b> pair")
    text = fig.layout.title.text
    assert text.startswith("a &lt;b&gt; pair<br>")
    assert "the colours of cat0 carried to cat&lt;1&gt; by the dense map" in text
    assert [a.text for a in fig.layout.scene.annotations] == ["cat0", "cat&lt;1&gt;"]


# ---------------------------------------------------------------------------- the file
def _figure_in(page: str) -> list:
    """The traces of the figure embedded in a page written by plotly."""
    start = page.index("Plotly.newPlot(")
    start = page.index("[", start)
    return json.JSONDecoder().raw_decode(page, start)[0]


def _length(array) -> int:
    if isinstance(array, dict):   # plotly's typed arrays: {"dtype": "f4", "bdata": base64}
        return len(base64.b64decode(array["bdata"])) // np.dtype(array["dtype"]).itemsize
    return len(array)


def test_page_is_self_contained_and_holds_both_meshes(pair, tmp_path):
    x, y, perm, r = pair
    path = write_match_html(x, y, r, tmp_path / "map.html", titles=("torus", "copy"))
    assert path == tmp_path / "map.html"
    page = path.read_text(encoding="utf-8")
    # plotly.js inside, nothing fetched: no script from elsewhere, no link outside the scripts
    assert not re.search(r"<script[^>]*\bsrc\s*=", page)
    assert not re.search(r"https?:|<link|<img|<iframe", re.sub(r"(?s)<script.*?</script>", "", page))
    assert len(page) > 1_000_000 and "<title>torus → copy: dense map</title>" in page
    traces = _figure_in(page)
    meshes = [t for t in traces if t["type"] == "mesh3d"]
    assert [_length(t["x"]) for t in meshes] == [x.n_vertices, y.n_vertices]
    assert [len(t["vertexcolor"]) for t in meshes] == [x.n_vertices, y.n_vertices]
    lines = [t for t in traces if t["type"] == "scatter3d" and t["mode"] == "lines"]
    assert len(lines) == 1 and _length(lines[0]["x"]) == 3 * 20
    assert "carried to copy by the dense map" in page


def test_page_replaces_an_old_one_and_leaves_no_temporary_file(pair, tmp_path):
    x, y, perm, r = pair
    path = tmp_path / "map.html"
    path.write_text("old")
    write_match_html(x, y, r, path, max_lines=5)
    assert [p.name for p in tmp_path.iterdir()] == ["map.html"]
    assert "5 of the 20 samples" in path.read_text(encoding="utf-8")


# ---------------------------------------------------------------------------- errors
def test_bad_inputs_are_refused(pair, tmp_path):
    x, y, perm, r = pair
    with pytest.raises(ValueError, match="dense=True"):
        match_figure(x, y, dataclasses.replace(r, x_to_y_dense_vertex=None))
    n = x.n_vertices
    with pytest.raises(ValueError, match=rf"x_colours must be RGB in \[0, 1\] of shape \({n}, 3\), got shape \({n},\)"):
        match_figure(x, y, r, x_colours=np.zeros(x.n_vertices))
    with pytest.raises(ValueError, match="values outside"):
        match_figure(x, y, r, x_colours=np.full((x.n_vertices, 3), 1.5))
    with pytest.raises(ValueError, match="max_lines must be a positive integer, got 0"):
        match_figure(x, y, r, max_lines=0)
    with pytest.raises(ValueError, match="titles must be a pair of names, got 'X'"):
        match_figure(x, y, r, titles="X")
    with pytest.raises(TypeError, match="y_mesh must be a gromov.Mesh, got ndarray"):
        match_figure(x, y.vertices, r)
    big = icosphere(4)   # 2562 vertices: another file than the one the map of the torus covers
    with pytest.raises(ValueError, match="x_mesh comes from a file of 2562 vertices .* other shapes"):
        match_figure(big, y, r)
    with pytest.raises(ValueError, match="does not exist"):
        write_match_html(x, y, r, tmp_path / "missing" / "map.html")
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------------- in a browser
#: Reports console.error calls and uncaught errors on the browser's log (stderr).
HOOK = """<script>(function () {
  function report(m) { console.log("PAGE-ERROR " + m); }
  var error = console.error;
  console.error = function () { report(Array.prototype.join.call(arguments, " ")); error.apply(console, arguments); };
  window.addEventListener("error", function (e) { report(e.message); });
  window.addEventListener("unhandledrejection", function (e) { report(e.reason); });
})();</script>"""


def _browse(page, tmp_path):
    """``(errors, image)``: the console errors of a page in headless Chromium and a screenshot."""
    exe = next((shutil.which(b) for b in BROWSERS if shutil.which(b)), None)
    if exe is None:
        pytest.skip(f"no headless browser: none of {', '.join(BROWSERS)} is installed")
    hooked = tmp_path / "hooked.html"
    hooked.write_text(page.read_text(encoding="utf-8").replace("<head>", "<head>" + HOOK, 1),
                      encoding="utf-8")
    shot = tmp_path / "shot.png"
    run = subprocess.run(
        [exe, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
         "--disable-quic", "--no-first-run", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}",
         f"--screenshot={shot}", "--window-size=1200,700", "--virtual-time-budget=10000",
         "--enable-logging=stderr", "--v=0", hooked.as_uri()],
        capture_output=True, text=True, timeout=120)
    errors = [ln for ln in run.stderr.splitlines()
              if "CONSOLE" in ln and ("PAGE-ERROR" in ln or "Uncaught" in ln)]
    assert shot.is_file(), run.stderr[-2000:]
    import matplotlib.image

    return errors, matplotlib.image.imread(shot)[..., :3]


def test_the_browser_check_sees_console_errors(tmp_path):
    page = tmp_path / "bad.html"
    page.write_text("<html><head></head><body><script>console.error('broken'); null.x;"
                    "</script></body></html>")
    errors, _ = _browse(page, tmp_path)
    assert len(errors) == 3   # the console.error, and the TypeError both uncaught and reported
    assert "PAGE-ERROR broken" in errors[0]


def test_page_draws_both_meshes_in_a_browser_without_errors(pair, tmp_path):
    x, y, perm, r = pair
    errors, image = _browse(write_match_html(x, y, r, tmp_path / "map.html"), tmp_path)
    assert errors == []
    assert image.shape == (700, 1200, 3)
    # the meshes' colours: saturated pixels (the page itself is white, grey and black)
    painted = image.max(axis=2) - image.min(axis=2) > 0.15
    left, right = painted[:, :600], painted[:, 600:]
    assert left.mean() > 0.05 and right.mean() > 0.05, (left.mean(), right.mean())
