r"""``gromov reproduce``: the experiments of Bronstein et al. (IJCV 2010, §5) end to end.

Bronstein, Bronstein, Mahmoudi, Kimmel & Sapiro, "A Gromov-Hausdorff framework with
diffusion geometry for topologically-robust non-rigid shape matching", IJCV 89 (2010).

What runs (:func:`reproduce`):

1. **Shapes.** The subsets of Experiment 1 (each deformation clean and welded at
   :data:`~gromov.experiments.datasets.WELD_COUNT` places) and Experiment 2 (each
   deformation with 10 and 20 holes), from TOSCA or from the built-in synthetic set.
   Every pose of a class is brought to the working resolution *identically*
   (:meth:`gromov.WorkingMesh.transfer` of the reference pose), so vertex ``i`` is the same
   point in every pose, and the topological noise is put on that working mesh; every mesh
   keeps the file's vertex numbering in ``input_ids``, so the ground truth is the identity.
2. **Recognition.** For each experiment and metric (geodesic, diffusion), the pairwise GH
   matrix (each shape's metric once, pairs in parallel), the ROC and equal error rate over
   all pairs (positives: same class), nearest-neighbour accuracy, MDS maps.
3. **Correspondence.** The matches of each class's reference pose with its deformations,
   clean, welded and with holes -- from the same runs for the geodesic metric; for the
   heat-kernel diffusion metric matched again with normalised heat distributions
   (:func:`gromov.metrics.diffusion.correspondence_options`: each task its own units,
   chosen on the validation sets; the recognition metric's own maps are reported beside
   them as ``recognition_metric``) -- and the paper's :math:`d(C, C_0)`, measured
   in the *geodesic* metric of the *clean* shapes for both matching metrics (so a weld's
   shortcut cannot make an error look small, and the two metrics are judged by the same
   ruler), divided by the clean shape's geodesic diameter. Bodies are left/right symmetric:
   both the direct and the mirrored ground truth are measured (the mirror of the reference
   pose through its best axis-aligned plane) and ``best`` counts the mirrored map as
   correct; both are reported.
4. **TOPKIDS** (when the data is there): kid01..kid25 matched to kid00 with the given
   ground truth (SHREC'16 protocol: errors of the images of kidXX's samples on kid00,
   geodesic on kid00, symmetric map of kid00 for the mirrored reading), and how the GH
   estimate to kid00 grows with the number of handles (Spearman correlation).
5. ``results.json``, PNG figures and a self-contained ``index.html`` report
   (:mod:`gromov.experiments.report`).
"""

from __future__ import annotations

import json
import logging
import platform
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .. import perturb as _perturb
from .._atomic import atomic_folder, atomic_write_text
from .._defaults import RANK_RESIDUAL, RANK_TAU_SCALE
from .._json import finite
from ..errors import GromovError
from ..gh import check_rank_residual, check_rank_tau_scale
from ..mesh import Mesh
from ..metrics import DIFFUSION_FILL_HOLES, metric_solver
from ..metrics.diffusion import correspondence_options
from ..resolution import WorkingMesh, simplify
from ..shape_metric import ShapeMetric
from . import datasets
from .pairwise import available_cpus, gh_matrix, match_pairs, prepare
from .recognition import (LOCAL_SCALING_K, errors_at, local_roc, mds_map, plot_mds, plot_roc, roc,
                          smallest_class)

__all__ = ["Settings", "settings_for", "reproduce", "reflection_map", "environment", "METRICS", "RESULT_KEYS",
           "RANK_BY"]

logger = logging.getLogger(__name__)

METRICS = ("geodesic", "diffusion")
"""The two metrics compared by every experiment."""

RANK_BY = ("trimmed", "gh")
"""What recognition ranks pairs of shapes by: the trimmed distortion of the GH correspondence
(:attr:`gromov.MatchResult.relative_trimmed`; the default, chosen on the synthetic set and the
held-out TOSCA classes) or the GH estimate itself (``relative_distance``). Both EERs are in
``results.json`` either way."""

RESULT_KEYS = (
    "eer.weld.geodesic", "eer.weld.diffusion", "eer.holes.geodesic", "eer.holes.diffusion",
    "correspondence.geodesic.clean", "correspondence.geodesic.weld",
    "correspondence.diffusion.clean", "correspondence.diffusion.weld",
)
"""Keys of ``results.json`` other tools read; each is both a nested path and a flat key."""


# ----------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class Settings:
    """What one run of :func:`reproduce` computes.

    Attributes
    ----------
    dataset : {"tosca", "synthetic"}
    quick : bool
    resolution : int or None
        Working mesh size (None: the meshes as they are).
    n_samples : int
        Farthest point samples per shape for every match.
    experiment1, experiment2 : dict of str to int
        Classes and number of deformations per class.
    topkids : int
        TOPKIDS shapes matched to kid00 (0: none).
    seed : int
        Sampling seed of every match (perturbation seeds are fixed per entry).
    metric_options : dict
        Per metric, options for :func:`gromov.metric_solver`: the recognition's.
    correspondence_options : dict
        Per metric, the options the correspondence (d(C, C0), TOPKIDS) is computed with
        (:func:`gromov.metrics.diffusion.correspondence_options` of ``metric_options``); where
        they differ from ``metric_options``, the correspondence pairs are matched again with
        them.
    rank_by : {"trimmed", "gh"}
        What recognition ranks pairs by (:data:`RANK_BY`).
    rank_tau_scale : float or None
        The trimmed ranking measures each diffusion correspondence with the heat distance at
        this times the diffusion time (:data:`gromov.gh.RANK_TAU_SCALE`; None: in the metric
        of the match).
    rank_residual : {"log", "difference"}
        The trimmed ranking's residuals: log ratios of corresponding distances or their
        differences (:data:`gromov.gh.RANK_RESIDUAL`).
    local_scaling : int
        The neighbour of :func:`gromov.experiments.recognition.local_scaling` for the EER of
        the locally scaled ranking, reported beside the EER (``eer_local``; capped at the
        number of shapes less one).
    """

    dataset: str
    quick: bool
    resolution: int | None
    n_samples: int
    experiment1: dict
    experiment2: dict
    topkids: int
    seed: int = 0
    metric_options: dict = field(default_factory=lambda: {m: {} for m in METRICS})
    rank_by: str = "trimmed"
    correspondence_options: dict = field(default_factory=lambda: {m: {} for m in METRICS})
    rank_tau_scale: float | None = RANK_TAU_SCALE
    rank_residual: str = RANK_RESIDUAL
    local_scaling: int = LOCAL_SCALING_K

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def settings_for(dataset: str, quick: bool = False, *, seed: int = 0, classes: dict | None = None,
                 topkids: bool = True) -> Settings:
    """The settings of a run: the paper's subsets on TOSCA, a smaller set when ``quick``.

    ``classes`` (TOSCA only) replaces the paper's classes: class name to the number of
    deformations in Experiment 1; Experiment 2 takes ``min(2, n)`` of them (1 when
    ``quick``, and ``quick`` caps Experiment 1 at 2). ``topkids=False``: no TOPKIDS part.

    ======================  ==========  =======  ========================  ============  =======
    run                     resolution  samples  Exp. 1 deformations       Exp. 2        TOPKIDS
    ======================  ==========  =======  ========================  ============  =======
    TOSCA                   3000        100      cat 2, dog 4, male 6,     2 per class   25
                                                 female 6 (paper)
    TOSCA ``--quick``       3000        100      2 per class               1 per class   5
    synthetic               as built    50       2 per class               1 per class   --
    synthetic ``--quick``   800         30       1 per class               1 per class   --
    ======================  ==========  =======  ========================  ============  =======
    """
    if dataset == "tosca":
        if classes is not None:
            classes = _check_classes(classes)
            e1 = {c: min(n, 2) if quick else n for c, n in classes.items()}
            e2 = {c: 1 if quick else min(n, 2) for c, n in classes.items()}
        else:
            e1 = {c: 2 for c in datasets.EXPERIMENT1_CLASSES} if quick else dict(datasets.EXPERIMENT1_CLASSES)
            e2 = {c: 1 for c in datasets.EXPERIMENT2_CLASSES} if quick else dict(datasets.EXPERIMENT2_CLASSES)
        return Settings("tosca", quick, 3000, 100, e1, e2, (5 if quick else 25) if topkids else 0, seed)
    if classes is not None:
        raise ValueError("classes apply to TOSCA data only (the synthetic set has its own classes)")
    if dataset == "synthetic":
        from .synthetic import Synthetic

        classes = list(Synthetic().classes)
        if quick:
            return Settings("synthetic", True, 800, 30, {c: 1 for c in classes}, {c: 1 for c in classes},
                            0, seed)
        return Settings("synthetic", False, None, 50, {c: 2 for c in classes}, {c: 1 for c in classes},
                        0, seed)
    raise ValueError(f"dataset must be 'tosca' or 'synthetic', got {dataset!r}")


