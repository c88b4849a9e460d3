"""Readers for the research shape collections and the paper's experiment subsets.

Two collections, laid out as in ``../shared/data`` (see its README; the data are never
copied into the repository):

- :class:`TOSCA` -- TOSCA high-resolution, files ``<class><pose>.off.gz`` (``cat0``,
  ``david10``). Within a class every pose has the same vertices in the same order, so the
  ground truth between two poses is the identity on vertex indices.
- :class:`TopKids` -- SHREC'16 "Topological KIDS" (Lähner et al., 3DOR 2016), ``kid00``
  (the null shape) to ``kid25`` with ``kidXX_ref.txt`` (match to ``kid00``) and
  ``kidXX_sym.txt`` (left-right symmetry on the same shape).

:func:`experiment1` and :func:`experiment2` list the TOSCA subsets of Bronstein, Bronstein,
Mahmoudi, Kimmel & Sapiro, "A Gromov-Hausdorff framework with diffusion geometry for
topologically-robust non-rigid shape matching", IJCV 89 (2010), §5, as plain data: each
:class:`Entry` names a shape and the topological noise to apply to it, with a fixed seed.
Applying the noise (``gromov.perturb.weld`` / ``holes``) is left to the caller, who
usually does it on the working-resolution mesh.

All indices returned here are 0-based *file* indices (``mesh.input_ids`` maps a loaded
mesh's vertices back to them).
"""

from __future__ import annotations

import gzip
import os
import re
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import GromovError
from ..io import load as _load

__all__ = [
    "DATA_ENV", "WELD_COUNT", "HOLE_COUNTS", "DatasetError", "data_root",
    "TOSCA", "TopKids", "Entry", "experiment1", "experiment2",
]

DATA_ENV = "GROMOV_DATA"
"""Environment variable naming the data directory (the one holding ``tosca/``, ``topkids/``)."""

WELD_COUNT = 3
"""Places glued together in each welded shape of experiment 1 (the paper glues "a few")."""

HOLE_COUNTS = (10, 20)
"""Numbers of holes punched in each deformation of experiment 2."""

_MESH_RE = re.compile(r"^([A-Za-z_]+)(\d+)\.off(\.gz)?$")
_KID_RE = re.compile(r"^(kid\d{2})\.off(\.gz)?$")


class DatasetError(GromovError, ValueError):
    """A data set file is malformed or disagrees with its mesh."""


# ------------------------------------------------------------------------------ data root
def data_root(path: str | os.PathLike | None = None) -> Path:
    """The data directory: ``path`` if given, else ``$GROMOV_DATA``.

    Parameters
    ----------
    path : str or os.PathLike, optional
        Directory holding the collections (``tosca/``, ``topkids/``).

    Returns
    -------
    Path
        The directory, ``~`` expanded.

    Raises
    ------
    FileNotFoundError
        Neither ``path`` nor ``$GROMOV_DATA`` is given, or the directory does not exist
        (the message names it).
    """
    if path is None:
        env = os.environ.get(DATA_ENV, "")
        if not env:
            raise FileNotFoundError(
                f"no data directory given: pass --data DIR or set {DATA_ENV}=DIR "
                "(the directory holding tosca/ and topkids/)")
        root, source = Path(env), f"${DATA_ENV}"
    else:
        root, source = Path(path), "data directory"
    root = root.expanduser()
    if not root.is_dir():
        what = "is not a directory" if root.exists() else "does not exist"
        raise FileNotFoundError(f"{source} {root} {what}: pass --data DIR or set {DATA_ENV}=DIR")
    return root


def _dir(root: str | os.PathLike, sub: str) -> Path:
    """``root`` itself if it holds meshes, else ``root/sub``; must exist."""
    root = Path(root).expanduser()
    if (root / sub).is_dir():
        return root / sub
    if not root.is_dir():
        raise FileNotFoundError(f"{sub} data directory {root} does not exist")
    return root


