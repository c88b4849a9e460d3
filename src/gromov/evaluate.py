"""Correspondence quality against ground truth, aware of intrinsic symmetries.

Bodies have a left/right intrinsic symmetry: the Gromov-Hausdorff distance has two
near-equal minima, the true map and its mirror. Both are fine for the distance; for
correspondence, :func:`correspondence_error` measures both readings and says which branch
the match found.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .match_result import MatchResult
from .shape_metric import ShapeMetric
from .mesh import Mesh

__all__ = ["CorrespondenceError", "correspondence_error", "image_errors", "DenseError", "dense_errors",
           "dense_error", "GeodesicReference"]


@dataclass(frozen=True, eq=False)
class CorrespondenceError:
    """Errors of the images of X's samples on Y, divided by Y's diameter in the error metric.

    Attributes
    ----------
    errors : ndarray (M,)
        Per sample, distance between the image and the ground-truth image.
    mean : float
    mirrored_errors : ndarray (M,) or None
        The same against the mirrored ground truth (when a symmetry is given).
    mirrored_mean : float or None
    branch : str
        ``"direct"`` or ``"mirrored"``: which reading fits the match better
        (``"direct"`` when no symmetry is given).
    """

    errors: np.ndarray
    mean: float
    mirrored_errors: np.ndarray | None
    mirrored_mean: float | None
    branch: str

    @property
    def best(self) -> float:
        """The mean error of the better branch."""
        return self.mean if self.mirrored_mean is None else min(self.mean, self.mirrored_mean)


def image_errors(samples, images, target: ShapeMetric, truth=None, *, name: str = "") -> np.ndarray:
    """Distance in ``target``'s metric from each image to its ground-truth image, / diameter.

    ``samples`` are input ids of the source shape, ``images`` input ids of ``target``;
    ``truth[i]`` is the target input vertex matching source input vertex ``i`` (default: the
    identity). Distances are taken between the nearest working vertices.
    """
    prefix = f"{name}: " if name else ""
    src = np.asarray(samples, dtype=np.int64)
    img = np.asarray(images, dtype=np.int64)
    if src.ndim != 1 or img.shape != src.shape:
        raise ValueError(f"{prefix}samples and images must be 1-D of equal length, "
                         f"got shapes {src.shape} and {img.shape}")
    if truth is None:
        gt = src
    else:
        truth = np.asarray(truth, dtype=np.int64)
        if src.size and (src.min() < 0 or src.max() >= len(truth)):
            raise ValueError(f"{prefix}ground truth has {len(truth)} entries, "
                             f"but a sample has input id {int(src.max())}")
        gt = truth[src]

    def near(ids):
        return target.working.from_source(target.input.from_input_ids(ids))

    return target.distances[near(img), near(gt)] / target.diameter


def correspondence_error(result: MatchResult, y: ShapeMetric, truth=None,
                         symmetry=None) -> CorrespondenceError:
    """Error of ``result``'s X -> Y images against a ground-truth map.

    Parameters
    ----------
    result : MatchResult
    y : ShapeMetric
        Y with the metric in which errors are measured (usually geodesic); distances are taken
        between the working vertices nearest to the image and to the ground-truth vertex.
    truth : array_like of int, optional
        ``truth[i]`` is the input vertex of Y matching input vertex ``i`` of X. Default: the
        identity (same vertex numbering, as within a TOSCA class).
    symmetry : array_like of int, optional
        ``symmetry[j]`` is the mirror of Y's input vertex ``j`` (0-based; e.g. from TOPKIDS
        ``*_sym.txt`` or a reflection of a symmetric reference pose).

    Returns
    -------
    CorrespondenceError
    """
    e = image_errors(result.x_samples, result.x_to_y_vertex, y, truth)
    if symmetry is None:
        return CorrespondenceError(e, float(e.mean()), None, None, "direct")
    symmetry = np.asarray(symmetry, dtype=np.int64)
    mirrored_truth = symmetry if truth is None else symmetry[np.asarray(truth, dtype=np.int64)]
    em = image_errors(result.x_samples, result.x_to_y_vertex, y, mirrored_truth)
    branch = "direct" if e.mean() <= em.mean() else "mirrored"
    return CorrespondenceError(e, float(e.mean()), em, float(em.mean()), branch)


#: Error thresholds of :func:`dense_errors`' marches, in units of sqrt(area): each march from
#: a true vertex stops at the first limit that reaches its image; the last is unlimited.
DENSE_LIMITS = (0.05, 0.25)
#: Points on which :func:`dense_error` first compares the direct and the mirrored reading.
MIRROR_PROBE = 500
#: At most this many unlimited marches per map; beyond it the errors above the last limit are
#: read off the all-pairs geodesic distances of a copy of the target simplified to
#: ``COARSE_VERTICES`` vertices (:class:`GeodesicReference`).
MAX_FULL_MARCHES = 1000
COARSE_VERTICES = 3000


class GeodesicReference:
    """Geodesic distances on a target's input mesh, for scoring maps onto it.

    Holds the fast-marching precomputation of the mesh (``fmm``) and, built on first use, a
    copy simplified to :data:`COARSE_VERTICES` vertices with all its pairwise geodesic
    distances, for errors too large to march to one by one (a grossly wrong map): there the
    error is the distance between the working vertices nearest to the image and to the truth,
    within the coarse mesh's edge length (about 2% of sqrt(area)) of the exact one.
    """

    def __init__(self, target: Mesh):
        from .metrics._fmm import FastMarching

        self.target = target
        self.fmm = FastMarching(target.vertices, target.faces)
        self._coarse = None

    def coarse(self, face: np.ndarray, bary: np.ndarray, src: np.ndarray) -> np.ndarray:
        """Coarse distances from the vertices ``src`` to the image points."""
        if self._coarse is None:
            from .metrics import metric_solver
            from .resolution import simplify

            w = simplify(self.target, min(COARSE_VERTICES, self.target.n_vertices))
            self._coarse = (w, metric_solver(w.mesh, "geodesic").pairwise())
        w, D = self._coarse
        img = self.target.faces[face, np.argmax(bary, axis=1)]
        return D[w.source_nearest[img], w.source_nearest[src]]


def dense_errors(face, bary, target: Mesh, truth, *, fmm=None) -> np.ndarray:
    r"""Geodesic distance on ``target`` between each image point and its true vertex.

    The standard measure of a dense map (Kim, Lipman & Funkhouser, SIGGRAPH 2011; the
    SHREC'16 protocol): for every vertex, :math:`d_Y(T(x), T_0(x))`, computed on the input
    mesh by fast marching from the true vertex (:class:`gromov.metrics._fmm.FastMarching`);
    at a point inside a face, the squared distances to its corners are interpolated
    barycentrically. Each march stops as soon as the distances of the image's corners are
    final, and at the latest at the first of :data:`DENSE_LIMITS` times sqrt(area) that
    covers them, so that a precise map costs a small disk per vertex.

    Parameters
    ----------
    face : ndarray (k,) of int
        Face of ``target`` holding each image (its own face numbering).
    bary : ndarray (k, 3)
        Barycentric coordinates of the image.
    target : Mesh
        The target's input mesh.
    truth : ndarray (k,) of int
        The true image of each point: a vertex of ``target`` as a file id.
    fmm : GeodesicReference, optional
        Of ``target``, to reuse its precomputation across maps.

    Returns
    -------
    ndarray (k,)
        Absolute geodesic errors (inf where the image lies on a component the truth's
        cannot reach). Errors above the last limit are marched exactly when at most
        :data:`MAX_FULL_MARCHES` points have them, else read off a coarse copy of the target
        (:class:`GeodesicReference`).
    """
    face = np.asarray(face, dtype=np.int64)
    bary = np.asarray(bary, dtype=np.float64)
    k = len(face)
    if face.ndim != 1 or bary.shape != (k, 3):
        raise ValueError(f"face and bary must be (k,) and (k, 3), got {face.shape} and {bary.shape}")
    if k and (face.min() < 0 or face.max() >= target.n_faces):
        raise ValueError(f"face ids must be in [0, {target.n_faces}), got {int(face.min())}..{int(face.max())}")
    src = target.from_input_ids(np.asarray(truth, dtype=np.int64))
    if src.shape != (k,) or (k and src.min() < 0):
        raise ValueError(f"truth must hold {k} vertex ids of the target")
    ref = GeodesicReference(target) if fmm is None else fmm
    corners = target.faces[face]
    err = np.full(k, np.inf)
    todo = np.arange(k)
    scale = float(np.sqrt(target.area))
    for limit in (*DENSE_LIMITS, np.inf):
        if not todo.size:
            break
        if limit == np.inf and todo.size > MAX_FULL_MARCHES:
            err[todo] = ref.coarse(face[todo], bary[todo], src[todo])
            break
        d = ref.fmm.distances_to(src[todo], corners[todo], limit=limit * scale)
        done = np.isfinite(d).all(axis=1) | (limit == np.inf)
        # a corner of weight 0 adds nothing, even unreached (0 x inf would be NaN)
        b = bary[todo[done]]
        err[todo[done]] = np.sqrt((b * np.where(b > 0, d[done], 0.0) ** 2).sum(axis=1))
        todo = todo[~done]
    return err


@dataclass(frozen=True, eq=False)
class DenseError:
    """Errors of a dense map against a ground truth, in the field's units.

    Attributes
    ----------
    errors : ndarray (k,)
        Per point, geodesic error divided by sqrt(area of the target) (the better of the
        direct and the mirrored ground truth, when a symmetry is given: ``branch``).
    direct : ndarray (k,)
        The same against the direct ground truth only.
    area, diameter : float
        The target's area and geodesic diameter (of its vertices' distances, from the
        farthest vertex of a far vertex), for the other unit: ``errors * sqrt(area) / diameter``.
    branch : str
        ``"direct"`` or ``"mirrored"``.
    """

    errors: np.ndarray
    direct: np.ndarray
    area: float
    diameter: float
    branch: str

    @property
    def mean(self) -> float:
        return float(np.mean(self.errors))

    @property
    def mean_direct(self) -> float:
        return float(np.mean(self.direct))

    def curve(self, thresholds=None) -> tuple[np.ndarray, np.ndarray]:
        """Cumulative curve: fraction of points with error <= e, for e in 0..0.25 (51 values)."""
        t = np.linspace(0.0, 0.25, 51) if thresholds is None else np.asarray(thresholds, dtype=float)
        return t, (self.errors[None, :] <= t[:, None]).mean(axis=1)

    def per_diameter(self) -> np.ndarray:
        """The errors divided by the target's geodesic diameter instead (the paper's unit)."""
        return self.errors * np.sqrt(self.area) / self.diameter


def _diameter(target: Mesh, ref: GeodesicReference) -> float:
    """Geodesic diameter by a double sweep (the farthest vertex from the farthest vertex of
    vertex 0's component), a lower bound within a few percent on bodies."""
    d = ref.fmm.distance([0])
    far = int(np.argmax(np.where(np.isfinite(d), d, -1.0)))
    d = ref.fmm.distance([far])
    return float(np.max(d[np.isfinite(d)]))


def _errors_at_least(face, bary, target: Mesh, truth, fmm: GeodesicReference) -> np.ndarray:
    """Lower bounds of :func:`dense_errors` / sqrt(area), from marches stopped at the last of
    :data:`DENSE_LIMITS`: a corner not reached is farther than the limit, and the error grows
    with each corner's distance. Exact where all three corners are reached (the same formula);
    for at most :data:`MAX_FULL_MARCHES` points, whose errors are all marched."""
    scale = float(np.sqrt(target.area))
    limit = DENSE_LIMITS[-1] * scale
    src = target.from_input_ids(np.asarray(truth, dtype=np.int64))
    d = fmm.fmm.distances_to(src, target.faces[face], limit=limit)
    return np.sqrt((bary * np.minimum(d, limit) ** 2).sum(axis=1)) / scale


def dense_error(face, bary, target: Mesh, truth, symmetry=None, *, fmm=None) -> DenseError:
    """:func:`dense_errors` divided by sqrt(area), against the direct ground truth and, given a
    ``symmetry`` of the target (file ids, -1 where none), against the mirrored one; the
    branch with the lower mean is reported (:class:`DenseError`). The mirrored reading is
    measured in full only when it has the lower mean on ``MIRROR_PROBE`` points drawn with a
    fixed seed (a mirrored map's errors are all far: each a march over much of the mesh); the
    probe itself first bounds those errors from below by marches stopped at the last of
    :data:`DENSE_LIMITS`, and marches on only where the bound leaves the question open.

    ``truth`` are file ids of ``target``'s vertices, one per image.
    """
    fmm = GeodesicReference(target) if fmm is None else fmm
    scale = float(np.sqrt(target.area))
    direct = dense_errors(face, bary, target, truth, fmm=fmm) / scale
    errors, branch = direct, "direct"
    if symmetry is not None:
        sym = np.asarray(symmetry, dtype=np.int64)
        t = np.asarray(truth, dtype=np.int64)
        mt = sym[t]
        mt = np.where(mt < 0, t, mt)
        # the mirrored reading in full only if it fits better on a seeded subset of the points
        probe = np.sort(np.random.default_rng(0).permutation(len(t))[:MIRROR_PROBE])
        bar = direct[probe].mean()
        bounded = len(probe) <= MAX_FULL_MARCHES   # its errors all marched: the bound holds
        if ((not bounded or _errors_at_least(face[probe], bary[probe], target, mt[probe], fmm).mean() < bar)
                and (dense_errors(face[probe], bary[probe], target, mt[probe], fmm=fmm) / scale).mean() < bar):
            mirrored = dense_errors(face, bary, target, mt, fmm=fmm) / scale
            if mirrored.mean() < direct.mean():
                errors, branch = mirrored, "mirrored"
    return DenseError(errors, direct, float(target.area), _diameter(target, fmm), branch)
