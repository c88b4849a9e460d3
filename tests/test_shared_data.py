"""Every mesh of the research data (TOSCA, TOPKIDS, SHREC'07 watertight) loads without a repair
that changes it and prepares with the default metric. Slow (minutes): run with GROMOV_SLOW=1."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import gromov
from gromov.errors import GromovWarning
from gromov.gh import ShapeMetric

from conftest import data_root

_FILES = sorted(p.relative_to(data_root()).as_posix() for folder in ("tosca", "topkids", "watertight")
                for p in (data_root() / folder).glob("*.off.gz")) if (data_root() / "tosca").is_dir() else []


@pytest.mark.slow
@pytest.mark.parametrize("name", _FILES)
def test_every_data_mesh_prepares_with_the_default_metric(data_dir, name):
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always", GromovWarning)
        mesh = gromov.load(data_dir / name)
    repairs = [str(w.message) for w in rec if issubclass(w.category, GromovWarning)]
    # a valid mesh is not changed by loading (a merge of its sheets would say so here)
    assert mesh.n_file_vertices == gromov.load(data_dir / name, repair=False).n_vertices
    assert not any("merged" in m for m in repairs), repairs
    s = ShapeMetric(mesh, "diffusion")
    d = s.distances
    assert np.isfinite(d).all() and s.diameter > 0
    assert len(s.samples(100, 0)) == 100
