r"""An interactive page of a dense map: both shapes in one 3-D scene the reader can turn.

:func:`match_figure` builds a plotly figure of a :class:`gromov.MatchResult` computed with
``dense=True``: X painted with a smooth colour function (by default
:func:`~gromov.experiments.report.coordinate_colours`), Y painted with the same colours
carried to it by the dense map (:meth:`~gromov.MatchResult.transfer`, barycentric), Y placed
beside X so that one camera shows both from the same viewpoint, and line segments from X's
samples to their images on Y. :func:`write_match_html` writes it as one self-contained HTML
page (plotly.js embedded: it opens with no network). Needs ``gromov[plot]`` (plotly).
"""

from __future__ import annotations

import html
import os
import tempfile
from pathlib import Path

import numpy as np

from ..mesh import Mesh
from .report import _principal_view, coordinate_colours

__all__ = ["match_figure", "write_match_html"]

#: Colour of the vertices the dense map leaves without an image (dropped on loading).
_GREY = 0.6


def match_figure(x_mesh: Mesh, y_mesh: Mesh, result, *, titles: tuple[str, str] = ("X", "Y"),
                 title: str | None = None, x_colours=None, max_lines: int = 100):
    """The plotly figure of a dense map between two meshes, as :func:`write_match_html` draws it.

    Both meshes are turned to their pooled principal axes (as in
    :func:`~gromov.experiments.report.plot_transfer`: the largest one left to right, the
    second one up), each is centred, and Y is shifted to the right of X; the sizes are kept.

    Parameters
    ----------
    x_mesh, y_mesh : Mesh
        The shapes ``result`` was computed for (its vertex ids are their ``input_ids``).
    result : MatchResult
        From ``gromov.match(x_mesh, y_mesh, ..., dense=True)``.
    titles : (str, str), default ("X", "Y")
        The shapes' names, written above them.
    title : str, optional
        The figure's title; by default it names the shapes and says how Y is painted.
    x_colours : array_like, shape (x_mesh.n_vertices, 3), optional
        RGB in [0, 1] per vertex of ``x_mesh``; default ``coordinate_colours(x_mesh)``.
    max_lines : int, default 100
        At most this many of X's samples are joined to their images (every k-th sample).

    Returns
    -------
    plotly.graph_objects.Figure
        Traces: X's mesh, Y's mesh, the segments (one ``Scatter3d``, ``None`` between
        segments), the samples of X and their images on Y (markers).

    Raises
    ------
    TypeError
        If a shape is not a :class:`Mesh`.
    ValueError
        If ``result`` has no dense maps or does not fit the meshes, ``x_colours`` is not RGB
        in [0, 1] of one row per vertex of X, or ``max_lines`` is not positive.
    ImportError
        If plotly is not installed.
    """
    for name, m in (("x_mesh", x_mesh), ("y_mesh", y_mesh)):
        if not isinstance(m, Mesh):
            raise TypeError(f"{name} must be a gromov.Mesh, got {type(m).__name__}")
    if not getattr(result, "has_dense", False):
        raise ValueError("the page needs the dense maps: gromov.match(..., dense=True)")
    n_x, n_y = len(result.x_to_y_dense_vertex), len(result.y_to_x_dense_vertex)
    for name, m, n in (("x_mesh", x_mesh, n_x), ("y_mesh", y_mesh, n_y)):
        if m.n_file_vertices != n:
            raise ValueError(f"{name} comes from a file of {m.n_file_vertices} vertices but the "
                             f"result's dense map covers {n}: it was computed for other shapes")
    if not (isinstance(titles, (tuple, list)) and len(titles) == 2):
        raise ValueError(f"titles must be a pair of names, got {titles!r}")
    tx, ty = (html.escape(str(t)) for t in titles)   # plotly renders text as HTML
    if isinstance(max_lines, bool) or not isinstance(max_lines, (int, np.integer)) or max_lines < 1:
        raise ValueError(f"max_lines must be a positive integer, got {max_lines!r}")
    if x_colours is None:
        x_colours = coordinate_colours(x_mesh)
    cx = np.asarray(x_colours, dtype=np.float64)
    if cx.shape != (x_mesh.n_vertices, 3) or not np.all((cx >= 0) & (cx <= 1)):
        raise ValueError(f"x_colours must be RGB in [0, 1] of shape ({x_mesh.n_vertices}, 3), "
                         f"got shape {cx.shape}" + ("" if cx.shape != (x_mesh.n_vertices, 3)
                                                    else " with values outside [0, 1]"))
    try:
        import plotly.graph_objects as go
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("the interactive page needs plotly: pip install 'gromov[plot]'") from exc

    # colours of X by file id, carried to Y through Y's map to X, read back in Y's vertex order
    by_id = x_mesh.per_file_vertex(cx)
    cy = result.transfer(by_id, method="barycentric", direction="x_to_y")[y_mesh.input_ids]
    cy = np.clip(np.where(np.isfinite(cy), cy, _GREY), 0.0, 1.0)

    # principal axes (a1 right, a2 up, a3 towards the viewer) as plotly's (x, z, -y): a rotation
    rot = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]) @ _principal_view((x_mesh, y_mesh))
    px, py = (m.vertices @ rot.T for m in (x_mesh, y_mesh))
    px -= (px.min(0) + px.max(0)) / 2
    py -= (py.min(0) + py.max(0)) / 2
    wx, wy = np.ptp(px[:, 0]), np.ptp(py[:, 0])
    py[:, 0] += (wx + wy) / 2 + 0.15 * max(np.ptp(px, axis=0).max(), np.ptp(py, axis=0).max())

    shown = np.arange(0, len(result.x_samples), -(-len(result.x_samples) // max_lines))
    a = px[x_mesh.from_input_ids(result.x_samples[shown])]
    b = py[y_mesh.from_input_ids(result.x_to_y_vertex[shown])]
    seg = np.full((3 * len(shown), 3), np.nan)
    seg[0::3], seg[1::3] = a, b
    err = result.sample_distortion[0][shown]
    hover = [f"sample {i}: {tx} vertex {s} → {ty} vertex {t}<br>RMS distortion {e:.3g}"
             for i, s, t, e in zip(shown, result.x_samples[shown], result.x_to_y_vertex[shown], err)]

    def rgb(c):
        return [f"rgb({r},{g},{b})" for r, g, b in np.rint(255 * c).astype(int)]

    def mesh(p, m, c, name):
        p = p.astype(np.float32)   # half the page's bytes, far below a pixel
        return go.Mesh3d(x=p[:, 0], y=p[:, 1], z=p[:, 2], i=m.faces[:, 0], j=m.faces[:, 1],
                         k=m.faces[:, 2], vertexcolor=rgb(c), name=name, hoverinfo="name",
                         flatshading=False, lighting=dict(ambient=0.6, diffuse=0.6, specular=0.1))

    def markers(p, name, colour):
        return go.Scatter3d(x=p[:, 0], y=p[:, 1], z=p[:, 2], mode="markers", name=name,
                            marker=dict(size=3, color=colour, line=dict(color="black", width=1)),
                            hovertext=hover, hoverinfo="text")

    lines = go.Scatter3d(x=seg[:, 0], y=seg[:, 1], z=seg[:, 2], mode="lines", hoverinfo="skip",
                         name=f"{len(shown)} of {len(result.x_samples)} samples → images",
                         line=dict(color="rgba(40,40,40,0.7)", width=2), connectgaps=False)
    head = f"{tx} → {ty}" if title is None else html.escape(str(title))
    note = (f"the colours of {tx} carried to {ty} by the dense map; lines join "
            f"{len(shown)} of the {len(result.x_samples)} samples of {tx} to their images")
    top = max(px[:, 2].max(), py[:, 2].max()) + 0.08 * np.ptp(np.vstack([px, py]), axis=0).max()
    notes = [dict(x=float(p[:, 0].mean()), y=0.0, z=float(top), text=t, showarrow=False,
                  font=dict(size=16)) for p, t in ((px, tx), (py, ty))]
    hidden = dict(visible=False, showspikes=False)
    fig = go.Figure([mesh(px, x_mesh, cx, tx), mesh(py, y_mesh, cy, ty), lines,
                     markers(a, f"samples of {tx}", "black"), markers(b, f"their images on {ty}", "white")])
    fig.update_layout(
        title=dict(text=f"{head}<br><sup>{note}</sup>", x=0.5, font=dict(size=16)), showlegend=True,
        legend=dict(orientation="h", y=0), margin=dict(l=0, r=0, t=50, b=0),
        scene=dict(xaxis=hidden, yaxis=hidden, zaxis=hidden, annotations=notes, aspectmode="data",
                   camera=dict(eye=dict(x=0, y=-1.7, z=0.2), up=dict(x=0, y=0, z=1))))
    return fig


def write_match_html(x_mesh: Mesh, y_mesh: Mesh, result, path, *, titles: tuple[str, str] = ("X", "Y"),
                     title: str | None = None, x_colours=None, max_lines: int = 100,
                     plotlyjs: str = "embed") -> Path:
    """Write an interactive, self-contained HTML page of a dense map (:func:`match_figure`).

    X is painted with ``x_colours``, Y with the same colours carried by the dense map, in one
    3-D scene the reader can turn and zoom, with line segments from samples of X to their
    images on Y. plotly.js is embedded in the page (about 5 MB): it needs no network. The page
    is written to a temporary file beside ``path``, then moved onto it.

    Parameters
    ----------
    x_mesh, y_mesh, result, titles, title, x_colours, max_lines
        As :func:`match_figure`.
    path : str or Path
        The ``.html`` file to write; its folder must exist.
    plotlyjs : {"embed", "directory"}, default "embed"
        Embed plotly.js in the page, or load it from ``plotly.min.js`` beside the page (written
        there if missing): one copy for a folder of pages, still no network.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    if not path.parent.is_dir():
        raise ValueError(f"the folder of {str(path)!r} does not exist")
    fig = match_figure(x_mesh, y_mesh, result, titles=titles, title=title, x_colours=x_colours,
                       max_lines=max_lines)
    name = title if title is not None else f"{titles[0]} → {titles[1]}: dense map"
    if plotlyjs not in ("embed", "directory"):
        raise ValueError(f"plotlyjs must be 'embed' or 'directory', got {plotlyjs!r}")
    if plotlyjs == "directory" and not (path.parent / "plotly.min.js").exists():
        from plotly.offline import get_plotlyjs

        _write_atomic(path.parent / "plotly.min.js", get_plotlyjs())
    page = fig.to_html(include_plotlyjs=True if plotlyjs == "embed" else "directory", full_html=True,
                       config={"displaylogo": False})
    page = page.replace("<head>", f"<head><title>{html.escape(name)}</title>", 1)
    _write_atomic(path, page)
    return path


def _write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to a temporary file beside ``path``, then move it onto ``path``."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.chmod(tmp, 0o644)   # mkstemp's 0o600 would keep the page from a web server
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
