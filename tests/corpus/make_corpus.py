"""Write a corpus of small meshes with the defects real files have.

Each file is made here, from seeded arithmetic on small shapes (none is copied from a data
set): ``python tests/corpus/make_corpus.py OUTDIR`` writes ``OUTDIR/<name>.off`` for every
entry of :data:`DEFECTS`. The test suite (``tests/test_corpus.py``) makes them in a temporary
folder and runs ``gromov info``, ``distances`` and ``match`` on each.

A file keeps its defect as written: vertex order, repeated vertices and faces, zero-area
faces. Where a defect is a real part of the shape (a pinch, a fin, a strip), the shape is
valid as it is; where it is noise (duplicates, zero-area faces, stray vertices), loading
repairs it.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from gromov.shapes import icosphere


def _potato(subdivisions: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A closed, smooth shape with no symmetry (a self-match has one right answer)."""
    s = icosphere(subdivisions)
    v = np.array(s.vertices)
    x, y, z = v.T
    r = 1.0 + 0.18 * np.sin(3 * x + 1) * np.cos(2 * y) + 0.12 * x * z + 0.08 * y ** 3
    return v * r[:, None] * [1.5, 1.0, 0.7], np.array(s.faces)


def _mirror_pressed(band: float, width: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed surface touching itself: a sphere-like shape whose two halves are mirror
    images in z, with its upper sheet pressed onto the lower one where ``|y - band| < width``
    (every upper vertex there takes the coordinates of the lower vertex below it: two sheets,
    vertices at the same places)."""
    nu, half = 32, 8   # 32 around, 2 * 8 - 1 rings from pole to pole
    theta = np.linspace(0.0, 0.5 * np.pi, half + 1)[1:]          # the upper rings and the equator
    phi = np.linspace(0.0, 2 * np.pi, nu, endpoint=False)
    ring = lambda t: np.c_[np.sin(t) * np.cos(phi), np.sin(t) * np.sin(phi), np.full(nu, np.cos(t))]
    upper = [ring(t) for t in theta[:-1]]
    rings = upper + [ring(theta[-1]) * [1, 1, 0]] + [r * [1, 1, -1] for r in upper[::-1]]
    v = np.vstack(rings + [[[0, 0, 1]], [[0, 0, -1]]])
    n_rings = len(rings)
    top, bottom = n_rings * nu, n_rings * nu + 1
    idx = lambda i, j: i * nu + j % nu
    f = []
    for i in range(n_rings - 1):
        for j in range(nu):
            f += [[idx(i, j), idx(i + 1, j), idx(i, j + 1)], [idx(i, j + 1), idx(i + 1, j), idx(i + 1, j + 1)]]
    for j in range(nu):
        f += [[top, idx(0, j), idx(0, j + 1)], [bottom, idx(n_rings - 1, j + 1), idx(n_rings - 1, j)]]
    x, y, z = v.T
    v = np.c_[1.6 * x + 0.3 * y * y, y + 0.25 * x * y, z * (0.8 + 0.2 * x)]   # odd in z: still mirrored
    mirror = np.r_[[idx(n_rings - 1 - i, j) for i in range(n_rings) for j in range(nu)], bottom, top]
    press = (v[:, 2] > 0) & (np.abs(v[:, 1] - band) < width)
    v[press] = v[mirror[press]]
    return v, np.array(f)


def fold():
    """Coincident vertices on two sheets: a thin fold where a closed surface touches itself
    over a patch (its triangles lie on each other, opposite ways round)."""
    return _mirror_pressed(0.0, 0.45)


def touching_curve():
    """A closed surface touching itself along a curve (a band one edge wide)."""
    return _mirror_pressed(0.3, 0.06)


def pinch():
    """Two cones meeting at their apex: one vertex shared by two closed surfaces."""
    rng = np.random.default_rng(1)
    parts, faces, n = [np.zeros((1, 3))], [], 1
    for height, k, sign in ((1.4, 17, 1.0), (0.9, 13, -1.0)):
        t = np.linspace(0, 2 * np.pi, k, endpoint=False)
        r = 0.6 + 0.15 * rng.random(k)
        for level in (0.5, 1.0):   # a ring halfway and the base ring
            parts.append(np.c_[level * r * np.cos(t) + 0.1 * level, level * r * np.sin(t),
                               np.full(k, sign * level * height)])
        mid, base = n + np.arange(k), n + k + np.arange(k)
        centre = n + 2 * k
        parts.append([[0.1, 0.0, sign * height]])
        nxt = np.roll(np.arange(k), -1)
        tri = [np.c_[np.zeros(k, int), mid, mid[nxt]], np.c_[mid, base, base[nxt]],
               np.c_[mid, base[nxt], mid[nxt]], np.c_[base, np.full(k, centre), base[nxt]]]
        tri = np.vstack(tri)
        faces.append(tri if sign > 0 else tri[:, ::-1])
        n = centre + 1
    return np.vstack(parts), np.vstack(faces)


def fin():
    """Non-manifold edges: a triangle standing out of the surface on three of its edges."""
    v, f = _potato()
    extra = []
    for k in (0, 200, 700):
        a, b, c = f[k]
        extra.append((a, b, len(v) + len(extra)))
    tips = [v[f[k, :2]].mean(0) * 1.25 for k in (0, 200, 700)]
    return np.vstack([v, tips]), np.vstack([f, extra])


def zero_area():
    """Zero-area faces (a vertex on the middle of an edge, closed by a flat triangle) and sliver
    faces (a vertex almost on an edge)."""
    v, f = _potato()
    f = f.tolist()
    v = v.tolist()
    for k, off in ((0, 0.0), (150, 0.0), (300, 0.0), (450, 1e-4), (600, 1e-4)):
        a, b, c = f[k]
        m = 0.5 * (np.asarray(v[a]) + np.asarray(v[b]))
        m = m + off * (np.asarray(v[c]) - m)
        w = len(v)
        v.append(m.tolist())
        f[k] = [a, w, c]
        f += [[w, b, c], [a, b, w]]
    return np.array(v), np.array(f)


def collinear():
    """A face on three points of a line, with vertices of its own: nothing else uses them."""
    v, f = _potato()
    line = v[0] + np.outer([0.0, 0.5, 1.0], [0.3, 0.2, 0.1])
    return np.vstack([v, line]), np.vstack([f, [[len(v), len(v) + 1, len(v) + 2]]])


def opposite_duplicates():
    """Faces written twice, the second time the other way round."""
    v, f = _potato()
    return v, np.vstack([f, f[::37, ::-1]])


def stray_vertices():
    """Unreferenced and duplicate vertices at the start, in the middle and at the end of the
    vertex list; some faces use the duplicates."""
    v, f = _potato()
    n = len(v)
    rng = np.random.default_rng(2)
    dup = rng.choice(n, 9, replace=False)
    # the new list: [stray, dup0..2] + v[:n//2] + [stray, dup3..5] + v[n//2:] + [dup6..8, stray]
    head = [[5.0, 5.0, 5.0], *v[dup[:3]]]
    middle = [[-5.0, 5.0, 5.0], *v[dup[3:6]]]
    tail = [*v[dup[6:]], [5.0, -5.0, 5.0]]
    old = np.r_[4 + np.arange(n // 2), 4 + n // 2 + 4 + np.arange(n - n // 2)]   # where v[i] went
    copies = np.r_[1, 2, 3, 4 + n // 2 + 1, 4 + n // 2 + 2, 4 + n // 2 + 3,
                   8 + n + np.arange(3)]
    V = np.vstack([head, v[:n // 2], middle, v[n // 2:], tail])
    F = old[f]
    for d, c in zip(dup, copies):   # every other face around the vertex uses its copy
        rows = np.flatnonzero((f == d).any(axis=1))[::2]
        F[rows] = np.where(f[rows] == d, c, F[rows])
    return V, F


def small_pieces():
    """Many small pieces beside a large one: 30 tiny irregular tetrahedra scattered around."""
    v, f = _potato()
    rng = np.random.default_rng(3)
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    tf = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    V, F = [v], [f]
    n = len(v)
    for _ in range(30):
        corners = tet * [1.0, 1.6, 2.3] + rng.uniform(-0.2, 0.2, (4, 3))   # no two edges alike
        V.append(corners * 0.03 + rng.uniform(-2.5, 2.5, 3))
        F.append(tf + n)
        n += 4
    return np.vstack(V), np.vstack(F)


def huge():
    """Coordinates near 1e30."""
    v, f = _potato()
    return v * 1e30, f


def tiny():
    """Coordinates near 1e-30."""
    v, f = _potato()
    return v * 1e-30, f


def strip():
    """A strip: every vertex and edge on the boundary (one row of triangles), bent in space,
    wider at one end and wavy along one side."""
    k = 60
    u = np.linspace(0, 4.0, k)
    w = 0.25 + 0.1 * u / 4.0 + 0.04 * np.sin(5 * u)
    centre = np.c_[np.cos(u), np.sin(u), 0.3 * u]
    side = np.c_[np.zeros(k), np.zeros(k), np.ones(k)]
    v = np.vstack([centre, centre + w[:, None] * side])
    a, b = np.arange(k - 1), k + np.arange(k - 1)
    f = np.vstack([np.c_[a, a + 1, b], np.c_[a + 1, b + 1, b]])
    return v, f


#: The corpus: file name -> function returning ``(vertices, faces)``.
DEFECTS = {fn.__name__: fn for fn in (fold, touching_curve, pinch, fin, zero_area, collinear,
                                      opposite_duplicates, stray_vertices, small_pieces, huge,
                                      tiny, strip)}


def write_off(path: Path, v: np.ndarray, f: np.ndarray) -> None:
    """An OFF file with the vertices and faces exactly as given (17 significant digits)."""
    with open(path, "w") as fh:
        fh.write(f"OFF\n{len(v)} {len(f)} 0\n")
        np.savetxt(fh, np.asarray(v, float), fmt="%.17g")
        np.savetxt(fh, np.c_[np.full(len(f), 3), np.asarray(f, int)], fmt="%d")


def make_corpus(out: Path) -> list[Path]:
    """Write every file of :data:`DEFECTS` into ``out``; return their paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, fn in DEFECTS.items():
        v, f = fn()
        write_off(out / f"{name}.off", v, f)
        paths.append(out / f"{name}.off")
    return paths


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python tests/corpus/make_corpus.py OUTDIR")
    for p in make_corpus(Path(sys.argv[1])):
        print(p)