def _check_classes(classes: dict) -> dict:
    if not isinstance(classes, dict) or not classes:
        raise ValueError(f"classes must be a non-empty dict of class name to number of deformations, "
                         f"got {classes!r}")
    out = {}
    for c, n in classes.items():
        if not isinstance(c, str) or isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"classes: each class needs a name and a positive number of "
                             f"deformations, got {c!r}: {n!r}")
        out[c] = int(n)
    if len(out) < 2:
        raise ValueError(f"recognition needs at least two classes, got {sorted(out)}")
    return out


# ----------------------------------------------------------------------------- helpers
def reflection_map(mesh: Mesh) -> np.ndarray:
    """Mirror of every vertex through the best axis-aligned plane of the bounding box.

    TOSCA reference poses (and the synthetic ones) are left/right symmetric about a plane
    through the bounding box's centre, perpendicular to a coordinate axis: reflect the
    vertices through each of the three planes and keep the one whose reflection lands
    closest to the surface (mean distance to the nearest vertex). A mesh in several pieces
    (a body with separate eyes or teeth) maps each piece onto one piece, the one most of its
    reflected vertices land nearest (the body onto the body, a left eye onto the right eye):
    a body vertex whose reflection passes near an eye is not sent onto the eye.

    Returns
    -------
    ndarray of int64, shape (n_vertices,)
        Input id (``mesh.input_ids``) of the mirror of the vertex with each input id;
        ``-1`` for ids that are not vertices of ``mesh`` (:meth:`Mesh.per_file_vertex`).
    """
    from scipy.spatial import cKDTree

    v = mesh.vertices
    centre = 0.5 * (v.min(0) + v.max(0))
    tree = cKDTree(v)
    best = None
    for axis in range(3):
        r = v.copy()
        r[:, axis] = 2 * centre[axis] - r[:, axis]
        d, idx = tree.query(r)
        if best is None or d.mean() < best[0]:
            best = (d.mean(), idx, r)
    idx, r = best[1].copy(), best[2]
    labels = mesh.component_labels
    if mesh.n_components > 1:
        for c in np.unique(labels):
            own = np.flatnonzero(labels == c)
            onto = int(np.bincount(labels[idx[own]]).argmax())
            if np.any(labels[idx[own]] != onto):
                there = np.flatnonzero(labels == onto)
                idx[own] = there[cKDTree(v[there]).query(r[own])[1]]
    return mesh.per_file_vertex(mesh.input_ids[idx])


def _weld(work: Mesh, count: int, seed: int, join: str = "pinch"):
    """Weld ``count`` places, relaxing the search when a pose has too few close parts.

    ``join``: how the two places are glued (:func:`gromov.perturb.weld`): ``"pinch"`` merges
    the two vertices (the paper's welded vertices), ``"tube"`` joins their 1-rings by a handle.

    The default search radius is 5 mean edge lengths and a weld needs the geodesic distance
    to be 4 times the Euclidean one; a pose whose parts do not come that close gets a
    larger radius (x1.5 up to four times), then a ratio of 2, then fewer welds. What was
    used is returned so the report can say it.
    """
    edge = work.mean_edge_length
    for ratio in (4.0, 2.0):
        for k in range(count, 0, -1):
            radius = 5 * edge
            for _ in range(5):
                try:
                    p = _perturb.weld(work, k, radius=radius, seed=seed, min_geodesic_ratio=ratio,
                                     join=join, resolution=None)
                except ValueError:
                    radius *= 1.5
                    continue
                return p, {"welds": k, "join": join, "radius_edges": round(radius / edge, 2),
                          "min_geodesic_ratio": ratio}
    raise GromovError(f"no place to weld on a mesh of {work.n_vertices} vertices")


@dataclass
class _Shape:
    label: str
    cls: str
    pose: int
    kind: str            # "clean", "weld", "holes"
    mesh: Mesh           # working mesh with the noise; input_ids = the file's numbering
    info: dict


def _collection(dataset: str, data: Path | None, pose_stretch: float = 0.0):
    if dataset == "tosca":
        return datasets.TOSCA(Path(data) / "tosca")
    from .synthetic import Synthetic

    return Synthetic(pose_stretch=pose_stretch)


class _Shapes:
    """Working meshes per (class, pose), made once; perturbed shapes per entry.

    ``weld_join``: how welds glue (:data:`gromov.perturb.WELD_JOINS`, :func:`gromov.perturb.weld`).
    ``store``: a :class:`gromov.store.ShapeStore` that keeps each shape's metrics and the rows
    of the geodesic ground truth (:meth:`geodesic`, :meth:`save_rows`) between runs, or None.
    """

    def __init__(self, collection, resolution, weld_join: str = "pinch", store=None):
        self.collection = collection
        self.resolution = resolution
        self.weld_join = weld_join
        self.store = store
        self.working: dict[tuple[str, int], WorkingMesh] = {}
        self.mirror: dict[str, np.ndarray] = {}
        self.shapes: dict[str, _Shape] = {}
        self.diameters: dict[tuple[str, int], float] = {}
        self.solvers: dict[tuple[str, int], object] = {}
        # shapes two experiments share (the clean ones): metrics and GH pairs computed once
        self.shared: set[str] = set()
        self.prepared: dict[tuple[str, str], ShapeMetric] = {}
        self.pairs: dict[tuple[str, str, str], tuple] = {}

    def work(self, cls: str, pose: int) -> WorkingMesh:
        key = (cls, pose)
        if key not in self.working:
            if (cls, 0) not in self.working:
                ref = self.collection.load(cls, 0)
                n = ref.n_vertices if self.resolution is None else min(self.resolution, ref.n_vertices)
                self.working[cls, 0] = simplify(ref, n)
                self.mirror[cls] = reflection_map(ref)
            if pose != 0:
                self.working[key] = self.working[cls, 0].transfer(self.collection.load(cls, pose))
        return self.working[key]

    def entry(self, e: datasets.Entry) -> _Shape:
        if e.label in self.shapes:
            return self.shapes[e.label]
        clean = self.work(e.cls, e.pose).mesh
        if e.perturbation is None:
            s = _Shape(e.label, e.cls, e.pose, "clean", clean, {"euler": clean.euler_characteristic})
        else:
            kind, count = e.perturbation
            if kind == "weld":
                p, info = _weld(clean, count, e.seed, self.weld_join)
            else:
                p = _perturb.holes(clean, count, seed=e.seed)
                info = {"holes": count}
            info.update(seed=e.seed, euler_before=p.euler_before, euler_after=p.euler_after,
                        boundary_loops_after=p.boundary_loops_after)
            s = _Shape(e.label, e.cls, e.pose, kind, p.mesh, info)
        self.shapes[e.label] = s
        return s

    def geodesic(self, cls: str, pose: int):
        """Geodesic solver on the clean working mesh, one per shape (not per pair), its rows
        cached (:class:`_CachedRows`)."""
        if (cls, pose) not in self.solvers:
            mesh = self.work(cls, pose).mesh
            self.solvers[cls, pose] = _stored_rows(self.store, mesh, metric_solver(mesh, "geodesic"))
        return self.solvers[cls, pose]

    def save_rows(self) -> None:
        """Keep the ground truth's new geodesic rows in the store (:func:`_save_rows`)."""
        for rows in self.solvers.values():
            _save_rows(self.store, rows)

    def diameter(self, cls: str, pose: int) -> float:
        """Geodesic diameter of the clean working mesh (largest of all pairwise distances).

        Recorded from the geodesic recognition pass when the clean shape is in it, else computed.
        """
        key = (cls, pose)
        if key not in self.diameters:
            self.diameters[key] = float(np.max(self.geodesic(cls, pose).pairwise()))
        return self.diameters[key]