def _off_vertex_count(path: Path) -> int:
    """Vertex count from an OFF header (``.off`` or ``.off.gz``) without reading the body."""
    opener = gzip.open if path.name.endswith(".gz") else open
    tokens: list[str] = []
    with opener(path, "rt") as f:
        for line in f:
            line = line.split("#", 1)[0].strip()
            if line:
                tokens.extend(line.split())
            if len(tokens) >= 2:
                break
    if not tokens or not tokens[0].endswith("OFF"):
        raise DatasetError(f"{path}: not an OFF file (header {tokens[:1]})")
    try:
        return int(tokens[1])
    except (IndexError, ValueError):
        raise DatasetError(f"{path}: no vertex count in the OFF header") from None


# ---------------------------------------------------------------------------------- TOSCA
class TOSCA:
    """Reader over a TOSCA-like directory of ``<class><pose>.off[.gz]`` meshes.

    Classes and poses are discovered from the file names. Ground truth: within a class,
    vertex ``i`` of one pose corresponds to vertex ``i`` of every other pose.

    Parameters
    ----------
    root : str or os.PathLike
        The ``tosca`` directory, or a data root that contains ``tosca/``.

    Raises
    ------
    FileNotFoundError
        The directory does not exist or holds no ``<class><pose>.off[.gz]`` file.
    DatasetError
        Two files name the same shape (``cat0.off`` and ``cat0.off.gz``).

    Examples
    --------
    >>> tosca = TOSCA(data_root() / "tosca")          # doctest: +SKIP
    >>> tosca.poses("wolf"), tosca.load("wolf", 0).n_vertices   # doctest: +SKIP
    ([0, 1, 2], 4344)
    """

    def __init__(self, root: str | os.PathLike):
        self.root = _dir(root, "tosca")
        files: dict[str, dict[int, Path]] = {}
        for p in sorted(self.root.iterdir()):
            m = _MESH_RE.match(p.name)
            if not m or not p.is_file():
                continue
            cls, pose = m.group(1), int(m.group(2))
            if pose in files.setdefault(cls, {}):
                raise DatasetError(f"{self.root}: both {files[cls][pose].name} and {p.name} "
                                   f"hold {cls}{pose}")
            files[cls][pose] = p
        if not files:
            raise FileNotFoundError(f"{self.root}: no <class><pose>.off.gz meshes found")
        self._files = files

    def __repr__(self) -> str:
        return f"TOSCA({str(self.root)!r}: {len(self._files)} classes, {len(self.shapes())} shapes)"

    @property
    def classes(self) -> list[str]:
        """Class names, sorted."""
        return sorted(self._files)

    def _class(self, cls: str) -> dict[int, Path]:
        if cls not in self._files:
            raise KeyError(f"no TOSCA class {cls!r} in {self.root}; classes: "
                           f"{', '.join(self.classes)}")
        return self._files[cls]

    def poses(self, cls: str) -> list[int]:
        """Pose numbers of ``cls``, sorted. Raises ``KeyError`` for an unknown class."""
        return sorted(self._class(cls))

    def path(self, cls: str, pose: int) -> Path:
        """File of ``cls`` in ``pose``. Raises ``KeyError`` naming the poses that exist."""
        poses = self._class(cls)
        valid = isinstance(pose, (int, np.integer)) and not isinstance(pose, bool)
        if not valid or int(pose) not in poses:
            raise KeyError(f"no pose {pose!r} of TOSCA class {cls!r}; poses: "
                           f"{', '.join(map(str, sorted(poses)))}")
        return poses[int(pose)]

    def load(self, cls: str, pose: int, **kwargs):
        """The mesh of ``cls`` in ``pose`` via :func:`gromov.load` (``kwargs`` passed on)."""
        return _load(self.path(cls, pose), **kwargs)

    def shapes(self) -> list[tuple[str, int]]:
        """All ``(class, pose)`` pairs, sorted by class then pose."""
        return [(c, p) for c in self.classes for p in self.poses(c)]


