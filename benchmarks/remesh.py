"""Independently remeshed copies of TOSCA poses, with ground truth carried by the nearest vertex.

Run:  .venv/bin/python benchmarks/remesh.py --out DIR [--data DIR] [--classes cat,dog,...]
                                            [--vertices 5000] [--densities 2000,8000]

TOSCA's poses of a class share one triangulation, which a method can snap to (functional maps
reach error 0 there). Each pose here is remeshed on its own by isotropic remeshing (Botsch &
Kobbelt, SGP 2004: rounds of edge split / collapse / flip and tangential smoothing, projected
back onto the input surface; pymeshlab's ``meshing_isotropic_explicit_remeshing``, 10 rounds), with a different target per
pose (``--vertices`` times 0.9 for pose 0 and 1.1 for the other pose), so that no two
copies share a vertex or a triangle. (gpytoolbox's ``remesh_botsch`` aborts the process on
horse5 with ``std::bad_alloc``; pymeshlab remeshes every pose.) Pose 0 of each class is also remeshed at each of
``--densities`` (a shape against itself at another density).

For each copy NAME the folder gets ``NAME.off`` and ``NAME.ids.txt``: per vertex of the copy,
the nearest vertex (0-based) of the original pose. Since the poses of a class share their
vertex numbering, the true image of a copy's vertex v on another copy of the class is the
vertex of that copy nearest to original vertex ``ids[v]`` (``true_images`` below). The meshes
are research data: the folder stays outside the repository. Needs pymeshlab
(``pip install ".[remesh]"``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import add_data_argument  # noqa: E402

#: Class -> the pose remeshed beside pose 0 (as benchmarks/bench_dense.py pairs them).
POSES = {"cat": 1, "dog": 1, "horse": 5, "centaur": 1, "wolf": 1, "david": 1, "michael": 1, "victoria": 1}


def remesh(mesh, n_vertices: int):
    """``(vertices, faces)`` of an isotropic remeshing of ``mesh`` to about ``n_vertices``
    (pymeshlab's explicit isotropic remeshing, 10 iterations): target edge h from
    area = 2 n (sqrt(3) / 4) h^2 (two equilateral faces per vertex)."""
    import pymeshlab

    h = np.sqrt(2.0 * mesh.area / (np.sqrt(3.0) * n_vertices))
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.array(mesh.vertices, dtype=np.float64), np.array(mesh.faces, dtype=np.int32)))
    ms.meshing_isotropic_explicit_remeshing(iterations=10, targetlen=pymeshlab.PureValue(float(h)))
    out = ms.current_mesh()
    return np.asarray(out.vertex_matrix(), dtype=np.float64), np.asarray(out.face_matrix(), dtype=np.int64)


def true_images(ids_x: np.ndarray, original_y: np.ndarray, vertices_y: np.ndarray) -> np.ndarray:
    """Vertex of copy Y nearest to the original pose's vertex ``ids_x[v]``, for each v of X."""
    return cKDTree(vertices_y).query(original_y[ids_x])[1]


def write_off(path: Path, v: np.ndarray, f: np.ndarray) -> None:
    with open(path, "w") as fh:
        fh.write(f"OFF\n{len(v)} {len(f)} 0\n")
        np.savetxt(fh, v, fmt="%.9g")
        np.savetxt(fh, np.c_[np.full(len(f), 3), f], fmt="%d")


def main(argv=None) -> int:
    from gromov.experiments import datasets

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--out", required=True, help="folder for the copies (outside the repository)")
    ap.add_argument("--classes", default=",".join(POSES))
    ap.add_argument("--vertices", type=int, default=5000)
    ap.add_argument("--densities", default="2000,8000", help="pose 0 also at these sizes ('': none)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tosca = datasets.TOSCA(Path(args.data) / "tosca")
    sizes = [int(s) for s in args.densities.split(",") if s]
    for cls in args.classes.split(","):
        jobs = [(0, int(0.9 * args.vertices), f"{cls}0"), (POSES[cls], int(1.1 * args.vertices), f"{cls}{POSES[cls]}")]
        jobs += [(0, n, f"{cls}0-{n}") for n in sizes]
        for pose, n, name in jobs:
            t = time.perf_counter()
            m = tosca.load(cls, pose)
            v, f = remesh(m, n)
            ids = cKDTree(m.vertices).query(v)[1]
            write_off(out / f"{name}.off", v, f)
            np.savetxt(out / f"{name}.ids.txt", m.input_ids[ids], fmt="%d")
            print(f"{name}: {m.n_vertices} -> {len(v)} vertices, {time.perf_counter() - t:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