class _CachedRows:
    """A metric solver whose rows (``from_sources``) are each computed once.

    The correspondence errors ask for the rows of the same ground-truth vertices many times
    (every variant of a pose, both metrics, direct and mirrored): a row of the fast marching
    does not depend on the other sources of its call, so the cached row is the same number."""

    def __init__(self, solver):
        self.solver = solver
        self.rows: dict[int, np.ndarray] = {}
        self.key: str | None = None   # with a store: the key its rows are kept under
        self.n_stored = 0             # rows read from (or written to) the store

    def pairwise(self):
        return self.solver.pairwise()

    def from_sources(self, sources) -> np.ndarray:
        sources = np.asarray(sources, dtype=np.int64).ravel().tolist()
        if not sources:
            return np.empty((0, self.solver.n_vertices))
        missing = np.array(sorted(set(sources) - self.rows.keys()), dtype=np.int64)
        if missing.size:
            self.rows.update(zip(missing.tolist(), self.solver.from_sources(missing)))
        return np.stack([self.rows[v] for v in sources])

    def between(self, sources, targets) -> np.ndarray:
        """``d(sources[i], targets[i])`` for each ``i``: from a cached row where there is one,
        else by fast marches stopped once their targets are final
        (:meth:`FastMarching.distances_to <gromov.metrics._fmm.FastMarching.distances_to>`, the
        same values as the rows); no row is kept. A solver other than the fast marching gives
        its rows."""
        sources = np.asarray(sources, dtype=np.int64).ravel()
        targets = np.asarray(targets, dtype=np.int64).ravel()
        solver = self.solver
        if not (getattr(solver, "method", None) == "fmm" and not solver.refine):
            return self.from_sources(sources)[np.arange(len(sources)), targets]
        out = np.empty(len(sources))
        cached = np.array([v in self.rows for v in sources.tolist()], dtype=bool)
        for i in np.flatnonzero(cached):
            out[i] = self.rows[int(sources[i])][targets[i]]
        todo = np.flatnonzero(~cached)
        if todo.size:
            uniq, inv = np.unique(sources[todo], return_inverse=True)
            # each source's targets in one row, padded with its first target
            order = np.argsort(inv, kind="stable")
            counts = np.bincount(inv, minlength=len(uniq))
            first = np.concatenate([[0], np.cumsum(counts)[:-1]])
            slot = np.arange(len(todo)) - np.repeat(first, counts)
            grid = np.repeat(targets[todo][order][first][:, None], counts.max(), axis=1)
            grid[inv[order], slot] = targets[todo][order]
            d = solver._engine().distances_to(uniq, grid)
            out[todo[order]] = d[inv[order], slot]
        return out


#: Name of the geodesic ground truth's rows in a store (:meth:`gromov.store.ShapeStore.put_extra`).
ROWS_EXTRA = "ground_truth_geodesic_rows"


def _rows_checksum(sources: np.ndarray, rows: np.ndarray) -> str:
    import hashlib

    h = hashlib.sha256(np.ascontiguousarray(sources, dtype=np.int64).tobytes())
    h.update(np.ascontiguousarray(rows, dtype=np.float64).tobytes())
    return h.hexdigest()


def _stored_rows(store, mesh: Mesh, solver) -> _CachedRows:
    """:class:`_CachedRows` of ``solver`` (the geodesic metric of ``mesh``), with the rows a
    store kept for that mesh (under the key of its geodesic entry, :data:`ROWS_EXTRA`) in
    place. Rows that do not match their checksum or the mesh are logged and computed again."""
    cached = _CachedRows(solver)
    if store is None:
        return cached
    cached.key = store.key_for(mesh, "geodesic", resolution=None, metric_options={})
    kept = store.extra(cached.key, ROWS_EXTRA)
    if kept is None:
        return cached
    sources, rows = kept.get("sources"), kept.get("rows")
    if (sources is None or rows is None or rows.shape != (len(sources), solver.n_vertices)
            or str(kept.get("checksum")) != _rows_checksum(sources, rows)):
        logger.warning("store %s: the geodesic rows kept for a mesh of %d vertices are damaged; they "
                       "are computed again", store.root, solver.n_vertices)
        return cached
    cached.rows.update(zip(sources.tolist(), rows))
    cached.n_stored = len(cached.rows)
    return cached


def _save_rows(store, cached: _CachedRows) -> None:
    """Keep ``cached``'s rows in the store where rows were added since they were read."""
    if store is None or cached.key is None or len(cached.rows) == cached.n_stored:
        return
    sources = np.array(sorted(cached.rows), dtype=np.int64)
    rows = np.stack([cached.rows[v] for v in sources.tolist()])
    store.put_extra(cached.key, ROWS_EXTRA, {"sources": sources, "rows": rows,
                                             "checksum": np.array(_rows_checksum(sources, rows))})
    cached.n_stored = len(sources)


def _geodesic_errors(w: WorkingMesh, solver, images, truth) -> np.ndarray:
    """Geodesic distance (``solver`` on ``w.mesh``) between image and truth (file ids)."""
    def near(ids):
        return w.from_source(w.source.from_input_ids(ids))

    a, b = near(images), near(truth)
    if isinstance(solver, _CachedRows):
        return solver.between(b, a)
    uniq, inv = np.unique(b, return_inverse=True)
    rows = solver.from_sources(uniq)
    return rows[inv, a]


def _pair_quality(result, shapes: _Shapes, x: _Shape, y: _Shape) -> dict:
    """d(C, C0) of one match, direct and mirrored, measured on the clean shapes."""
    wx, wy = shapes.work(x.cls, x.pose), shapes.work(y.cls, y.pose)
    dx, dy = shapes.diameter(x.cls, x.pose), shapes.diameter(y.cls, y.pose)
    sym = shapes.mirror[x.cls]
    out = {}
    for name, tx, ty in (("direct", result.x_samples, result.y_samples),
                         ("mirrored", sym[result.x_samples], sym[result.y_samples])):
        tx = np.where(tx < 0, result.x_samples, tx)
        ty = np.where(ty < 0, result.y_samples, ty)
        exy = _geodesic_errors(wy, shapes.geodesic(y.cls, y.pose), result.x_to_y_vertex, tx) / dy
        eyx = _geodesic_errors(wx, shapes.geodesic(x.cls, x.pose), result.y_to_x_vertex, ty) / dx
        out[name] = 0.5 * (float(exy.mean()) + float(eyx.mean()))
    out["best"] = min(out["direct"], out["mirrored"])
    out["branch"] = "direct" if out["direct"] <= out["mirrored"] else "mirrored"
    return out


