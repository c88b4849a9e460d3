r"""The report of ``gromov reproduce``: correspondence figures and a self-contained HTML page.

``gromov reproduce`` runs the experiments of Bronstein, Bronstein, Mahmoudi, Kimmel &
Sapiro, "A Gromov-Hausdorff framework with diffusion geometry for topologically-robust
non-rigid shape matching", IJCV 89 (2010), §5, and writes ``results.json``, PNG figures and
``index.html`` into one folder. This module draws and writes the last two:

- :func:`voronoi_labels` turns distances from K samples into Voronoi cells on a mesh (each
  vertex labelled with its nearest sample);
- :func:`plot_correspondence` draws two meshes side by side with corresponding cells in the
  same colour, as in the paper's correspondence figures (needs ``gromov[plot]``);
- :func:`write_report` writes ``index.html``: our numbers beside the paper's (:data:`PAPER`),
  the figures embedded as ``data:`` URIs, timings, parameters, seeds and versions. The page
  loads nothing from anywhere: no external CSS, scripts, fonts or images.
"""

from __future__ import annotations

import base64
import html
import json
import logging
import math
import numbers
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .._atomic import atomic_path, atomic_write_text
from ..mesh import Mesh
from .datasets import EXPERIMENT1_CLASSES

__all__ = ["PAPER", "PAPER_CLASSES", "other_classes", "voronoi_labels", "plot_correspondence",
           "plot_transfer", "coordinate_colours", "write_report"]

logger = logging.getLogger(__name__)

#: The paper's numbers, as fractions (Bronstein, Bronstein, Mahmoudi, Kimmel & Sapiro,
#: IJCV 89 (2010), §5). ``"eer"``: equal error rates of Table 1, Experiment 1 (shapes with
#: topological noise made by welding, ``"weld"``) and Experiment 2 (holes, ``"holes"``).
#: ``"correspondence"``: the correspondence distance :math:`d(C, C_0)` on the cats, without
#: (``"clean"``) and with (``"topology"``) topology changes.
PAPER: dict = {
    "eer": {
        "weld": {"diffusion": 0.04, "geodesic": 0.135},
        "holes": {"diffusion": 0.0, "geodesic": 0.068},
    },
    "correspondence": {
        "diffusion": {"clean": 0.0268, "topology": 0.0291},
        "geodesic": {"clean": 0.0514, "topology": 0.1586},
    },
}

#: Our correspondence conditions and the paper's column each is compared with.
_PAPER_CONDITION = {"clean": "clean", "weld": "topology", "holes": "topology"}

_EXPERIMENTS = {"weld": "Experiment 1 (welds)", "holes": "Experiment 2 (holes)"}
_CONDITIONS = {"clean": "clean", "weld": "welds", "holes": "holes"}
_METRIC_ORDER = ("diffusion", "geodesic")
_METRICS = ("diffusion", "geodesic", "euclidean")
_GREY = (0.62, 0.62, 0.62)
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_JPEG_SIGNATURE = b"\xff\xd8\xff"


# ---------------------------------------------------------------------------- Voronoi cells
def voronoi_labels(distances) -> np.ndarray:
    """Voronoi cells of samples on a mesh: the index of the nearest sample of each vertex.

    .. math::

        \\ell(v) = \\operatorname*{arg\\,min}_{k = 0, \\dots, K-1} D_{kv},

    ties going to the smallest ``k``. With ``D`` the distances from the K samples of a shape
    (in its own metric) and the samples of two shapes matched index by index, equal labels
    mark corresponding cells, as in the correspondence figures of Bronstein et al. (IJCV
    2010, §5).

    Parameters
    ----------
    distances : array_like, shape (K, n)
        Non-negative distances from K >= 1 samples (rows) to the n vertices (columns).
        ``+inf`` means unreachable (e.g. another connected component); a vertex that no
        sample reaches gets the label -1.

    Returns
    -------
    ndarray of int64, shape (n,)
        Cell of each vertex, in ``0 .. K-1``, or -1 for an unreachable vertex.

    Raises
    ------
    ValueError
        If ``distances`` is not 2-D, has no row, or holds NaN, negative or ``-inf`` values.
    """
    d = np.asarray(distances, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"distances must be a 2-D (K, n) array, got shape {d.shape}")
    if d.shape[0] < 1:
        raise ValueError(f"distances must have at least one row (sample), got shape {d.shape}")
    if np.isnan(d).any():
        raise ValueError(f"distances must not hold NaN, got {int(np.isnan(d).sum())} NaN entries")
    if (d < 0).any():
        raise ValueError(f"distances must be non-negative (+inf allowed for unreachable), "
                         f"got minimum {float(d.min())}")
    labels = np.argmin(d, axis=0).astype(np.int64)
    if d.shape[1]:
        labels[np.isinf(d).all(axis=0)] = -1
    return labels


# ---------------------------------------------------------------------------- the figure
def _check_labels(labels, mesh: Mesh, name: str) -> np.ndarray:
    lab = np.asarray(labels)
    if lab.ndim != 1 or lab.shape[0] != mesh.n_vertices:
        raise ValueError(f"{name} must be a 1-D array with one label per vertex "
                         f"({mesh.n_vertices}), got shape {lab.shape}")
    if not (np.issubdtype(lab.dtype, np.integer) and lab.dtype != bool):
        raise TypeError(f"{name} must hold integers (cell ids, -1 for none), got dtype {lab.dtype}")
    lab = lab.astype(np.int64)
    if lab.size and lab.min() < -1:
        raise ValueError(f"{name} must be >= -1 (-1 = unassigned), got {int(lab.min())}")
    return lab


def _check_view(view) -> np.ndarray:
    r = np.asarray(view, dtype=np.float64)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise ValueError(f"view must be a finite (3, 3) rotation matrix, got shape {r.shape}")
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-6):
        raise ValueError("view must be orthonormal (rows: screen right, screen up, towards "
                         "the viewer)")
    return r


