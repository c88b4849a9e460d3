"""Built-in shapes for demos and tests: sphere, flat grid, rolled half-cylinder, torus.

All generators return a :class:`gromov.Mesh` with vertices in a known parametrisation,
so that tests can state facts about exact distances (great circles on the sphere,
isometry between a flat sheet and the same sheet rolled into a cylinder).
"""

from __future__ import annotations

import numpy as np

from .mesh import Mesh

__all__ = ["icosphere", "grid", "rolled_grid", "torus"]


def icosphere(subdivisions: int = 3, radius: float = 1.0) -> Mesh:
    """Unit icosahedron subdivided ``subdivisions`` times and projected on the sphere.

    ``10 * 4**subdivisions + 2`` vertices (642 for 3, 2562 for 4, 10242 for 5).
    """
    if subdivisions < 0:
        raise ValueError(f"subdivisions must be >= 0, got {subdivisions}")
    t = (1.0 + 5.0**0.5) / 2.0
    v = np.array(
        [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
         [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]],
        dtype=float,
    )
    f = np.array(
        [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]],
        dtype=np.int64,
    )
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(subdivisions):
        # one midpoint per unique edge
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        uniq, inv = np.unique(e, axis=0, return_inverse=True)
        inv = inv.reshape(3, -1).T + len(v)
        mid = v[uniq[:, 0]] + v[uniq[:, 1]]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        v = np.vstack([v, mid])
        a, b, c = f[:, 0], f[:, 1], f[:, 2]
        ab, bc, ca = inv[:, 0], inv[:, 1], inv[:, 2]
        f = np.concatenate(
            [np.stack(x, axis=1) for x in ((a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca))]
        )
    return Mesh(v * radius, f)


def _grid_faces(nu: int, nv: int, jitter_diagonals: bool) -> np.ndarray:
    idx = np.arange(nu * nv).reshape(nu, nv)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    if jitter_diagonals:
        # alternate the diagonal so the triangulation has no preferred direction
        flip = ((np.arange(nu - 1)[:, None] + np.arange(nv - 1)[None, :]) % 2 == 1).ravel()
    else:
        flip = np.zeros(a.shape, bool)
    t1 = np.where(flip[:, None], np.stack([a, b, d], 1), np.stack([a, b, c], 1))
    t2 = np.where(flip[:, None], np.stack([b, c, d], 1), np.stack([a, c, d], 1))
    return np.concatenate([t1, t2]).astype(np.int64)


def grid(nu: int = 31, nv: int = 16, width: float = np.pi, height: float = 1.0) -> Mesh:
    """Flat ``width x height`` sheet in the plane z=0, ``nu x nv`` vertices.

    Vertex ``i*nv + j`` sits at ``(width*i/(nu-1), height*j/(nv-1), 0)``.
    """
    if nu < 2 or nv < 2:
        raise ValueError(f"grid needs nu, nv >= 2, got {nu}, {nv}")
    u, w = np.meshgrid(np.linspace(0, width, nu), np.linspace(0, height, nv), indexing="ij")
    v = np.stack([u.ravel(), w.ravel(), np.zeros(u.size)], axis=1)
    return Mesh(v, _grid_faces(nu, nv, True))


def rolled_grid(nu: int = 31, nv: int = 16, width: float = np.pi, height: float = 1.0) -> Mesh:
    """The sheet of :func:`grid` rolled into a half-cylinder of radius ``width/pi``.

    Same vertex numbering and faces as :func:`grid`; the map is an isometry of the
    continuous surfaces, so intrinsic distances agree up to discretisation.
    """
    flat = grid(nu, nv, width, height)
    r = width / np.pi
    theta = flat.vertices[:, 0] / r
    v = np.stack([r * np.cos(theta), flat.vertices[:, 1], r * np.sin(theta)], axis=1)
    return Mesh(v, flat.faces)


def torus(nu: int = 48, nv: int = 24, major: float = 1.0, minor: float = 0.35) -> Mesh:
    """A closed torus (genus 1, Euler characteristic 0)."""
    if nu < 3 or nv < 3:
        raise ValueError(f"torus needs nu, nv >= 3, got {nu}, {nv}")
    a, b = np.meshgrid(np.linspace(0, 2 * np.pi, nu, endpoint=False),
                       np.linspace(0, 2 * np.pi, nv, endpoint=False), indexing="ij")
    v = np.stack([(major + minor * np.cos(b)) * np.cos(a), (major + minor * np.cos(b)) * np.sin(a),
                  minor * np.sin(b)], axis=-1).reshape(-1, 3)
    idx = np.arange(nu * nv).reshape(nu, nv)
    i0, j0 = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    p00, p10 = idx[i0, j0].ravel(), idx[(i0 + 1) % nu, j0].ravel()
    p11, p01 = idx[(i0 + 1) % nu, (j0 + 1) % nv].ravel(), idx[i0, (j0 + 1) % nv].ravel()
    f = np.concatenate([np.stack([p00, p10, p11], 1), np.stack([p00, p11, p01], 1)])
    return Mesh(v, f.astype(np.int64))