def _dense_quality(result, shapes: _Shapes, x: _Shape, y: _Shape) -> dict:
    """A dense map's errors X -> Y on the clean Y (geodesic between image and true vertex, as
    :func:`_pair_quality`), x 100 / sqrt(area) and / diameter; the better of the direct and the
    mirrored reading."""
    wy = shapes.work(y.cls, y.pose)
    img = result.x_to_y_dense_vertex
    ids = np.flatnonzero(img >= 0)          # X's vertices (file ids) with an image
    sym = shapes.mirror[x.cls][ids]
    geo = shapes.geodesic(y.cls, y.pose)
    direct = _geodesic_errors(wy, geo, img[ids], ids)
    mirrored = _geodesic_errors(wy, geo, img[ids], np.where(sym < 0, ids, sym))
    best = direct if direct.mean() <= mirrored.mean() else mirrored
    unit = 100.0 / np.sqrt(wy.mesh.area)
    return {"mean": float(best.mean() * unit), "direct": float(direct.mean() * unit),
            "per_diameter": float(best.mean() / shapes.diameter(y.cls, y.pose))}


def _versions() -> dict:
    from importlib import metadata

    out = {"python": platform.python_version(), "platform": platform.platform()}
    for dist in ("gromov", "numpy", "scipy", "numba", "potpourri3d", "robust-laplacian",
                 "fast-simplification", "POT", "matplotlib"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = None
    return out


def environment() -> dict:
    """The machine a run's floating point depends on, recorded beside the versions.

    Bit-identical results hold on one machine for one seed; across machines the CPU's
    kernels (the BLAS's for its architecture, numba's for its instruction set) sum in other
    orders and results agree to a tolerance (docs/design/reproduction.md, "What is
    reproducible").

    Returns
    -------
    dict
        ``cpu`` (the model name, None where unknown), ``machine`` (``platform.machine()``),
        ``cpus`` (the CPUs this process may use), ``numba_cpu`` (the CPU numba compiles for)
        and ``blas``: one entry per BLAS or OpenMP library loaded (threadpoolctl's
        ``threadpool_info()``: ``user_api``, ``internal_api``, ``version``, ``architecture``,
        ``threading_layer``, ``num_threads`` and the library's file name, without its folder).
    """
    from threadpoolctl import threadpool_info

    blas = [{**{k: info.get(k) for k in ("user_api", "internal_api", "version", "architecture",
                                          "threading_layer", "num_threads")},
             "file": Path(info["filepath"]).name if info.get("filepath") else None}
            for info in threadpool_info()]
    try:
        from llvmlite import binding
        from numba.core import config

        numba_cpu = config.CPU_NAME or binding.get_host_cpu_name()
    except ImportError:  # pragma: no cover - numba is a dependency
        numba_cpu = None
    return {"cpu": _cpu_model(), "machine": platform.machine(), "cpus": available_cpus(),
            "numba_cpu": numba_cpu, "blas": blas}


def _cpu_model() -> str | None:
    """The CPU's model name: /proc/cpuinfo's ``model name`` (Linux), else
    ``platform.processor()``; None where neither says."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or None


def _say(msg: str, quiet: bool) -> None:
    if not quiet:
        print(msg, file=sys.stderr, flush=True)


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


# ----------------------------------------------------------------------------- recognition
def _recognition(name: str, entries, shapes: _Shapes, st: Settings, jobs: int, out: Path,
                 quiet: bool, timings: dict, matches: dict) -> dict:
    """Pairwise GH matrices of one experiment for both metrics, ROC/EER, MDS figures.

    Shapes in ``shapes.shared`` (in both experiments) keep their prepared metric and their
    GH pairs for the other experiment, which does not compute them again (same shapes, same
    order, same options: the same numbers)."""
    items = [shapes.entry(e) for e in entries]
    labels = np.array([s.cls for s in items])
    perturbed = np.array([s.kind != "clean" for s in items])
    keep = _correspondence_pairs(items)
    rec = {"entries": [s.label for s in items], "classes": list(dict.fromkeys(labels.tolist())),
           "labels": labels.tolist(), "perturbed": perturbed.tolist(),
           "smallest_class": smallest_class(labels),
           "shapes": {s.label: s.info for s in items}}
    curves = {}
    for metric in METRICS:
        t = time.perf_counter()
        sources = [shapes.prepared.get((metric, s.label), s.mesh) for s in items]
        if shapes.store is not None:   # each shape's metric read back, or computed and kept
            sources = shapes.store.shapes(sources, metric, resolution=None,
                                          metric_options=st.metric_options[metric],
                                          rank_tau_scale=st.rank_tau_scale, progress=not quiet)
        prepared = prepare(sources, metric, n_samples=st.n_samples, seed=st.seed, resolution=None,
                           metric_options=st.metric_options[metric], progress=not quiet,
                           rank_tau_scale=st.rank_tau_scale, jobs=jobs)   # in metrics_s, as per-shape work
        for s, sm in zip(items, prepared):
            if s.label in shapes.shared:
                shapes.prepared[metric, s.label] = sm
        known = {(i, j): shapes.pairs[metric, items[i].label, items[j].label]
                 for i in range(len(items)) for j in range(i + 1, len(items))
                 if (metric, items[i].label, items[j].label) in shapes.pairs}
        if metric == "geodesic":   # the clean shapes' diameters, for the correspondence errors
            for s, sm in zip(items, prepared):
                if s.kind == "clean":
                    shapes.diameters.setdefault((s.cls, s.pose), sm.diameter)
        timings[f"{name}.{metric}.metrics_s"] = round(time.perf_counter() - t, 2)
        r = gh_matrix(prepared, metric, n_samples=st.n_samples, seed=st.seed, jobs=jobs,
                      progress=not quiet, keep=keep, known=known, rank_tau_scale=st.rank_tau_scale,
                      rank_residual=st.rank_residual, store=shapes.store)
        for i in range(len(items)):
            for j in range(i + 1, len(items)):
                if items[i].label in shapes.shared and items[j].label in shapes.shared:
                    shapes.pairs[metric, items[i].label, items[j].label] = (
                        r.distance[i, j], r.relative[i, j], r.trimmed[i, j], r.results.get((i, j)))
        timings[f"{name}.{metric}.pairs_s"] = round(r.seconds_match, 2)
        ranking = {"trimmed": r.trimmed, "gh": r.relative}
        rocs = {k: roc(m, labels) for k, m in ranking.items()}
        D, curve = ranking[st.rank_by], rocs[st.rank_by]
        curves[metric] = curve
        # beside the EER; the synthetic set's Experiment 2 has classes of 3 (recorded, no warning)
        curve_local, D_local, k_local = local_roc(D, labels, st.local_scaling, warn=False)
        mask = perturbed[:, None] | perturbed[None, :]
        nn = labels[np.argmin(D + np.diag(np.full(len(items), np.inf)), axis=1)]
        rec[metric] = {
            "eer": float(curve.eer),
            "ranked_by": st.rank_by,
            "eer_gh": float(rocs["gh"].eer),
            "eer_trimmed": float(rocs["trimmed"].eer),
            "eer_perturbed_pairs": float(roc(D, labels, mask=mask).eer) if perturbed.any() else None,
            "nn_accuracy": float(np.mean(nn == labels)),
            "errors_at_eer": errors_at(D, labels, curve.eer_threshold),
            "eer_local": float(curve_local.eer),
            "local_scaling_k": k_local,
            "errors_at_eer_local": errors_at(D_local, labels, curve_local.eer_threshold),
            "confusions": [f"{items[i].label}->{nn[i]}" for i in range(len(items)) if nn[i] != labels[i]],
            "relative": r.relative.round(9).tolist(),
            "trimmed": r.trimmed.round(9).tolist(),
            "seconds": round(time.perf_counter() - t, 2),
        }
        for (i, j), res in r.results.items():
            matches[metric, items[i].label, items[j].label] = res
        coords = mds_map(D, 2, seed=st.seed)
        f = f"mds_{name}_{metric}.png"
        plot_mds(coords, labels, out / f, marked=perturbed, marked_label=name,
                 title=f"MDS, {metric}, {'Experiment 1 (welds)' if name == 'weld' else 'Experiment 2 (holes)'}"
                       f"{', trimmed distortion' if st.rank_by == 'trimmed' else ''}")
        rec.setdefault("figures", {})[f"mds_{name}_{metric}"] = f
        _say(f"  {name}/{metric}: EER {curve.eer:.3f}, nearest-neighbour accuracy "
             f"{rec[metric]['nn_accuracy']:.3f} ({time.perf_counter() - t:.0f} s)", quiet)
    f = f"roc_{name}.png"
    plot_roc(curves, out / f, title="ROC, " + ("Experiment 1 (welds)" if name == "weld" else "Experiment 2 (holes)"))
    rec["figures"][f"roc_{name}"] = f
    return rec


#: Metrics whose correspondence matches also get dense maps, scored (the default metric: the
#: map a user gets).
DENSE_METRICS = ("diffusion",)


def _correspondence_pairs(items) -> list[tuple[int, int]]:
    """The correspondence pairs: each class's reference (first of its class) with the others."""
    first = {}
    for i, s in enumerate(items):
        first.setdefault(s.cls, i)
    return [(first[s.cls], i) for i, s in enumerate(items) if i != first[s.cls] and s.pose != 0]


def _distinct_correspondence(st: Settings, metric: str) -> bool:
    return st.correspondence_options[metric] != st.metric_options[metric]


def _correspondence_runs(name: str, entries, shapes: _Shapes, st: Settings, jobs: int, quiet: bool,
                         timings: dict, matches: dict) -> None:
    """Match the correspondence pairs of one experiment again with the correspondence's
    metric options, for each metric whose options differ from the recognition's; pairs
    already matched (a clean deformation is in both experiments) are not run twice."""
    items = [shapes.entry(e) for e in entries]
    for metric in METRICS:
        if not _distinct_correspondence(st, metric):
            continue
        t = time.perf_counter()
        pairs = [(i, j) for i, j in _correspondence_pairs(items)
                 if (metric, items[i].label, items[j].label) not in matches]
        used = sorted({k for ij in pairs for k in ij})
        index = {k: n for n, k in enumerate(used)}
        sources = [items[k].mesh for k in used]
        if shapes.store is not None and sources:   # as match_pairs would prepare them
            sources = shapes.store.shapes(sources, metric, resolution=None,
                                          metric_options=correspondence_options(
                                              metric, st.correspondence_options[metric]),
                                          progress=not quiet)
        results = match_pairs(sources, [(index[i], index[j]) for i, j in pairs],
                              metric, n_samples=st.n_samples, seed=st.seed, resolution=None,
                              metric_options=st.correspondence_options[metric], jobs=jobs,
                              progress=not quiet, dense=metric in DENSE_METRICS)
        for (i, j), res in zip(pairs, results):
            matches[metric, items[i].label, items[j].label] = res
        timings[f"{name}.{metric}.correspondence_s"] = round(time.perf_counter() - t, 2)
        _say(f"  {name}/{metric}: {len(pairs)} correspondence pairs matched with "
             f"{st.correspondence_options[metric]} ({time.perf_counter() - t:.0f} s)", quiet)


def _correspondence(matches: dict, shapes: _Shapes, quiet: bool, metrics=METRICS, say: bool = True) -> dict:
    """d(C, C0) per metric, condition and class from the kept matches."""
    out = {}
    for metric in metrics:
        per = {}   # (cls, condition) -> list of (best, direct)
        dense = {}  # condition -> list of dense-map qualities
        pairs = []
        for (m, xl, yl), res in matches.items():
            if m != metric:
                continue
            x, y = shapes.shapes[xl], shapes.shapes[yl]
            q = _pair_quality(res, shapes, x, y)
            per.setdefault((y.cls, y.kind), []).append(q)
            if res.has_dense:
                dq = _dense_quality(res, shapes, x, y)
                dense.setdefault(y.kind, []).append(dq)
                q = {**q, "dense": round(dq["mean"], 4)}
            pairs.append({"x": xl, "y": yl, **{k: (round(v, 6) if isinstance(v, float) else v)
                                                for k, v in q.items()},
                          "relative_distance": round(res.relative_distance, 6)})
        by_class, by_class_direct = {}, {}
        for (cls, kind), qs in per.items():
            by_class.setdefault(cls, {})[kind] = float(np.mean([q["best"] for q in qs]))
            by_class_direct.setdefault(cls, {})[kind] = float(np.mean([q["direct"] for q in qs]))
        entry = {"by_class": by_class, "by_class_direct": by_class_direct, "pairs": pairs}
        for kind in ("clean", "weld", "holes"):
            qs = [q for (c, k), v in per.items() if k == kind for q in v]
            if qs:
                entry[kind] = float(np.mean([q["best"] for q in qs]))
                entry[f"{kind}_direct"] = float(np.mean([q["direct"] for q in qs]))
                entry[f"{kind}_mirrored_fraction"] = float(np.mean([q["branch"] == "mirrored" for q in qs]))
                entry[f"{kind}_pairs"] = len(qs)
        if dense:
            entry["dense"] = {"unit": "geodesic error x 100 / sqrt(area) of the clean working mesh; "
                                      "per_diameter: / its geodesic diameter",
                              **{f"{kind}{suffix}": float(np.mean([d[key] for d in ds]))
                                 for kind, ds in dense.items()
                                 for suffix, key in (("", "mean"), ("_direct", "direct"),
                                                     ("_per_diameter", "per_diameter"))}}
        out[metric] = entry
        _say(f"  correspondence {metric}: " + ", ".join(
            f"{k} {entry[k]:.4f}" for k in ("clean", "weld", "holes") if k in entry), quiet or not say)
    return out


def _correspondence_figures(matches: dict, shapes: _Shapes, out: Path) -> dict:
    """Fig. 6-like pictures: X's sample cells carried to Y, for one welded pair per metric."""
    from .report import plot_correspondence, voronoi_labels

    figures = {}
    for metric in METRICS:
        keys = [k for k in matches if k[0] == metric and shapes.shapes[k[2]].kind == "weld"]
        keys = keys or [k for k in matches if k[0] == metric]
        if not keys:
            continue
        _, xl, yl = keys[0]
        x, y = shapes.shapes[xl], shapes.shapes[yl]
        res = matches[keys[0]]
        wx, wy = shapes.work(x.cls, x.pose), shapes.work(y.cls, y.pose)
        px = wx.from_source(wx.source.from_input_ids(res.x_samples))
        x_labels = voronoi_labels(shapes.geodesic(x.cls, x.pose).from_sources(px))
        # cells on Y: around each sample's image, by geodesic distance on the clean Y, drawn
        # on the perturbed Y (whose vertices are clean vertices: map by file id)
        img = wy.from_source(wy.source.from_input_ids(res.x_to_y_vertex))
        cells = voronoi_labels(shapes.geodesic(y.cls, y.pose).from_sources(img))
        y_labels = cells[wy.mesh.from_input_ids(y.mesh.input_ids)]
        key = f"correspondence_{metric}_{y.kind}"
        f = f"{key}.png"
        plot_correspondence(x.mesh, y.mesh, x_labels, y_labels, out / f, titles=(xl, yl),
                            title=f"{metric}: cells of {xl}'s samples carried to {yl}")
        figures[key] = f
    return figures


def _dense_pages(matches: dict, shapes: _Shapes, out: Path) -> dict:
    """One interactive page per class (its first dense map, a weld where there is one): the
    reference's colours carried to the deformed shape, with plotly.js once beside them."""
    try:
        from .view import write_match_html
    except ImportError:   # pragma: no cover - plotly missing: no pages
        return {}
    pages = {}
    keys = sorted((k for k, r in matches.items() if r.has_dense),
                  key=lambda k: shapes.shapes[k[2]].kind != "weld")   # welds first, stable
    for metric, xl, yl in keys:
        y = shapes.shapes[yl]
        key = f"dense_{y.cls}"
        if key in pages:
            continue
        x = shapes.shapes[xl]
        f = f"{key}.html"
        write_match_html(x.mesh, y.mesh, matches[metric, xl, yl], out / f, titles=(xl, yl),
                         plotlyjs="directory")
        pages[key] = f
    return pages


# ----------------------------------------------------------------------------- TOPKIDS
def _dense_summary(per: dict, samples: dict[str, float]) -> dict:
    """Means over pairs of a dense map's errors in the field's unit (x 100 / sqrt(area)) and the
    paper's (/ diameter), the cumulative curve of all vertices, and each pair's mean."""
    errs = list(per.values())
    allv = np.concatenate([e.errors for e in errs])
    t = np.linspace(0.0, 0.25, 51)
    return {
        "unit": "geodesic error on the input mesh x 100 / sqrt(area); per_diameter: / geodesic diameter",
        "mean": float(np.mean([e.mean for e in errs]) * 100),
        "mean_direct": float(np.mean([e.mean_direct for e in errs]) * 100),
        "median": float(np.median(allv) * 100),
        "per_diameter_mean": float(np.mean([e.per_diameter().mean() for e in errs])),
        "gross_pairs": int(sum(e.per_diameter().mean() > 0.25 for e in errs)),
        "mirrored_pairs": int(sum(e.branch == "mirrored" for e in errs)),
        "samples_mean": float(np.mean(list(samples.values())) * 100),
        "per_shape": {k: round(e.mean * 100, 3) for k, e in per.items()},
        "per_shape_direct": {k: round(e.mean_direct * 100, 3) for k, e in per.items()},
        "curve": {"thresholds": t.round(4).tolist(),
                  "fraction": (allv[None, :] <= t[:, None]).mean(axis=1).round(4).tolist()},
    }


def _topkids_dense(kids, names, results, ref_mesh, sym0) -> dict:
    """Dense maps kidXX -> kid00 scored on kid00's input mesh (the SHREC'16 protocol), the
    better of the direct and the mirrored ground truth per pair; the samples' images scored
    the same way beside them."""
    from ..evaluate import GeodesicReference, dense_error

    fmm = GeodesicReference(ref_mesh)
    per, samples = {}, {}
    for name, r in zip(names, results):
        gt = kids.ground_truth(name)
        per[name] = dense_error(r.x_to_y_dense_face, r.x_to_y_dense_bary, ref_mesh, gt, sym0, fmm=fmm)
        samples[name] = dense_error(r.x_to_y_face, r.x_to_y_bary, ref_mesh, gt[r.x_samples], sym0,
                                    fmm=fmm).mean
    return _dense_summary(per, samples)


def _topkids(data: Path, st: Settings, jobs: int, out: Path, quiet: bool, timings: dict, store=None) -> dict:
    from scipy.stats import spearmanr

    from .correspondence import error_curve
    from .recognition import _figure

    kids = datasets.TopKids(Path(data) / "topkids")
    ref = kids.reference
    names = [n for n in kids.names if n != ref][: st.topkids]
    t = time.perf_counter()
    meshes = [kids.load(n) for n in [ref] + names]
    works = [simplify(m, min(st.resolution or m.n_vertices, m.n_vertices)) for m in meshes]
    handles = [(2 - m.euler_characteristic) / 2 for m in meshes]
    timings["topkids.load_s"] = round(time.perf_counter() - t, 2)
    w0 = works[0]
    geo0 = _stored_rows(store, w0.mesh, metric_solver(w0.mesh, "geodesic"))
    if store is None:
        diam0 = float(np.max(geo0.pairwise()))
    else:   # the same symmetrised matrix, kept with kid00's geodesic entry
        diam0 = float(np.max(store.shape(ShapeMetric(meshes[0], "geodesic", working=w0), "geodesic").distances))
    sym0 = kids.symmetry(ref)
    area0 = float(meshes[0].area)
    res = {"n_shapes": len(names), "reference": ref, "shapes": names,
           "handles": dict(zip(names, handles[1:])), "euler_reference": meshes[0].euler_characteristic}
    curves = {}
    for metric in METRICS:
        t = time.perf_counter()
        shapes = [ShapeMetric(m, metric, working=w, metric_options=st.correspondence_options[metric])
                  for m, w in zip(meshes, works)]
        if store is not None:   # each keyed by its mesh and working mesh
            shapes = store.shapes(shapes, metric, progress=not quiet)
        results = match_pairs(shapes, [(i, 0) for i in range(1, len(shapes))], metric,
                              n_samples=st.n_samples, seed=st.seed, resolution=None, jobs=jobs,
                              progress=not quiet, dense=metric in DENSE_METRICS)
        direct, best, mirrored, rel, trim, abs_err = [], [], [], [], [], []
        for name, r in zip(names, results):
            gt = kids.ground_truth(name)[r.x_samples]
            gm = sym0[gt]
            gm = np.where(gm < 0, gt, gm)
            e = _geodesic_errors(w0, geo0, r.x_to_y_vertex, gt)
            em = _geodesic_errors(w0, geo0, r.x_to_y_vertex, gm)
            direct.append(e.mean() / diam0)
            mirrored.append(em.mean() < e.mean())
            chosen = e if e.mean() <= em.mean() else em
            best.append(chosen.mean() / diam0)
            abs_err.append(chosen)
            rel.append(r.relative_distance)
            trim.append(r.relative_trimmed)
        rho = spearmanr(handles[1:], rel).statistic if len(rel) > 2 else None
        rho_t = spearmanr(handles[1:], trim).statistic if len(trim) > 2 else None
        res[metric] = {
            "correspondence": float(np.mean(best)), "correspondence_direct": float(np.mean(direct)),
            "mirrored_fraction": float(np.mean(mirrored)),
            "relative_distance_mean": float(np.mean(rel)), "relative_distance_max": float(np.max(rel)),
            "spearman_distance_vs_handles": None if rho is None else float(rho),
            # the trimmed distortion (recognition's ranking): does it set the handles aside?
            "relative_trimmed_mean": float(np.mean(trim)),
            "spearman_trimmed_vs_handles": None if rho_t is None else float(rho_t),
            "per_shape": {n: round(float(b), 6) for n, b in zip(names, best)},
            "relative_distance": {n: round(float(d), 6) for n, d in zip(names, rel)},
            "seconds": round(time.perf_counter() - t, 2),
        }
        if metric in DENSE_METRICS:
            t_dense = time.perf_counter()
            res[metric]["dense"] = _topkids_dense(kids, names, results, meshes[0], sym0)
            timings[f"topkids.{metric}.dense_eval_s"] = round(time.perf_counter() - t_dense, 2)
            _say(f"  topkids/{metric} dense map: mean error {res[metric]['dense']['mean']:.2f} x 100 / "
                 f"sqrt(area) (direct {res[metric]['dense']['mean_direct']:.2f}), samples "
                 f"{res[metric]['dense']['samples_mean']:.2f}", quiet)
        thr, frac = error_curve(np.concatenate(abs_err), area0)
        curves[metric] = (thr, frac)
        res[metric]["error_curve"] = {"thresholds": thr.round(4).tolist(), "fraction": frac.round(4).tolist()}
        timings[f"topkids.{metric}_s"] = res[metric]["seconds"]
        _say(f"  topkids/{metric}: d(C,C0) {res[metric]['correspondence']:.4f} "
             f"(direct {res[metric]['correspondence_direct']:.4f}), GH/diam mean "
             f"{res[metric]['relative_distance_mean']:.4f}, Spearman vs handles "
             f"{res[metric]['spearman_distance_vs_handles']}", quiet)
    _save_rows(store, geo0)
    fig = _figure((5.0, 4.0), 100)
    ax = fig.add_subplot(111)
    for metric, (thr, frac) in curves.items():
        ax.plot(thr, frac, label=metric)
    ax.set_xlabel("geodesic error / sqrt(area)")
    ax.set_ylabel("fraction of samples")
    ax.set_title(f"TOPKIDS: kid01-{names[-1][3:]} to {ref} (symmetric map counted)")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "topkids_error_curve.png")
    res["figures"] = {"topkids_error_curve": "topkids_error_curve.png"}
    return res


