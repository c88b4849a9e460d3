"""Samples re-seated where the other samples place them (:mod:`gromov.reseat`)."""

import numpy as np
import pytest

from gromov import Mesh, gh
from gromov.gmds import SurfaceDistance, SurfacePoints, SymmetricGMDS
from gromov.metrics import metric_solver
from gromov.reseat import covering_radius, reseat_start
from gromov.sampling import farthest_point_sampling
from gromov.shapes import icosphere


@pytest.fixture(scope="module")
def lumpy():
    """An ellipsoid with seeded bumps (no symmetry), its geodesic distances and samples."""
    s = icosphere(3)
    v = np.array(s.vertices) * [1.0, 0.7, 0.5]
    bumps = np.random.default_rng(3).normal(size=(6, 3))
    v *= (1.0 + 0.15 * np.exp(-4 * ((v[:, None, :] - bumps[None] / 2) ** 2).sum(-1)).sum(1))[:, None]
    m = Mesh(v, s.faces)
    D = metric_solver(m, "geodesic").pairwise()
    S = SurfaceDistance(m, D)
    P = np.asarray(farthest_point_sampling(D, 40, seed=0).indices)
    Q = np.asarray(farthest_point_sampling(D, 40, seed=1).indices)
    return m, D, S, P, Q


def test_the_exact_map_stays(lumpy):
    m, _, S, P, Q = lumpy
    ip, iq = SurfacePoints.at_vertices(m, P), SurfacePoints.at_vertices(m, Q)
    gm = SymmetricGMDS(S, S, P, Q)
    assert reseat_start(S, S, P, Q, ip, iq, *gm.blocks(ip, iq)) is None


def test_a_displaced_group_goes_back_to_its_vertices(lumpy):
    """Five neighbouring samples' images moved together to the far side (each kept beside the
    others, as a misplaced limb is): with every other pair fixed, each one's best vertex lies in
    its own cell again; no other image moves."""
    m, D, S, P, Q = lumpy
    r = covering_radius(S, Q)
    group = np.argsort(D[P[0], P])[:5]                  # sample 0 and its four nearest samples
    far = int(np.argmax(D[P[0]]))
    wrong = P.copy()
    wrong[group] = np.argsort(D[far])[:5]               # the five vertices nearest the far point
    assert np.all(D[wrong[group], P[group]] > 3 * r)
    ip, iq = SurfacePoints.at_vertices(m, wrong), SurfacePoints.at_vertices(m, Q)
    gm = SymmetricGMDS(S, S, P, Q)
    start = reseat_start(S, S, P, Q, ip, iq, *gm.blocks(ip, iq))
    assert start is not None
    sp, sq = start
    # each back in its own sample's cell (GMDS then makes the last, local step)
    assert np.all(D[sp.vertex(m.faces)[group], P[group]] < r), D[sp.vertex(m.faces)[group], P[group]] / r
    rest = np.setdiff1d(np.arange(len(P)), group)
    np.testing.assert_array_equal(sp.face[rest], ip.face[rest])
    np.testing.assert_array_equal(sp.bary[rest], ip.bary[rest])
    np.testing.assert_array_equal(sq.face, iq.face)


def test_reseat_runs_where_the_map_is_direct(monkeypatch, tosca_cat0):
    """On a real shape: the TOSCA cat against itself with the images of one leg's samples put
    on the other front leg (a misplaced limb, held by its own samples): ``orientation="prefer"``
    moves them back, and with ``RESEAT_ROUNDS = 0`` they stay."""
    from gromov.gh import ShapeMetric, _Fit, _reseat, pair_orientation

    sx = ShapeMetric(tosca_cat0, "diffusion")
    P = Q = sx.samples(100, 0)
    D = sx.distances
    sym = sx.symmetry(100, 0)
    assert sym is not None
    gm = SymmetricGMDS(sx.surface, sx.surface, P, Q)
    # the sample farthest from its own mirror image (the end of a limb) and its nearest samples
    tip = int(P[np.argmax(D[P, sym[P]])])
    r = covering_radius(sx.surface, P)
    near = np.argsort(D[tip, P])[:6]
    leg = near[D[P[near], sym[P[near]]] > 2 * r]       # those that the mirror moves off their cell
    assert len(leg) >= 3
    wrong = P.copy()
    wrong[leg] = sym[P[leg]]          # onto the mirror leg
    ip, iq = SurfacePoints.at_vertices(sx.mesh, wrong), SurfacePoints.at_vertices(sx.mesh, Q)
    ip, iq, n_iter, conv = gm.solve(ip, iq)   # GMDS alone keeps the leg where it is
    fit = _Fit(ip, iq, n_iter, conv, [], pair_orientation(sx, sx, P, Q, ip, iq))
    assert fit.orientation > 0.5

    def err(f):
        return D[f.img_p.vertex(sx.mesh.faces)[leg], P[leg]]

    assert np.median(err(fit)) > r
    monkeypatch.setattr(gh, "RESEAT_ROUNDS", 0)
    assert _reseat(sx, sx, P, Q, gm, fit) is fit
    monkeypatch.setattr(gh, "RESEAT_ROUNDS", 3)
    out = _reseat(sx, sx, P, Q, gm, fit)
    assert out is not fit and out.orientation > 0.5
    assert gm.distortion(out.img_p, out.img_q, 2.0) < gm.distortion(fit.img_p, fit.img_q, 2.0)
    assert np.max(err(out)) < 0.5 * r