# ---------------------------------------------------------------------------- experiments
@dataclass(frozen=True)
class Entry:
    """One shape of an experiment: a TOSCA pose and the topological noise to apply.

    Attributes
    ----------
    experiment : str
        ``"experiment1"`` or ``"experiment2"``.
    cls : str
        TOSCA class (``"cat"``, ``"dog"``, ``"david"``, ``"victoria"``).
    pose : int
        Pose number; ``0`` is the class's reference pose.
    perturbation : tuple or None
        ``None`` (the clean shape), ``("weld", count)`` or ``("holes", count)``.
    seed : int
        Seed for the perturbation, a CRC-32 of ``experiment/cls/pose/perturbation``:
        the same on every run and platform, distinct between the entries of a subset.
    """

    experiment: str
    cls: str
    pose: int
    perturbation: tuple[str, int] | None
    seed: int

    @property
    def label(self) -> str:
        """Short name, e.g. ``"cat1"``, ``"cat1+weld3"``, ``"dog2+holes10"``."""
        name = f"{self.cls}{self.pose}"
        if self.perturbation is None:
            return name
        kind, count = self.perturbation
        return f"{name}+{kind}{count}"


def _seed(experiment: str, cls: str, pose: int, perturbation) -> int:
    tag = "clean" if perturbation is None else f"{perturbation[0]}{perturbation[1]}"
    return zlib.crc32(f"{experiment}/{cls}/{pose}/{tag}".encode())


def _entry(experiment: str, cls: str, pose: int, perturbation) -> Entry:
    return Entry(experiment, cls, pose, perturbation, _seed(experiment, cls, pose, perturbation))


def _reference_and_deformations(tosca: TOSCA, cls: str, n: int) -> list[int]:
    """Pose 0 and the first ``n`` other poses of ``cls`` in sorted order."""
    poses = tosca.poses(cls)
    if 0 not in poses:
        raise DatasetError(f"class {cls!r} has no reference pose 0; poses: {poses}")
    others = [p for p in poses if p != 0]
    if len(others) < n:
        raise DatasetError(f"class {cls!r} needs {n} poses besides 0, has {others}")
    return others[:n]


EXPERIMENT1_CLASSES = {"cat": 2, "dog": 4, "david": 6, "victoria": 6}
"""Experiment 1 classes and deformations per class (male = david, female = victoria)."""

EXPERIMENT2_CLASSES = {"cat": 2, "dog": 2, "david": 2, "victoria": 2}
"""Experiment 2 classes and deformations per class."""


def experiment1(tosca: TOSCA, classes: dict[str, int] | None = None) -> list[Entry]:
    """The point-wise topology changes subset (Bronstein et al. 2010, §5, experiment 1).

    Per class of :data:`EXPERIMENT1_CLASSES` (cat 2, dog 4, david 6, victoria 6
    deformations): the clean reference pose 0, then each deformation clean and welded at
    :data:`WELD_COUNT` places (``("weld", 3)``). The deformations are the first N poses
    other than 0 in sorted order: cat 1, 2; dog 1, 2, 3, 5; david 1, 6, 10, 11, 12, 13;
    victoria 1, 2, 4, 7, 10, 12. 40 entries for the full TOSCA set.

    Parameters
    ----------
    tosca : TOSCA
        Or any collection with the same ``poses(cls)`` method (e.g. the built-in
        :class:`gromov.experiments.synthetic.Synthetic`).
    classes : dict of str to int, optional
        Classes and deformations per class; default :data:`EXPERIMENT1_CLASSES`.

    Returns
    -------
    list of Entry
        Ordered by class (as above), then pose, clean before welded.

    Raises
    ------
    DatasetError
        A class lacks pose 0 or has too few poses. ``KeyError`` if a class is missing.
    """
    out = []
    for cls, n in (EXPERIMENT1_CLASSES if classes is None else classes).items():
        deformations = _reference_and_deformations(tosca, cls, n)
        out.append(_entry("experiment1", cls, 0, None))
        for pose in deformations:
            out.append(_entry("experiment1", cls, pose, None))
            out.append(_entry("experiment1", cls, pose, ("weld", WELD_COUNT)))
    return out