# ----------------------------------------------------------------------------- main
def check_dependencies() -> None:
    """Raise ImportError, before any work, when a package the run needs is missing: matplotlib
    draws the report's figures (without it a run stopped at its first figure, after the
    experiments). plotly's interactive pages are optional: without it they are left out."""
    from importlib.util import find_spec

    if find_spec("matplotlib") is None:
        raise ImportError("gromov reproduce draws its figures with matplotlib, which is not installed: "
                          "pip install 'gromov[plot]'")


def _check_out(out: Path) -> None:
    """Refuse an ``out`` that replacing as a whole would lose files of the user's."""
    if out.exists() and not out.is_dir():
        raise ValueError(f"out {str(out)!r} exists and is not a folder")
    if not out.is_dir():
        return
    real = out.resolve()
    if Path.cwd().resolve().is_relative_to(real):
        raise ValueError(f"out {str(out)!r} holds the current directory; it is replaced as a "
                         "whole when the run is complete: choose a new folder")
    if any(real.iterdir()) and not (real / "results.json").is_file():
        raise ValueError(f"out {str(out)!r} is a folder with files but no results.json, not a "
                         "previous output; it is replaced as a whole when the run is complete: "
                         "choose a new or empty folder")


def reproduce(data=None, out="gromov-reproduce", *, quick: bool = False, jobs: int | None = None,
              seed: int = 0, quiet: bool = False, command: str | None = None,
              diffusion: dict | None = None, weld_join: str = "pinch", classes: dict | None = None,
              topkids: bool = True, rank_by: str = "trimmed",
              rank_tau_scale: float | None = RANK_TAU_SCALE, rank_residual: str = RANK_RESIDUAL,
              pose_stretch: float = 0.0, local_scaling: int = LOCAL_SCALING_K, store=None) -> dict:
    """Run the paper's experiments and write ``results.json``, figures and ``index.html``.

    Parameters
    ----------
    data : str or Path, optional
        Directory with ``tosca/`` (and optionally ``topkids/``), laid out like
        ``../shared/data``. None: the built-in synthetic set
        (:class:`gromov.experiments.synthetic.Synthetic`), no files needed.
    out : str or Path, default "gromov-reproduce"
        Output directory (created, with its parents). Everything is written into a hidden
        sibling folder ``.NAME.XXXXXXXX.tmp`` that takes the place of ``out`` only once
        complete (:func:`gromov._atomic.atomic_folder`: an atomic exchange on Linux), so an
        interrupted run leaves the previous complete ``out`` or the new one, never a mixture;
        an error or Ctrl-C deletes the hidden folder, SIGKILL can leave it behind. An existing
        ``out`` is replaced as a whole, so it must be empty or a previous output (holding
        ``results.json``), and must not hold the current directory.
    quick : bool, default False
        A smaller run (see :func:`settings_for`).
    jobs : int, optional
        Worker processes for the matches; default: the CPUs this process may use.
    seed : int, default 0
        Sampling seed of every match.
    quiet : bool, default False
        No progress output on stderr.
    command : str, optional
        The command line, recorded in the results.
    diffusion : dict, optional
        Options of the diffusion metric (:func:`gromov.metric_solver`), e.g.
        ``{"kernel": "connectivity", "m": 50, "fill_holes": None}`` for the paper's graph diffusion
        exactly (small holes are closed first unless ``"fill_holes": None``) or
        ``{"kernel": "biharmonic"}``; default: the heat kernel, raw distances at tau = 0.005
        for recognition and normalised heat distributions at tau = 0.01 for the correspondence
        (d(C, C0), TOPKIDS); with ``units`` or ``tau`` given, the same options serve both
        (:func:`gromov.metrics.diffusion.correspondence_options`). Recorded in ``params``
        (``metric_options``, ``correspondence_options``).
    weld_join : {"pinch", "tube"}, default "pinch"
        How Experiment 1 welds (:func:`gromov.perturb.weld`): ``"pinch"`` merges two vertices
        where parts nearly touch -- the paper's *welded vertices*, a point-wise topology change
        (IJCV 2010, §5); ``"tube"`` removes both 1-rings and joins them by a short handle of
        finite width (harder: like the self-contacts of SHREC'16 TOPKIDS). Recorded in
        ``params``.
    classes : dict of str to int, optional
        TOSCA classes to run instead of the paper's (:func:`settings_for`), e.g.
        ``{"wolf": 2, "horse": 4, "centaur": 5, "michael": 6}`` -- classes the paper did not
        use, to choose settings without looking at its test classes. Recorded in ``params``.
    topkids : bool, default True
        Run the TOPKIDS part when its data is there.
    rank_by : {"trimmed", "gh"}, default "trimmed"
        What recognition (ROC, EER, nearest neighbours, MDS maps) ranks pairs by
        (:data:`RANK_BY`): the trimmed distortion of each pair's GH correspondence (RMS of its
        best-fitting 80% of pairs, :func:`gromov.gmds.trimmed_rms`) or the GH estimate. The
        EERs of both are recorded (``eer_gh``, ``eer_trimmed``).
    rank_tau_scale : float or None, default RANK_TAU_SCALE (0.5)
        The trimmed distortion of a heat-kernel diffusion correspondence is measured with the
        heat distance at this times the diffusion time (:func:`gromov.experiments.gh_matrix`'s
        ``rank_tau_scale``); None: in the metric of the match (the same scale). The
        correspondences, GH estimates and d(C, C0) do not depend on it. Recorded in ``params``.
    rank_residual : {"log", "difference"}, default RANK_RESIDUAL ("log")
        The trimmed distortion summarises the log ratios of corresponding distances (a
        multiplicative distortion, :func:`gromov.gmds.log_ratio_residuals`) or, in the
        additive form, their differences over the larger diameter
        (:func:`gromov.experiments.gh_matrix`'s ``rank_residual``). Like ``rank_tau_scale`` it changes only the ranking. Recorded in
        ``params``.
    pose_stretch : float, default 0
        Synthetic set only: ``Synthetic(pose_stretch=...)``, poses as far from isometric as
        TOSCA's (0.1: geodesic distances change by 2.4-6.5 %) -- a validation set on which a
        choice meets the variation within a class that the paper's classes have. Recorded in
        ``params``.
    local_scaling : int, default LOCAL_SCALING_K (4)
        Each ranking's EER is also reported after
        :func:`gromov.experiments.recognition.local_scaling` with this neighbour (capped at the
        number of shapes less one): ``recognition.<experiment>.<metric>.eer_local``,
        ``local_scaling_k``, ``errors_at_eer_local``. A set-level normalisation, reported
        beside the EER, never instead of it. Recorded in ``params``.
    store : str, os.PathLike or gromov.store.ShapeStore, optional
        A shape store (:mod:`gromov.store`, outside ``out``): every shape's metrics -- the
        clean, welded and holed shapes, in the recognition's metric options and in the
        correspondence's, TOPKIDS' -- are read from it where it has them, else computed and
        added, as are the recognition's pair results (:func:`gromov.experiments.gh_matrix`'s
        ``store``) and the geodesic rows the correspondence error is measured with; a second
        run with the same options computes no metric again. The results are the same as
        without a store; what was read back and computed is in ``results["store"]``.

    Returns
    -------
    dict
        The content of ``results.json``. Keys of :data:`RESULT_KEYS` are there both nested
        (``results["eer"]["weld"]["geodesic"]``) and flat (``results["eer.weld.geodesic"]``);
        values are fractions. ``topkids`` is None without TOPKIDS data.
    """
    t_start = time.perf_counter()
    check_dependencies()
    if jobs is None:
        jobs = available_cpus()
    if int(jobs) < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    jobs = int(jobs)
    dataset = "synthetic" if data is None else "tosca"
    if data is not None:
        data = Path(data)
        if not (data / "tosca").is_dir():
            raise datasets.DatasetError(f"{data}: no tosca/ directory (expected the layout of "
                                        f"../shared/data: tosca/cat0.off.gz, ...)")
    st = settings_for(dataset, quick, seed=seed, classes=classes, topkids=topkids)
    if rank_by not in RANK_BY:
        raise ValueError(f"rank_by must be one of {RANK_BY}, got {rank_by!r}")
    if isinstance(local_scaling, bool) or not isinstance(local_scaling, (int, np.integer)) or local_scaling < 1:
        raise ValueError(f"local_scaling must be a positive integer, got {local_scaling!r}")   # before any work
    st = replace(st, rank_by=rank_by, rank_tau_scale=check_rank_tau_scale(rank_tau_scale),
                 rank_residual=check_rank_residual(rank_residual), local_scaling=int(local_scaling))
    if pose_stretch and data is not None:
        raise ValueError("pose_stretch stretches the synthetic set's poses; TOSCA's are as scanned")
    if pose_stretch:
        from .synthetic import Synthetic

        Synthetic(pose_stretch=pose_stretch)   # its own checks, before any work
    if weld_join not in _perturb.WELD_JOINS:
        raise ValueError(f"weld_join must be one of {_perturb.WELD_JOINS}, got {weld_join!r}")
    if diffusion:
        from ..shapes import icosphere

        try:  # the solver's own checks, on a tiny mesh, before any work
            metric_solver(icosphere(1), "diffusion", **dict(diffusion))
        except TypeError as exc:
            raise ValueError(f"diffusion options {dict(diffusion)}: {exc}") from None
        st.metric_options["diffusion"] = dict(diffusion)
    # recorded as run: the library's hole filling applies unless the options say otherwise
    st.metric_options["diffusion"].setdefault("fill_holes", DIFFUSION_FILL_HOLES)
    # the correspondence's own defaults (normalised heat distributions) unless units/tau given
    st = replace(st, correspondence_options={m: correspondence_options(m, st.metric_options[m])
                                             for m in METRICS})
    out = Path(out)
    _check_out(out)
    if store is not None:
        from ..store import ShapeStore, as_store

        root = Path(store.root if isinstance(store, ShapeStore) else store).resolve()
        if root.is_relative_to(out.resolve()):
            raise ValueError(f"store {str(root)!r} is inside out {str(out)!r}, which is replaced as a "
                             "whole when the run is complete: keep the store outside it")
        store = as_store(store)
        counts = (store.computed, store.reused, store.pairs_reused)
    final = out
    with atomic_folder(final) as out:   # everything below writes into a hidden sibling folder
        collection = _collection(dataset, data, pose_stretch)
        unknown = [c for c in {**st.experiment1, **st.experiment2} if c not in collection.classes]
        if unknown:
            raise datasets.DatasetError(f"no class {', '.join(map(repr, unknown))} in {data}; classes: "
                                        f"{', '.join(collection.classes)}")
        shapes = _Shapes(collection, st.resolution, weld_join, store)
        timings: dict = {}
        _say(f"gromov reproduce: {dataset}{' (quick)' if quick else ''}, {jobs} job(s), output in {final}", quiet)

        t = time.perf_counter()
        exp1 = datasets.experiment1(collection, st.experiment1)
        exp2 = datasets.experiment2(collection, st.experiment2)
        for e in exp1 + exp2:
            shapes.entry(e)
        shapes.shared = {e.label for e in exp1} & {e.label for e in exp2}
        timings["shapes_s"] = round(time.perf_counter() - t, 2)
        _say(f"  {len(exp1)} + {len(exp2)} shapes at {st.resolution or 'full'} resolution "
             f"({timings['shapes_s']:.0f} s)", quiet)

        matches: dict = {}      # the recognition's kept pairs
        cmatches: dict = {}     # the correspondence pairs with the correspondence's options
        recognition = {}
        for name, exp in (("weld", exp1), ("holes", exp2)):
            recognition[name] = _recognition(name, exp, shapes, st, jobs, out, quiet, timings, matches)
            _correspondence_runs(name, exp, shapes, st, jobs, quiet, timings, cmatches)
        t = time.perf_counter()
        for key, res in matches.items():
            if not _distinct_correspondence(st, key[0]):
                cmatches[key] = res
        correspondence = _correspondence(cmatches, shapes, quiet)
        distinct = [m for m in METRICS if _distinct_correspondence(st, m)]
        # the recognition metric's own maps too, for comparison
        for metric, entry in _correspondence(matches, shapes, quiet, distinct, say=False).items():
            correspondence[metric]["recognition_metric"] = {
                k: entry[k] for k in ("clean", "weld", "holes", "clean_direct", "weld_direct", "holes_direct")
                if k in entry}
        figures = {}
        for rec in recognition.values():
            figures.update(rec.pop("figures"))
        figures.update(_correspondence_figures(cmatches, shapes, out))
        figures.update(_dense_pages(cmatches, shapes, out))
        shapes.save_rows()
        timings["correspondence_s"] = round(time.perf_counter() - t, 2)

        topkids = None
        if data is not None and st.topkids and (data / "topkids").is_dir():
            topkids = _topkids(data, st, jobs, out, quiet, timings, store)
            figures.update(topkids.pop("figures"))
        timings["total_s"] = round(time.perf_counter() - t_start, 2)

        results = {
            "dataset": dataset, "data": None if data is None else str(data), "quick": quick,
            "date": time.strftime("%Y-%m-%d"), "command": command or "gromov reproduce",
            "seconds_total": timings["total_s"], "jobs": jobs,
            "eer": {exp: {m: recognition[exp][m]["eer"] for m in METRICS} for exp in recognition},
            "recognition": recognition,
            "correspondence": correspondence,
            "topkids": topkids,
            "timings": timings,
            "params": {**st.to_dict(), "weld_count": datasets.WELD_COUNT, "weld_join": weld_join,
                       "pose_stretch": float(pose_stretch),
                       "hole_counts": list(datasets.HOLE_COUNTS),
                       "correspondence_error": "geodesic on the clean working meshes / clean geodesic diameter; "
                                               "best of direct and mirrored ground truth"},
            "seeds": {"sampling": seed, "perturbations": {s.label: s.info.get("seed") for s in shapes.shapes.values()
                                                          if "seed" in s.info}},
            "versions": _versions(),
            "environment": environment(),
            "figures": figures,
            "store": None if store is None else {
                "path": str(store.root), **{k: v - v0 for k, v, v0 in zip(
                    ("shapes_computed", "shapes_read", "pairs_read"),
                    (store.computed, store.reused, store.pairs_reused), counts)}},
        }
        for key in RESULT_KEYS:
            a, b, c = key.split(".")
            results[key] = results[a][b].get(c) if a == "correspondence" else results[a][b][c]
        atomic_write_text(out / "results.json", json.dumps(finite(results), indent=1, default=_json_default,
                                                                allow_nan=False))
        from .report import write_report

        write_report(json.loads((out / "results.json").read_text()), out)
    _say(f"  wrote {final / 'results.json'} and {final / 'index.html'} ({timings['total_s']:.0f} s)", quiet)
    return results