def _principal_view(meshes) -> np.ndarray:
    """Rows: the largest, second and (right-handed) third principal axis of the meshes.

    The covariance is the area-weighted one of face centroids, each mesh centred on its
    own area centroid, pooled over the meshes. Each of the first two axes is signed so that
    its largest coordinate is positive (deterministic, and keeps a world "up" up when it is
    the second axis); the third is their cross product, so the view is a rotation, never a
    mirror.
    """
    cov = np.zeros((3, 3))
    for m in meshes:
        v, f = m.vertices, m.faces
        c = v[f].mean(axis=1)
        w = m.face_areas
        total = float(w.sum())
        if total <= 0:
            c, w, total = v, np.ones(len(v)), float(len(v))
        c = c - (w[:, None] * c).sum(axis=0) / total
        cov += (c * (w / total)[:, None]).T @ c
    _, vecs = np.linalg.eigh(cov)
    e1, e2 = vecs[:, 2], vecs[:, 1]
    e1 = e1 * (1.0 if e1[np.argmax(np.abs(e1))] > 0 else -1.0)
    e2 = e2 * (1.0 if e2[np.argmax(np.abs(e2))] > 0 else -1.0)
    return np.stack([e1, e2, np.cross(e1, e2)])


def _label_colours(ids: np.ndarray) -> np.ndarray:
    """Categorical RGB colours: hues by golden-ratio steps, saturation and value cycling.

    Consecutive ids are 0.382 of the hue circle apart and differ in value, so neighbouring
    cells (which farthest-point samples seldom number consecutively anyway) stand apart.
    Ids < 0 are grey.
    """
    from matplotlib.colors import hsv_to_rgb

    k = np.maximum(ids, 0)
    hue = np.mod(0.11 + 0.6180339887498949 * k, 1.0)
    sat = np.array([0.70, 0.50, 0.85])[k % 3]
    val = np.array([0.95, 0.78, 0.62])[(k // 3 + k) % 3]
    rgb = hsv_to_rgb(np.stack([hue, sat, val], axis=-1))
    rgb[ids < 0] = _GREY
    return rgb


def _face_labels(faces: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """The label most vertices of each face share (the first vertex's when all differ)."""
    l0, l1, l2 = labels[faces[:, 0]], labels[faces[:, 1]], labels[faces[:, 2]]
    return np.where((l1 == l2) & (l0 != l1), l1, l0)


#: Light direction in view coordinates (right, up, towards the viewer): upper left, front.
_LIGHT = np.array([-0.45, 0.55, 1.0]) / np.linalg.norm([-0.45, 0.55, 1.0])
_AMBIENT = 0.32


def _draw_mesh(ax, p: np.ndarray, faces: np.ndarray, labels: np.ndarray | None,
               colours: np.ndarray | None = None) -> None:
    """Painter's algorithm: faces sorted far to near, Lambert-shaded, two-sided. Faces take the
    colour of their vertices' ``labels`` (categorical), or the mean of their vertices' RGB
    ``colours``."""
    from matplotlib.collections import PolyCollection

    tri = p[faces]  # (m, 3, 3) in view coordinates
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, norm, out=np.tile([0.0, 0.0, 1.0], (len(n), 1)), where=norm > 0)
    n[n[:, 2] < 0] *= -1.0  # two-sided lighting: orientation of the input does not matter
    shade = _AMBIENT + (1.0 - _AMBIENT) * np.clip(n @ _LIGHT, 0.0, 1.0)
    base = _label_colours(_face_labels(faces, labels)) if colours is None else colours[faces].mean(axis=1)
    rgb = np.clip(base, 0.0, 1.0) * shade[:, None]
    order = np.argsort(tri[:, :, 2].mean(axis=1), kind="stable")
    pc = PolyCollection(tri[order, :, :2], facecolors=rgb[order], edgecolors=rgb[order],
                        linewidths=0.25, antialiaseds=True)
    ax.add_collection(pc)


def plot_correspondence(x_mesh: Mesh, y_mesh: Mesh, x_labels, y_labels, path, *,
                        titles: tuple[str, str] = ("X", "Y"), title: str | None = None,
                        dpi: int = 110, view=None) -> Path:
    """Draw a correspondence as coloured cells on two meshes side by side, to a PNG file.

    As in the correspondence figures of Bronstein et al. (IJCV 2010, §5): each face takes
    the colour of its vertices' cell id (see :func:`voronoi_labels`), the same id in the
    same colour on both shapes, so matching cells are seen at a glance. Colours are
    categorical (hues by golden-ratio steps, with cycling saturation and value); id -1
    (unassigned) is grey. Faces are Lambert-shaded from a light at the upper left front,
    two-sided, and drawn far to near (painter's algorithm) with orthographic projection.

    The view is chosen from the shapes' principal axes (area-weighted, pooled over both
    shapes, each centred): the largest extent horizontal, the second vertical, looking
    along the smallest; the same rotation and the same scale are used for both shapes.

    Parameters
    ----------
    x_mesh, y_mesh : Mesh
    x_labels : array_like of int, shape (x_mesh.n_vertices,)
        Cell id of each vertex of ``x_mesh``, >= -1.
    y_labels : array_like of int, shape (y_mesh.n_vertices,)
        Cell id of each vertex of ``y_mesh``; the same id means the corresponding cell.
    path : str or Path
        Output PNG file; its parent folder must exist.
    titles : (str, str), default ("X", "Y")
        Title above each shape.
    title : str, optional
        Title of the figure.
    dpi : int, default 110
        The figure is about 9 inches wide.
    view : array_like, shape (3, 3), optional
        Rotation whose rows are the screen's right, up and towards-the-viewer directions in
        the meshes' coordinates. Default: from the principal axes, as above.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TypeError
        If a mesh is not a :class:`gromov.Mesh`, labels are not integers, or a title is
        not a string.
    ValueError
        If labels have the wrong length or values < -1, ``dpi`` is not positive or ``view``
        is not a rotation.
    ImportError
        If matplotlib is not installed.
    """
    for name, m in (("x_mesh", x_mesh), ("y_mesh", y_mesh)):
        if not isinstance(m, Mesh):
            raise TypeError(f"{name} must be a gromov.Mesh, got {type(m).__name__}")
    lx = _check_labels(x_labels, x_mesh, "x_labels")
    ly = _check_labels(y_labels, y_mesh, "y_labels")
    if (isinstance(titles, str) or not isinstance(titles, (tuple, list)) or len(titles) != 2
            or not all(isinstance(t, str) for t in titles)):
        raise TypeError(f"titles must be a pair of strings, got {titles!r}")
    if title is not None and not isinstance(title, str):
        raise TypeError(f"title must be a string or None, got {type(title).__name__}")
    if isinstance(dpi, bool) or not isinstance(dpi, numbers.Integral) or dpi <= 0:
        raise ValueError(f"dpi must be a positive integer, got {dpi!r}")
    rot = _principal_view((x_mesh, y_mesh)) if view is None else _check_view(view)
    return _two_panels((x_mesh, y_mesh), ((lx, None), (ly, None)), rot, path, titles, title, dpi)


def _two_panels(meshes, paints, rot, path, titles, title, dpi) -> Path:
    """Both meshes side by side, seen along ``rot`` at one scale; ``paints``: per mesh
    ``(labels, None)`` or ``(None, RGB per vertex)``."""
    from .recognition import _figure

    x_mesh, y_mesh = meshes
    proj = []
    for m in (x_mesh, y_mesh):
        p = m.vertices @ rot.T
        used = p[m.faces.ravel()] if m.n_faces else p
        lo, hi = used.min(axis=0), used.max(axis=0)
        proj.append((p, 0.5 * (lo + hi), 0.5 * (hi - lo)))
    half = np.max([h for _, _, h in proj], axis=0)
    hx, hy = max(half[0], 1e-12), max(half[1], 1e-12)
    pad = 1.04
    panel_w = 4.5
    panel_h = float(np.clip(panel_w * hy / hx, 1.6, 6.0))
    top = 0.35 + (0.35 if title else 0.0)
    fig = _figure((2 * panel_w, panel_h + top), int(dpi))
    for i, ((p, centre, _), m, (lab, rgb), sub) in enumerate(zip(proj, (x_mesh, y_mesh), paints, titles)):
        ax = fig.add_axes((i * 0.5, 0.0, 0.5, panel_h / (panel_h + top)))
        if m.n_faces:
            _draw_mesh(ax, p, m.faces, lab, rgb)
        ax.set_xlim(centre[0] - pad * hx, centre[0] + pad * hx)
        ax.set_ylim(centre[1] - pad * hy, centre[1] + pad * hy)
        ax.set_aspect("equal", adjustable="box")
        ax.set_axis_off()
        ax.set_title(sub, fontsize=11)
    if title:
        fig.suptitle(title, fontsize=12, y=1.0 - 0.08 / (panel_h + top))
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=int(dpi))
    return path


def coordinate_colours(mesh: Mesh, view=None) -> np.ndarray:
    """``(n, 3)`` RGB in [0, 1]: each vertex's coordinates along the principal axes, scaled
    to the unit cube -- a smooth function that tells every part of a shape from the others,
    the usual way to show a dense map (its values carried to the other shape)."""
    rot = _principal_view((mesh,)) if view is None else _check_view(view)
    p = mesh.vertices @ rot.T
    lo, hi = p.min(axis=0), p.max(axis=0)
    return 0.15 + 0.8 * (p - lo) / np.maximum(hi - lo, 1e-12)


def plot_transfer(x_mesh: Mesh, y_mesh: Mesh, x_colours, y_colours, path, *,
                  titles: tuple[str, str] = ("X", "Y"), title: str | None = None,
                  dpi: int = 110, view=None) -> Path:
    """Draw a dense map as a colour function of X and the same function carried to Y.

    As :func:`plot_correspondence`, but each shape is painted with per-vertex RGB colours
    (e.g. :func:`coordinate_colours` of X and :meth:`gromov.MatchResult.transfer` of them
    to Y), both seen from the same viewpoint and at the same scale.

    Parameters
    ----------
    x_mesh, y_mesh : Mesh
    x_colours, y_colours : array_like, shape (n_vertices, 3)
        RGB in [0, 1] per vertex of each mesh.
    path, titles, title, dpi, view
        As :func:`plot_correspondence`.
    """
    rgbs = []
    for name, m, c in (("x_colours", x_mesh, x_colours), ("y_colours", y_mesh, y_colours)):
        if not isinstance(m, Mesh):
            raise TypeError(f"the meshes must be gromov.Mesh, got {type(m).__name__}")
        c = np.asarray(c, dtype=np.float64)
        if c.shape != (m.n_vertices, 3) or not np.all(np.isfinite(c)):
            raise ValueError(f"{name} must be finite RGB of shape ({m.n_vertices}, 3), got {c.shape}")
        rgbs.append((None, c))
    rot = _principal_view((x_mesh, y_mesh)) if view is None else _check_view(view)
    return _two_panels((x_mesh, y_mesh), rgbs, rot, path, titles, title, dpi)


# ---------------------------------------------------------------------------- formatting
def _esc(x) -> str:
    return html.escape(str(x), quote=True)


def _num(x) -> float | None:
    """A finite float from a number (not a bool), else None."""
    if isinstance(x, bool) or not isinstance(x, numbers.Real):
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _pct(x) -> str:
    v = _num(x)
    return "n/a" if v is None else f"{100.0 * v:.1f}%"


def _fix4(x) -> str:
    v = _num(x)
    return "n/a" if v is None else f"{v:.4f}"


def _seconds(x) -> str:
    v = _num(x)
    if v is None:
        return "n/a" if x is None or isinstance(x, numbers.Real) else _value_text(x)
    if v >= 120:
        return f"{v:.0f} s ({int(v // 60)} min {v % 60:02.0f} s)"
    return f"{v:.1f} s" if v >= 1 else f"{v:.3f} s"


def _compare(ours, paper, *, unit: float, kind: str, judge: bool = True) -> tuple[str, str]:
    """``(ours - paper, verdict)`` for a lower-is-better number; unit = display precision.
    Without ``judge`` (a run on other data than the paper's) there is neither."""
    o, p = _num(ours), _num(paper)
    if o is None or p is None or not judge:
        return "", ""
    diff = o - p
    if kind == "pct":
        text = f"{100.0 * diff:+.1f} pp"
    else:
        text = f"{diff:+.4f}"
    if diff > unit / 2:
        verdict = "worse than the paper"
    elif diff < -unit / 2:
        verdict = "better than the paper"
    else:
        verdict = "same as the paper"
    return text, verdict


def _get(d, *keys):
    """``d[k0][k1]...`` or None when any level is missing or not a mapping."""
    for k in keys:
        if not isinstance(d, Mapping) or k not in d:
            return None
        d = d[k]
    return d


def _ordered(keys, preferred) -> list:
    keys = list(keys)
    return [k for k in preferred if k in keys] + [k for k in keys if k not in preferred]


def _table(header, rows, *, cls: str = "") -> str:
    """An HTML table; every cell is escaped here."""
    c = f' class="{_esc(cls)}"' if cls else ""
    out = [f"<table{c}>", "<thead><tr>" + "".join(f"<th>{_esc(h)}</th>" for h in header)
           + "</tr></thead>", "<tbody>"]
    for row in rows:
        out.append("<tr>" + "".join(f"<td>{_esc(v)}</td>" for v in row) + "</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


def _not_run(what: str) -> str:
    return f'<p class="na">{_esc(what)}: not run.</p>'


def _flatten(d, prefix: str = "") -> list[tuple[str, object]]:
    out = []
    for k, v in d.items():
        name = f"{prefix} / {k}" if prefix else str(k)
        if isinstance(v, Mapping) and v:
            out.extend(_flatten(v, name))
        else:
            out.append((name, v))
    return out


def _value_text(v, limit: int = 300) -> str:
    if isinstance(v, float):
        text = f"{v:.6g}"
    elif isinstance(v, (str, int, bool)) or v is None:
        text = str(v)
    else:
        try:
            text = json.dumps(v, default=str)
        except (TypeError, ValueError):
            text = str(v)
    return text if len(text) <= limit else text[:limit - 1] + "…"


# ---------------------------------------------------------------------------- figures
def _caption(key: str) -> str:
    """A caption from a figure key, e.g. ``"roc_weld"`` -> ``"ROC, Experiment 1 (welds)"``."""
    kinds = {"roc": "ROC", "mds": "MDS map", "correspondence": "Correspondence",
             "topkids": "TOPKIDS", "dense": "Interactive dense map"}
    tokens = [t for t in str(key).split("_") if t]
    if not tokens:
        return str(key)
    head, rest = tokens[0], tokens[1:]
    recognition = head in ("roc", "mds")
    words = [kinds.get(head, head)]
    free = head not in kinds  # was the last word a free one? then continue it
    for t in rest:
        if recognition and t in _EXPERIMENTS:
            words.append(_EXPERIMENTS[t])
        elif t in _CONDITIONS or t in _METRIC_ORDER:
            words.append(_CONDITIONS.get(t, t))
        elif free:
            words[-1] += " " + t
        else:
            words.append(t)
        free = not (t in _CONDITIONS or t in _METRIC_ORDER)
    return ", ".join(words)


def _section_of(key: str) -> str:
    head = str(key).split("_", 1)[0]
    return {"roc": "recognition", "mds": "recognition", "correspondence": "correspondence",
            "dense": "correspondence", "topkids": "topkids"}.get(head, "other")


def _embed(out_dir: Path, key: str, filename) -> str:
    caption = _caption(key)
    if not isinstance(filename, (str, Path)):
        return f'<p class="na">Figure {_esc(caption)}: no file name given.</p>'
    path = out_dir / filename
    if str(filename).endswith(".html"):   # an interactive page: linked, not embedded
        if not path.is_file():
            return f'<p class="na">Page {_esc(caption)}: file {_esc(filename)} not found.</p>'
        return (f'<p class="page"><a href="{_esc(filename)}">{_esc(caption)}</a>: both shapes to turn '
                f"and zoom, the reference's colours carried by the dense map.</p>")
    try:
        data = path.read_bytes()
    except OSError:
        logger.warning("report: figure %r not found at %s", key, path)
        return f'<p class="na">Figure {_esc(caption)}: file {_esc(filename)} not found.</p>'
    if data.startswith(_PNG_SIGNATURE):
        mime = "image/png"
    elif data.startswith(_JPEG_SIGNATURE):
        mime = "image/jpeg"
    else:
        return (f'<p class="na">Figure {_esc(caption)}: {_esc(filename)} is not a PNG '
                f'or JPEG image.</p>')
    b64 = base64.b64encode(data).decode("ascii")
    return (f'<figure><img alt="{_esc(caption)}" src="data:{mime};base64,{b64}">'
            f"<figcaption>{_esc(caption)} <span class=\"file\">({_esc(filename)})</span>"
            f"</figcaption></figure>")


def _figures_html(out_dir: Path, figures: Mapping, section: str) -> str:
    parts = [_embed(out_dir, k, f) for k, f in figures.items() if _section_of(k) == section]
    return '<div class="figures">\n' + "\n".join(parts) + "\n</div>" if parts else ""


# ---------------------------------------------------------------------------- sections
def _header(results: Mapping) -> str:
    quick = results.get("quick")
    rows = [
        ("data set", results.get("dataset", "not given")),
        ("data", results.get("data") if results.get("data") is not None else "not given"),
        ("date", results.get("date", "not given")),
        ("command", results.get("command", "not given")),
        ("total time", _seconds(results.get("seconds_total"))),
        ("quick run", "yes" if quick else ("no" if quick is not None else "not given")),
    ]
    other = other_classes(results)
    if other:
        rows.append(("classes", ", ".join(other)))
    body = "\n".join(f"<tr><th>{_esc(k)}</th><td>{_esc(v)}</td></tr>" for k, v in rows)
    out = f'<table class="kv">\n{body}\n</table>'
    if other:
        out += (f'\n<p class="note">Run on {_esc(", ".join(other))}, not on the paper\'s classes '
                f"({_esc(', '.join(PAPER_CLASSES))}): the paper's numbers beside ours are for its "
                "classes, a reference point rather than a comparison.</p>")
    if quick:
        out += ('\n<p class="note">Quick run: fewer shapes, samples or iterations than the '
                "paper; the numbers are a check that everything runs, not a reproduction.</p>")
    return out


PAPER_CLASSES = tuple(EXPERIMENT1_CLASSES)
"""The TOSCA classes of the paper's experiments (david: its male, victoria: its female)."""


def other_classes(results: Mapping) -> list[str]:
    """The classes of a TOSCA run that are not the paper's (``params.experiment1``), else ``[]``."""
    classes = _get(results, "params", "experiment1")
    if results.get("dataset") != "tosca" or not isinstance(classes, Mapping):
        return []
    return list(classes) if set(classes) != set(PAPER_CLASSES) else []


def on_papers_data(results: Mapping) -> bool:
    """Whether a run is on the paper's data (TOSCA, the paper's classes): only then are our
    numbers judged against the paper's; elsewhere its numbers are a reference point."""
    return results.get("dataset") == "tosca" and not other_classes(results)


def _paper_label(results: Mapping) -> str:
    return "paper" if on_papers_data(results) else "paper (its TOSCA numbers)"


def _eer_of(results: Mapping, exp: str, metric: str):
    v = _get(results, "eer", exp, metric)
    return v if v is not None else _get(results, "recognition", exp, metric, "eer")


def _recognition_rows(results: Mapping) -> tuple[list, list[str]]:
    exps: dict = {}
    for src in (results.get("eer"), results.get("recognition")):
        if isinstance(src, Mapping):
            exps.update((k, None) for k, v in src.items() if isinstance(v, Mapping))
    rows, worse = [], []
    for exp in _ordered(exps, tuple(_EXPERIMENTS)):
        metrics: dict = {}
        for src in (_get(results, "eer", exp), _get(results, "recognition", exp)):
            if isinstance(src, Mapping):
                metrics.update((k, None) for k, v in src.items()
                               if k in _METRICS and (isinstance(v, Mapping) or _num(v) is not None))
        for metric in _ordered(metrics, _METRIC_ORDER):
            ours = _eer_of(results, exp, metric)
            paper = _get(PAPER, "eer", exp, metric)
            diff, verdict = _compare(ours, paper, unit=0.001, kind="pct", judge=on_papers_data(results))
            nn = _get(results, "recognition", exp, metric, "nn_accuracy")
            name = _EXPERIMENTS.get(exp, exp)
            ranked = _get(results, "recognition", exp, metric, "ranked_by")
            other = _get(results, "recognition", exp, metric,
                         "eer_gh" if ranked == "trimmed" else "eer_trimmed")
            local = _get(results, "recognition", exp, metric, "eer_local")
            rows.append((name, metric, _pct(ours), _pct(paper) if paper is not None else "",
                         diff, verdict, _pct(nn) if nn is not None else "",
                         _pct(other) if _num(other) is not None else "",
                         _pct(local) if _num(local) is not None else ""))
            if verdict.startswith("worse"):
                worse.append(f"EER, {name}, {metric}: {_pct(ours)} against the paper's "
                             f"{_pct(paper)} ({diff})")
    return rows, worse


def _recognition_sets(results: Mapping) -> str:
    rec = results.get("recognition")
    if not isinstance(rec, Mapping):
        return ""
    items = []
    for exp in _ordered([k for k in rec if isinstance(rec[k], Mapping)], tuple(_EXPERIMENTS)):
        r = rec[exp]
        entries, classes, perturbed = r.get("entries"), r.get("classes"), r.get("perturbed")
        bits = []
        if isinstance(entries, (list, tuple)):
            bits.append(f"{len(entries)} shapes")
        if isinstance(classes, (list, tuple)):
            uniq = list(dict.fromkeys(str(c) for c in classes))
            bits.append(f"{len(uniq)} classes ({', '.join(uniq)})")
        if isinstance(perturbed, (list, tuple)):
            bits.append(f"{sum(bool(p) for p in perturbed)} with topological noise")
        if bits:
            items.append(f"<li>{_esc(_EXPERIMENTS.get(exp, exp))}: {_esc('; '.join(bits))}</li>")
    return "<ul>\n" + "\n".join(items) + "\n</ul>" if items else ""


def _error_counts(table) -> str:
    if not isinstance(table, Mapping) or not table:
        return "none"
    return ", ".join(f"{k} {v[0]} of {v[1]}" for k, v in table.items()
                     if isinstance(v, (list, tuple)) and len(v) == 2)


def errors_text(errors: Mapping) -> str:
    """One line on where the errors at a threshold are (:func:`recognition.errors_at`)."""
    return (f"false acceptances (pairs of classes): {_error_counts(errors.get('false_accept'))}; "
            f"false rejections (within a class): {_error_counts(errors.get('false_reject'))}")


def _error_sources(results: Mapping) -> str:
    """Which classes the errors at each EER threshold come from."""
    items = []
    for exp in _EXPERIMENTS:
        for metric in _METRIC_ORDER:
            e = _get(results, "recognition", exp, metric, "errors_at_eer")
            if isinstance(e, Mapping):
                items.append(f"<li>{_esc(_EXPERIMENTS[exp])}, {_esc(metric)}: "
                             f"{_esc(errors_text(e))}</li>")
    if not items:
        return ""
    return ("<p>Where the errors are, at the threshold of each equal error rate (counts of "
            "pairs):</p>\n<ul>\n" + "\n".join(items) + "\n</ul>")


def _recognition(results: Mapping, figures: Mapping, out_dir: Path) -> tuple[str, list[str]]:
    rows, worse = _recognition_rows(results)
    parts = ["<h2>Recognition</h2>"]
    if not rows:
        parts.append(_not_run("Recognition (Experiments 1 and 2)"))
    else:
        ranked = {_get(results, "recognition", exp, m, "ranked_by")
                  for exp in _EXPERIMENTS for m in _METRIC_ORDER} - {None}
        if ranked == {"trimmed"}:
            how = ("ranking the pairs by the <em>trimmed distortion</em> of their Gromov-Hausdorff "
                   "correspondence: the RMS distortion of its best-fitting 80% of sample pairs, "
                   "which sets aside the pairs a local change of topology altered (our choice, "
                   "not the paper's: made on the synthetic set and on TOSCA classes the paper did "
                   "not use). The column “EER, GH estimate” ranks by the GH estimate itself (½ RMS "
                   "distortion)")
            if _get(results, "params", "rank_residual") == "log":
                how = how.replace("the RMS distortion of its best-fitting 80% of sample pairs",
                                  "the RMS of the log ratios of corresponding distances over its "
                                  "best-fitting 80% of sample pairs (a multiplicative distortion)", 1)
            scale = _get(results, "params", "rank_tau_scale")
            if scale is not None:
                how = how.replace(" (our choice", f"; for the diffusion metric measured with the heat "
                                  f"distance at {scale:g} × the diffusion time the correspondence was "
                                  f"found at (our choices", 1)
            other = "EER, GH estimate"
        elif ranked == {"gh"}:
            how = ("ranking the pairs by the Gromov-Hausdorff estimate (½ RMS distortion). The "
                   "column “EER, trimmed” ranks by the trimmed distortion (RMS of the best-fitting 80% of "
                   "sample pairs)")
            other = "EER, trimmed"
        else:
            how = "ranking the pairs by the Gromov-Hausdorff estimate"
            other = ""
        parts.append(f"<p>Equal error rate of shape pairs as a same-class detector, {how} "
                     "(lower is better); paper: Table 1. "
                     "Nearest-neighbour accuracy: leave-one-out classification by the "
                     "closest other shape (not reported in the paper).</p>")
        parts.append(_recognition_sets(results))
        head = ("experiment", "metric", "EER ours", f"EER {_paper_label(results)}", "ours − paper", "verdict",
                "nearest-neighbour accuracy")
        ks = {_get(results, "recognition", exp, m, "local_scaling_k")
              for exp in _EXPERIMENTS for m in _METRIC_ORDER} - {None}
        local = ""
        if any(row[-1] for row in rows):
            local = f"EER, locally scaled (k = {', '.join(str(k) for k in sorted(ks))})"
            parts.append("<p>The last column is the same ranking after <em>local scaling</em>: "
                         "each distance divided by the geometric mean of the two shapes' "
                         "distances to their k-th nearest shape in the set (Zelnik-Manor &amp; "
                         "Perona, NIPS 2004). It uses the whole set, not the pair alone, so it "
                         "is not the paper's measure and is not compared with it. A shape with "
                         "topological noise lies farther from its own class than clean shapes "
                         "do, and gets a larger scale (k chosen on the validation sets).</p>")
        keep = [i for i, on in enumerate((True,) * 7 + (bool(other), bool(local))) if on]
        rows = [tuple(row[i] for i in keep) for row in rows]
        parts.append(_table(head + ((other,) if other else ()) + ((local,) if local else ()), rows))
        parts.append(_error_sources(results))
    parts.append(_figures_html(out_dir, figures, "recognition"))
    return "\n".join(p for p in parts if p), worse


def _correspondence(results: Mapping, figures: Mapping, out_dir: Path) -> tuple[str, list[str]]:
    corr = results.get("correspondence")
    parts = ["<h2>Correspondence</h2>"]
    worse: list[str] = []
    metrics = ([m for m in _ordered(corr, _METRIC_ORDER) if isinstance(corr[m], Mapping)]
               if isinstance(corr, Mapping) else [])
    if not metrics:
        parts.append(_not_run("Correspondence"))
    else:
        parts.append(
            "<p>Correspondence distance d(C, C<sub>0</sub>): the mean distance between each "
            "sample's computed and true image, relative to the diameter, averaged over both "
            "directions (lower is better). Ours is measured with the geodesic metric of the "
            "clean (unperturbed) shapes for both matching metrics, so a weld's shortcut cannot "
            "make an error look small. Bodies are left/right symmetric: the table counts the "
            "mirrored map as correct (best of direct and mirrored ground truth) and gives the "
            "direct-only number beside it. The paper reports d(C, C<sub>0</sub>) on the cats, "
            "without and with topology changes; our welds and holes are both compared with its "
            "“with topology changes” number, and the difference is taken from our cats when "
            "we have them, else from all classes.</p>")
        rows = []
        classes: list = []
        for metric in metrics:
            m = corr[metric]
            by_class = m.get("by_class") if isinstance(m.get("by_class"), Mapping) else {}
            classes.extend(c for c in by_class if c not in classes)
            conds = [k for k in m if k in _CONDITIONS and _num(m[k]) is not None]
            for cond in _ordered(conds, tuple(_CONDITIONS)):
                ours = m.get(cond)
                direct = m.get(f"{cond}_direct")
                cat = _get(by_class, "cat", cond)
                pcond = _PAPER_CONDITION.get(cond)
                paper = _get(PAPER, "correspondence", metric, pcond) if pcond else None
                ref = cat if _num(cat) is not None else ours
                diff, verdict = _compare(ref, paper, unit=1e-4, kind="fix", judge=on_papers_data(results))
                rows.append((metric, _CONDITIONS.get(cond, cond), _fix4(ours),
                             _fix4(direct) if _num(direct) is not None else "",
                             _fix4(cat) if cat is not None else "",
                             _fix4(paper) if paper is not None else "", diff, verdict))
                if verdict.startswith("worse"):
                    which = "cats" if ref is cat else "all classes"
                    worse.append(f"d(C, C0), {metric}, {_CONDITIONS.get(cond, cond)} "
                                 f"({which}): {_fix4(ref)} against the paper's "
                                 f"{_fix4(paper)} ({diff})")
        parts.append(_table(("metric", "condition", "ours, all classes", "ours, direct only",
                             "ours, cats",
                             f"{_paper_label(results)}, cats", "ours − paper", "verdict"), rows))
        own = [m for m in metrics if isinstance(corr[m].get("recognition_metric"), Mapping)]
        if own:
            parts.append(
                "<p>The correspondence of " + ", ".join(_esc(m) for m in own) + " is computed with "
                "its own metric options, not the recognition's (docs/design/metrics.md, “Heat units”): "
                + "; ".join(f"{_esc(m)}: {_esc(_get(results, 'params', 'correspondence_options', m))} "
                            f"(recognition: {_esc(_get(results, 'params', 'metric_options', m))})"
                            for m in own)
                + ". The recognition metric's own maps of the same pairs, for comparison:</p>")
            orow = [(m, _CONDITIONS.get(c, c), _fix4(corr[m]["recognition_metric"][c]),
                     _fix4(corr[m]["recognition_metric"].get(f"{c}_direct")))
                    for m in own for c in _ordered([k for k in corr[m]["recognition_metric"]
                                                    if k in _CONDITIONS], tuple(_CONDITIONS))]
            parts.append(_table(("metric", "condition", "recognition metric, all classes",
                                 "direct only"), orow))
        if classes:
            cols = [(metric, cond) for metric in metrics
                    for cond in _ordered([c for c in corr[metric] if c in _CONDITIONS],
                                         tuple(_CONDITIONS))]
            header = ["class"] + [f"{metric}, {_CONDITIONS.get(c, c)}" for metric, c in cols]
            crow = [[str(c)] + [_fix4(_get(corr, metric, "by_class", c, cond))
                                if _get(corr, metric, "by_class", c, cond) is not None else ""
                                for metric, cond in cols] for c in classes]
            parts.append("<h3>By class</h3>")
            parts.append(_table(header, crow))
    dense_rows = [(m, _CONDITIONS.get(c, c), f"{d[c]:.2f}", f"{d[c + '_direct']:.2f}",
                   _fix4(d.get(c + "_per_diameter")))
                  for m in (_ordered(corr, _METRIC_ORDER) if isinstance(corr, Mapping) else [])
                  if isinstance(d := _get(corr, m, "dense"), Mapping)
                  for c in _ordered([k for k in d if k in _CONDITIONS], tuple(_CONDITIONS))]
    if dense_rows:
        parts.append("<h3>Dense maps</h3><p>Every working vertex of the reference carried to the "
                     "deformed shape (<code>match(..., dense=True)</code>), scored on the clean shape: "
                     "mean geodesic error × 100 / √area (the field's unit; the better of the direct "
                     "and the mirrored reading, and the direct one alone) and ÷ the geodesic "
                     "diameter (the paper's unit). Not in the paper.</p>")
        parts.append(_table(("metric", "condition", "mean × 100 / √area", "direct only",
                             "mean / diameter"), dense_rows))
    parts.append(_figures_html(out_dir, figures, "correspondence"))
    return "\n".join(p for p in parts if p), worse


_TOPKIDS_ROWS = (
    ("correspondence", "d(C, C0)", _fix4),
    ("correspondence_direct", "d(C, C0), direct ground truth only", _fix4),
    ("mirrored_fraction", "maps closer to the mirrored ground truth", _pct),
    ("relative_distance_mean", "mean relative distortion", _fix4),
    ("spearman_distance_vs_handles", "Spearman ρ of the distortion with the number of handles", _fix4),
    ("relative_trimmed_mean", "mean relative trimmed distortion (best-fitting 80% of pairs)", _fix4),
    ("spearman_trimmed_vs_handles", "Spearman ρ of the trimmed distortion with the number of handles", _fix4),
)


def _topkids(results: Mapping, figures: Mapping, out_dir: Path) -> str:
    tk = results.get("topkids")
    parts = ["<h2>TOPKIDS</h2>"]
    if not isinstance(tk, Mapping):
        parts.append(_not_run("TOPKIDS (SHREC'16 topological noise)"))
    else:
        # per-metric sections hold the results; "handles" (name -> count) is a mapping too
        metrics = [m for m in _ordered(tk, _METRIC_ORDER)
                   if isinstance(tk[m], Mapping) and "correspondence" in tk[m]]
        bits = []
        if tk.get("n_shapes") is not None:
            bits.append(f"{tk['n_shapes']} shapes")
        if tk.get("reference") is not None:
            bits.append(f"each matched with the reference {tk['reference']}")
        own = [m for m in _METRICS
               if _get(results, "params", "correspondence_options", m) not in
               (None, _get(results, "params", "metric_options", m))]
        bits_own = "".join(f" The {_esc(m)} maps use the correspondence's options "
                           f"{_esc(_get(results, 'params', 'correspondence_options', m))}."
                           for m in own)
        parts.append(f"<p>SHREC'16 TOPKIDS (not in the paper){': ' if bits else ''}"
                     f"{_esc(', '.join(bits))}. Lower d(C, C<sub>0</sub>) and distortion are "
                     f"better.{bits_own}</p>")
        if metrics:
            rows = [[label] + [fmt(_get(tk, m, key)) for m in metrics]
                    for key, label, fmt in _TOPKIDS_ROWS
                    if any(_get(tk, m, key) is not None for m in metrics)]
            parts.append(_table(["measure"] + metrics, rows))
            dense = [(m, tk[m]["dense"]) for m in metrics if isinstance(tk[m].get("dense"), Mapping)]
            if dense:
                parts.append("<h3>Dense maps (SHREC'16 protocol)</h3><p>Every vertex of kidXX "
                             "carried to the reference by <code>match(..., dense=True)</code>, scored "
                             "on the reference's input mesh: mean geodesic error × 100 / √area per "
                             "pair, averaged (the better of the direct and the mirrored ground truth, "
                             "and the direct one alone); the sample images scored the same way; "
                             "pairs whose mean error exceeds a quarter of the diameter.</p>")
                parts.append(_table(
                    ("metric", "dense, mean", "dense, direct only", "median vertex", "mean / diameter",
                     "samples, mean", "grossly wrong pairs"),
                    [(m, f"{d['mean']:.2f}", f"{d['mean_direct']:.2f}", f"{d['median']:.2f}",
                      _fix4(d["per_diameter_mean"]), f"{d['samples_mean']:.2f}", str(d["gross_pairs"]))
                     for m, d in dense]))
            shapes: list = []
            for m in metrics:
                ps = tk[m].get("per_shape")
                if isinstance(ps, Mapping):
                    shapes.extend(s for s in ps if s not in shapes)
            if shapes:
                handles = tk.get("handles") if isinstance(tk.get("handles"), Mapping) else {}
                rows = [[s] + [_fix4(v) if (v := _get(tk, m, "per_shape", s)) is not None else ""
                               for m in metrics]
                        + ([f"{h:g}" if (h := _num(handles.get(s))) is not None else ""] if handles else [])
                        for s in shapes]
                parts.append("<h3>d(C, C0) per shape</h3>")
                parts.append(_table(["shape"] + metrics + (["handles"] if handles else []), rows))
        else:
            parts.append('<p class="na">No per-metric results.</p>')
    parts.append(_figures_html(out_dir, figures, "topkids"))
    return "\n".join(p for p in parts if p)


def _kv_section(title: str, d, *, fmt=_value_text, header=("name", "value")) -> str:
    parts = [f"<h2>{_esc(title)}</h2>"]
    if not isinstance(d, Mapping) or not d:
        parts.append(_not_run(title))
    else:
        parts.append(_table(header, [(k, fmt(v)) for k, v in _flatten(d)], cls="kv"))
    return "\n".join(parts)


def _parameters(results: Mapping) -> str:
    parts = ["<h2>Parameters and seeds</h2>"]
    any_ = False
    for key, title in (("params", "Parameters"), ("seeds", "Seeds")):
        d = results.get(key)
        if isinstance(d, Mapping) and d:
            any_ = True
            parts.append(f"<h3>{title}</h3>")
            parts.append(_table(("name", "value"), [(k, _value_text(v)) for k, v in _flatten(d)],
                                cls="kv"))
        else:
            parts.append(f'<p class="na">{title}: not given.</p>')
    return "\n".join(parts) if any_ else parts[0] + "\n" + _not_run("Parameters and seeds")


def _summary(worse: list[str], n_compared: int) -> str:
    if n_compared == 0:
        return ""
    if not worse:
        return (f"<p>None of our {n_compared} numbers compared with the paper is worse than "
                "the paper's.</p>")
    items = "\n".join(f"<li>{_esc(w)}</li>" for w in worse)
    return (f"<p>Worse than the paper in {len(worse)} of {n_compared} compared numbers:</p>\n"
            f"<ul>\n{items}\n</ul>")


_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;margin:2em auto;
max-width:70em;padding:0 1em;color:#222;line-height:1.4}
h1{font-size:1.5em}h2{font-size:1.25em;border-bottom:1px solid #ccc;margin-top:2em}
h3{font-size:1.05em}
table{border-collapse:collapse;margin:.6em 0}
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:left;vertical-align:top}
thead th{background:#f2f2f2}
table.kv th{background:#f7f7f7;font-weight:normal}
td{font-variant-numeric:tabular-nums}
.na{color:#666;font-style:italic}
.note{background:#f7f7f7;border-left:3px solid #999;padding:.4em .8em}
.figures{display:flex;flex-wrap:wrap;gap:1em}
figure{margin:0;max-width:100%}
figure img{max-width:100%;height:auto;border:1px solid #eee}
figcaption{font-size:.9em;color:#444}
.file{color:#888}
code{font-family:ui-monospace,Menlo,Consolas,monospace}
"""


# ---------------------------------------------------------------------------- the page
def write_report(results: Mapping, out_dir, *, figures: Mapping[str, str] | None = None) -> Path:
    """Write ``out_dir/index.html``: the results of ``gromov reproduce`` beside the paper's.

    The page is self-contained: the figures, read from ``out_dir/<filename>``, are embedded
    as base64 ``data:`` URIs, the style sheet is inline, and nothing (CSS, scripts, fonts,
    images) is loaded from elsewhere. All text from ``results`` is HTML-escaped.

    Sections: a header (data set, date, command, total time, quick flag) and a summary of
    where we are worse than the paper; **Recognition** (EER of Experiments 1 and 2, ours and
    the paper's, as percentages, with the difference in percentage points and the
    nearest-neighbour accuracy when given; ROC and MDS figures); **Correspondence**
    (:math:`d(C, C_0)` overall and by class for the clean, weld and holes conditions, ours and
    the paper's, four decimals; correspondence figures); **TOPKIDS** (geodesic and
    diffusion); **Timings**; **Parameters and seeds**; **Versions**. A part that is missing
    or None is replaced by a short "not run" line. The paper's numbers are :data:`PAPER`
    (Bronstein et al., IJCV 89 (2010), §5); lower is better for all of them.

    Parameters
    ----------
    results : mapping
        As written by ``gromov reproduce`` to ``results.json``. Keys used, all optional:
        ``dataset``, ``data``, ``quick``, ``date``, ``command``, ``seconds_total``,
        ``eer[experiment][metric]`` (fractions; experiments ``"weld"``, ``"holes"``),
        ``recognition[experiment]`` (``entries``, ``classes``, ``perturbed`` lists and
        ``[metric]["eer"]``, ``[metric]["nn_accuracy"]``),
        ``correspondence[metric]`` (``clean``, ``weld``, ``holes`` and
        ``by_class[class][condition]``), ``topkids`` (None or ``n_shapes``, ``reference``
        and per metric ``correspondence``, ``correspondence_direct``, ``mirrored_fraction``,
        ``relative_distance_mean``, ``per_shape``), ``timings`` (flat or nested seconds),
        ``params``, ``seeds``, ``versions`` and ``figures`` (figure key to file name in
        ``out_dir``).
    out_dir : str or Path
        Folder of the report and its figures; created if missing.
    figures : mapping of str to str, optional
        Figure key to file name in ``out_dir``; replaces ``results["figures"]``. Keys are
        captioned from their parts, e.g. ``"roc_weld"`` -> "ROC, Experiment 1 (welds)",
        and placed by prefix: ``roc_``/``mds_`` under Recognition, ``correspondence_``
        under Correspondence, ``topkids_`` under TOPKIDS, any other at the end. A missing
        or unreadable file gives a note instead of the image.

    Returns
    -------
    Path
        The path of ``index.html``.

    Raises
    ------
    TypeError
        If ``results`` or ``figures`` is not a mapping.
    """
    if not isinstance(results, Mapping):
        raise TypeError(f"results must be a mapping (the dict of results.json), "
                        f"got {type(results).__name__}")
    if figures is None:
        figures = results.get("figures") or {}
    if not isinstance(figures, Mapping):
        raise TypeError(f"figures must be a mapping of figure key to file name, "
                        f"got {type(figures).__name__}")
    figures = {str(k): v for k, v in figures.items()}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    recognition, worse_r = _recognition(results, figures, out)
    correspondence, worse_c = _correspondence(results, figures, out)
    n_compared = (sum(1 for exp in PAPER["eer"] for m in PAPER["eer"][exp]
                      if _num(_eer_of(results, exp, m)) is not None)
                  + _n_corr_compared(results)) if on_papers_data(results) else 0
    other = _figures_html(out, figures, "other")
    versions = results.get("versions")
    gromov_version = _get(results, "versions", "gromov")
    title = "gromov reproduce: Bronstein et al., IJCV 2010"
    body = [
        f"<h1>{_esc(title)}</h1>",
        "<p>Reproduction of the experiments of A. M. Bronstein, M. M. Bronstein, "
        "M. Mahmoudi, R. Kimmel and G. Sapiro, “A Gromov-Hausdorff framework with diffusion "
        "geometry for topologically-robust non-rigid shape matching”, International Journal "
        "of Computer Vision 89 (2010), §5.</p>",
        _header(results),
        _summary(worse_r + worse_c, n_compared),
        recognition,
        correspondence,
        _topkids(results, figures, out),
        _kv_section("Timings", results.get("timings"), fmt=_seconds,
                    header=("step", "time")),
        _parameters(results),
        _kv_section("Versions", versions, header=("package", "version")),
    ]
    if other:
        body += ["<h2>Other figures</h2>", other]
    footer = (f"gromov {gromov_version}" if gromov_version is not None else "gromov")
    page = "\n".join([
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{_esc(title)}</title>",
        f"<style>{_CSS}</style>",
        "</head>",
        "<body>",
        *[b for b in body if b],
        f'<p class="na">Written by {_esc(footer)}.</p>',
        "</body>",
        "</html>",
        "",
    ])
    path = out / "index.html"
    atomic_write_text(path, page)
    logger.info("report written to %s", path)
    return path


def _n_corr_compared(results: Mapping) -> int:
    corr = results.get("correspondence")
    if not isinstance(corr, Mapping):
        return 0
    n = 0
    for metric, m in corr.items():
        if not isinstance(m, Mapping) or metric not in PAPER["correspondence"]:
            continue
        by_class = m.get("by_class") if isinstance(m.get("by_class"), Mapping) else {}
        for cond in _PAPER_CONDITION:
            ref = _get(by_class, "cat", cond)
            if _num(ref) is None:
                ref = m.get(cond)
            n += _num(ref) is not None
    return n