def experiment2(tosca: TOSCA, classes: dict[str, int] | None = None) -> list[Entry]:
    """The holes subset (Bronstein et al. 2010, §5, experiment 2).

    Per class of :data:`EXPERIMENT2_CLASSES` (cat, dog, david, victoria): the clean
    reference pose 0 and the first two other poses in sorted order (cat 1, 2; dog 1, 2;
    david 1, 6; victoria 1, 2), each deformation with 10 and with 20 holes. The clean
    deformations are *not* included (they are in :func:`experiment1`): 5 entries per
    class, 20 in all.

    Parameters
    ----------
    tosca : TOSCA
        Or any collection with the same ``poses(cls)`` method.
    classes : dict of str to int, optional
        Classes and deformations per class; default :data:`EXPERIMENT2_CLASSES`.

    Returns
    -------
    list of Entry
        Ordered by class, then pose, 10 holes before 20.

    Raises
    ------
    DatasetError
        A class lacks pose 0 or has too few poses. ``KeyError`` if a class is missing.
    """
    out = []
    for cls, n in (EXPERIMENT2_CLASSES if classes is None else classes).items():
        deformations = _reference_and_deformations(tosca, cls, n)
        out.append(_entry("experiment2", cls, 0, None))
        for pose in deformations:
            for count in HOLE_COUNTS:
                out.append(_entry("experiment2", cls, pose, ("holes", count)))
    return out


# -------------------------------------------------------------------------------- TopKids
def _read_ints(path: Path) -> np.ndarray:
    """Whitespace-separated integers as a 2-D int64 array (one row per line)."""
    try:
        a = np.loadtxt(path, dtype=np.int64, ndmin=2)
    except ValueError as exc:
        raise DatasetError(f"{path}: not a table of integers: {exc}") from None
    return a


