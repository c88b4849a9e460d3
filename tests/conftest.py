"""Shared fixtures: the research data directory and working meshes made from it.

The data are read from ``$GROMOV_DATA`` or ``../shared/data`` beside the repository;
they are never copied into the repository.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import gromov

REPO = Path(__file__).resolve().parents[1]


def data_root() -> Path:
    env = os.environ.get("GROMOV_DATA")
    return Path(env) if env else REPO.parent / "shared" / "data"


@pytest.fixture(scope="session")
def data_dir() -> Path:
    root = data_root()
    if not (root / "tosca").is_dir():
        pytest.skip(f"research data not found at {root} (set GROMOV_DATA)")
    return root


@pytest.fixture(scope="session")
def tosca_cat0(data_dir):
    import gromov

    return gromov.load(data_dir / "tosca" / "cat0.off.gz")


@pytest.fixture(scope="session")
def cat_working(tosca_cat0):
    """cat0 simplified to about 3,000 vertices (the paper's working size)."""
    import gromov

    return gromov.simplify(tosca_cat0, 3000)


def body_and_debris(n_debris: int = 12, size: float = 0.05):
    """An icosphere of radius 1 with ``n_debris`` tiny tetrahedra floating beside it."""
    from gromov.shapes import icosphere

    body = icosphere(3)
    rng = np.random.default_rng(0)
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    tf = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    V, F, n = [np.array(body.vertices)], [np.array(body.faces)], body.n_vertices
    for _ in range(n_debris):
        V.append(tet * size * rng.uniform(0.8, 1.2, 3) + rng.normal(size=3) * 1.6)
        F.append(tf + n)
        n += 4
    return gromov.Mesh(np.vstack(V), np.vstack(F)), body.n_vertices


def pytest_collection_modifyitems(config, items):
    if os.environ.get("GROMOV_SLOW") == "1":
        return
    skip = pytest.mark.skip(reason="slow: full-resolution data; run with GROMOV_SLOW=1")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def held_out_pair(data_dir):
    """``make(cls, label, metric="diffusion")`` -> ``(shapes, ref, y, sx, sy)``: the reference pose
    of a TOSCA class and one of its shapes (e.g. "horse6+weld3", "centaur1+holes10"), built as
    ``gromov reproduce`` builds them (3,000 vertices, pinch welds), with their metrics."""
    from gromov.experiments.datasets import TOSCA, experiment1, experiment2
    from gromov.experiments.reproduce import _Shapes
    from gromov.gh import ShapeMetric

    tosca = TOSCA(data_dir / "tosca")
    shapes = _Shapes(tosca, 3000, "pinch")

    def make(cls: str, label: str, metric: str = "diffusion"):
        listed = experiment2 if "holes" in label else experiment1
        entries = [shapes.entry(e) for e in listed(tosca, {cls: 2})]
        y = next(e for e in entries if e.label == label)
        opts = {"units": "raw"} if metric == "diffusion" else {}   # the heat kernel in raw units
        return (shapes, entries[0], y, ShapeMetric(entries[0].mesh, metric, resolution=None, metric_options=opts),
                ShapeMetric(y.mesh, metric, resolution=None, metric_options=opts))

    return make