class TopKids:
    """Reader for SHREC'16 "Topological KIDS" (low resolution): ``kid00`` .. ``kid25``.

    ``kid00`` is the null shape; every other kid is the same child in another pose with
    self-contacts merged into handles. Ground truth files use 1-based indices; everything
    returned here is 0-based, in the vertex order of the ``.off`` file (checked against its
    header's vertex count).

    Parameters
    ----------
    root : str or os.PathLike
        The ``topkids`` directory, or a data root that contains ``topkids/``.

    Raises
    ------
    FileNotFoundError
        The directory does not exist or holds no ``kidXX.off[.gz]`` mesh.
    """

    reference = "kid00"

    def __init__(self, root: str | os.PathLike):
        self.root = _dir(root, "topkids")
        files = {}
        for p in sorted(self.root.iterdir()):
            m = _KID_RE.match(p.name)
            if m and p.is_file():
                files.setdefault(m.group(1), p)
        if not files:
            raise FileNotFoundError(f"{self.root}: no kidXX.off.gz meshes found")
        self._files = files
        self._counts: dict[str, int] = {}

    def __repr__(self) -> str:
        return f"TopKids({str(self.root)!r}: {len(self._files)} shapes)"

    @property
    def names(self) -> list[str]:
        """Shape names that exist (``kid00``, ``kid01``, ...), sorted."""
        return sorted(self._files)

    def path(self, name: str) -> Path:
        """Mesh file of ``name``. Raises ``KeyError`` naming the shapes that exist."""
        if name not in self._files:
            raise KeyError(f"no TopKids shape {name!r} in {self.root}; shapes: "
                           f"{', '.join(self.names)}")
        return self._files[name]

    def load(self, name: str, **kwargs):
        """The mesh of ``name`` via :func:`gromov.load` (``kwargs`` passed on)."""
        return _load(self.path(name), **kwargs)

    def n_vertices(self, name: str) -> int:
        """Vertex count in the file of ``name`` (from the OFF header)."""
        if name not in self._counts:
            self._counts[name] = _off_vertex_count(self.path(name))
        return self._counts[name]

    def ground_truth(self, name: str) -> np.ndarray:
        """Matching vertex on ``kid00`` of each vertex of ``name``.

        From ``<name>_ref.txt``: two 1-based columns, vertex on ``name`` and its match on
        ``kid00``; every vertex has a match. For ``kid00`` itself, the identity.

        Returns
        -------
        ndarray of int64, shape (n_vertices(name),)
            Values in ``[0, n_vertices("kid00"))``.

        Raises
        ------
        KeyError
            Unknown shape.
        FileNotFoundError
            The ``_ref.txt`` file is missing.
        DatasetError
            The file is not two integer columns, misses or repeats a vertex of ``name``, or
            names a vertex outside ``name`` or ``kid00``.
        """
        n = self.n_vertices(name)
        if name == self.reference:
            return np.arange(n, dtype=np.int64)
        n0 = self.n_vertices(self.reference)
        path = self.root / f"{name}_ref.txt"
        if not path.is_file():
            raise FileNotFoundError(f"{path}: ground truth file of {name} not found")
        a = _read_ints(path)
        if a.shape[1] != 2:
            raise DatasetError(f"{path}: expected 2 columns (vertex on {name}, vertex on "
                               f"{self.reference}), found {a.shape[1]}")
        src, dst = a[:, 0] - 1, a[:, 1] - 1
        self._check_range(path, src, n, name, "first")
        self._check_range(path, dst, n0, self.reference, "second")
        out = np.full(n, -1, dtype=np.int64)
        out[src] = dst
        if len(a) != n or np.any(out < 0):
            missing = np.flatnonzero(out < 0)
            raise DatasetError(f"{path}: {len(a)} rows for {n} vertices of {name}; "
                               f"{len(missing)} vertices without a match "
                               f"(first {missing[:5].tolist()}, 0-based)")
        return out

    def symmetry(self, name: str) -> np.ndarray:
        """Left-right symmetric vertex on the same shape, ``-1`` where there is none.

        From ``<name>_sym.txt``, 1-based, 0 meaning no match, in either of the two layouts
        of the data: one column with a row per vertex (``kid00``), or two columns ``vertex,
        symmetric vertex`` listing only the vertices that have a match (the other kids).
        Roughly 98-99 % of the defined entries satisfy ``sym[sym[i]] == i``; the map is not
        an exact involution.

        Returns
        -------
        ndarray of int64, shape (n_vertices(name),)

        Raises
        ------
        KeyError, FileNotFoundError, DatasetError
            As :meth:`ground_truth`.
        """
        n = self.n_vertices(name)
        path = self.root / f"{name}_sym.txt"
        if not path.is_file():
            raise FileNotFoundError(f"{path}: symmetry file of {name} not found")
        a = _read_ints(path)
        if a.shape[1] == 1:
            if len(a) != n:
                raise DatasetError(f"{path}: one column of {len(a)} rows, but {name} has "
                                   f"{n} vertices")
            src, dst = np.arange(n), a[:, 0]
        elif a.shape[1] == 2:
            src, dst = a[:, 0] - 1, a[:, 1]
            self._check_range(path, src, n, name, "first")
            if len(np.unique(src)) != len(src):
                raise DatasetError(f"{path}: a vertex of {name} is listed more than once")
        else:
            raise DatasetError(f"{path}: expected 1 or 2 columns, found {a.shape[1]}")
        if np.any((dst < 0) | (dst > n)):
            raise DatasetError(f"{path}: symmetric vertex outside 0..{n} (1-based, 0 = none) "
                               f"for {name} with {n} vertices")
        out = np.full(n, -1, dtype=np.int64)
        out[src] = dst - 1
        return out

    @staticmethod
    def _check_range(path: Path, idx: np.ndarray, n: int, name: str, column: str) -> None:
        bad = (idx < 0) | (idx >= n)
        if bad.any():
            raise DatasetError(f"{path}: {column} column has {int(bad.sum())} indices outside "
                               f"1..{n} ({name} has {n} vertices), first "
                               f"{int(idx[bad][0]) + 1}")
