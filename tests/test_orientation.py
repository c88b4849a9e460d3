"""Orientation of correspondences: coherent winding, outward normals, the agreement measure,
and ``match(..., orientation="prefer")``."""

import numpy as np
import pytest

import gromov
from gromov import Mesh, match
from gromov.evaluate import correspondence_error
from gromov.experiments.reproduce import reflection_map
from gromov.gh import ShapeMetric
from gromov.orientation import (coherent_faces, is_consistently_oriented, orientation_agreement,
                                outward_normals)
from gromov.shapes import grid, icosphere


def _ellipsoid():
    s = icosphere(3)
    return Mesh(s.vertices * [1.0, 1.7, 2.6] + [0.3, -0.2, 0.5], s.faces)


def test_coherent_faces_rewinds_flipped_faces():
    e = _ellipsoid()
    assert is_consistently_oriented(e)
    f = np.array(e.faces)
    flipped = np.r_[3, 17, 18, 200]
    f[flipped] = f[flipped][:, ::-1]
    bad = Mesh(e.vertices, f)
    assert not is_consistently_oriented(bad)
    faces, ok = coherent_faces(bad)
    assert ok and is_consistently_oriented(Mesh(e.vertices, faces))
    # the majority winding of the piece may lose; each face is either all kept or all flipped
    same = np.all(faces == e.faces, axis=1)
    assert same.all() or (~same).all()


def test_outward_normals_point_out_whatever_the_winding():
    e = _ellipsoid()
    centre = e.vertices.mean(axis=0)
    for faces in (e.faces, e.faces[:, ::-1]):
        n, ok = outward_normals(Mesh(e.vertices, faces))
        assert ok
        assert np.all(np.einsum("ij,ij->i", n, e.vertices - centre) > 0)
        np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0)
    # an open flat sheet encloses nothing: its faces' own winding decides
    g = grid(11, 6)
    for faces, sign in ((g.faces, 1.0), (g.faces[:, ::-1], -1.0)):
        n, ok = outward_normals(Mesh(g.vertices, faces))
        fn = Mesh(g.vertices, faces).face_normals[0]
        assert ok and np.all(sign * n @ g.face_normals[0] > 0.99) and np.all(n @ fn > 0.99)


def test_agreement_is_one_for_rigid_maps_and_zero_for_mirrors():
    e = _ellipsoid()
    idx = gromov.farthest_point_sampling(np.linalg.norm(e.vertices[:, None] - e.vertices[None], axis=-1),
                                         40, seed=0).indices
    x, (n, _) = e.vertices[idx], outward_normals(e)
    dx = np.linalg.norm(x[:, None] - x[None], axis=-1)
    rot = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))[0]
    rot *= np.sign(np.linalg.det(rot))  # a rotation
    moved = Mesh(e.vertices @ rot.T + 5.0, e.faces)
    nm, _ = outward_normals(moved)
    assert orientation_agreement(x, n[idx], dx, moved.vertices[idx], nm[idx]) == 1.0
    # a reflection, with the faces re-wound so that the mirror image is outward-oriented too
    mirror = Mesh(e.vertices * [-1.0, 1.0, 1.0], e.faces[:, ::-1])
    nr, _ = outward_normals(mirror)
    assert orientation_agreement(x, n[idx], dx, mirror.vertices[idx], nr[idx]) == 0.0
    # a scrambled map keeps about half
    perm = np.random.default_rng(2).permutation(len(idx))
    a = orientation_agreement(x, n[idx], dx, moved.vertices[idx][perm], nm[idx][perm])
    assert 0.3 < a < 0.7


def test_a_partial_flip_has_an_agreement_near_one_half():
    """A map that is direct on one half of a symmetric shape and mirrored on the other (one leg
    sent to the other side) keeps the orientation of about half the sample triangles, within
    ``DIRECT_MARGIN`` of 1/2: ``orientation="prefer"`` does not take it for a clearly direct map."""
    s = icosphere(3)
    e = Mesh(s.vertices * [1.0, 1.7, 2.6], s.faces)  # symmetric under x -> -x, y -> -y, z -> -z
    idx = gromov.farthest_point_sampling(np.linalg.norm(e.vertices[:, None] - e.vertices[None], axis=-1),
                                         60, seed=0).indices
    x, (n, _) = e.vertices[idx], outward_normals(e)
    dx = np.linalg.norm(x[:, None] - x[None], axis=-1)
    # the mirror image of each vertex across the plane z = 0 (a vertex of the same mesh)
    mirror = np.argmin(np.linalg.norm(e.vertices[:, None] * [1, 1, -1] - e.vertices[None], axis=-1), axis=1)
    assert np.allclose(e.vertices[mirror], e.vertices * [1, 1, -1])
    upper = x[:, 1] > 0  # half the shape (about y), mirrored across z = 0; the other half kept
    img = np.where(upper, mirror[idx], idx)
    a = orientation_agreement(x, n[idx], dx, e.vertices[img], n[img])
    assert abs(a - 0.5) < gromov.gh.DIRECT_MARGIN
    assert orientation_agreement(x, n[idx], dx, e.vertices[mirror[idx]], n[mirror[idx]]) == 0.0


def test_prefer_does_not_take_a_partial_flip_for_the_direct_map(held_out_pair):
    """horse0 -> horse6 with three welds (held-out class, built as ``gromov reproduce`` builds
    it), default diffusion metric: the lowest-distortion map found is mirrored, and among the
    orientation-preserving alternatives the lowest is a partial flip (agreement 0.54, d(C, C0)
    0.097, which a rule accepting any agreement above 1/2 returns as "direct"). A clearly direct
    map (agreement above 1/2 +
    ``DIRECT_MARGIN``) is preferred to it; here the mirrored map composed with a reflection
    gives one, and it is right."""
    from gromov.experiments.reproduce import _pair_quality

    shapes, ref, welded, x, y = held_out_pair("horse", "horse6+weld3")
    r = match(x, y, "diffusion")
    assert abs(r.orientation - 0.5) > gromov.gh.DIRECT_MARGIN
    assert _pair_quality(r, shapes, ref, welded)["best"] < 0.05


def test_prefer_warns_and_ignores_on_a_non_orientable_mesh():
    # a Moebius strip: a 12 x 2 grid of quads whose ends are glued with a half twist
    nu = 12
    t = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    w = np.array([-0.3, 0.3])
    ang = t[:, None] / 2
    pts = np.stack([(1 + w * np.cos(ang)) * np.cos(t)[:, None], (1 + w * np.cos(ang)) * np.sin(t)[:, None],
                    w * np.sin(ang) + 0 * t[:, None]], axis=-1).reshape(-1, 3)
    faces = []
    for i in range(nu):
        a0, a1 = 2 * i, 2 * i + 1
        if i < nu - 1:
            b0, b1 = 2 * i + 2, 2 * i + 3
        else:
            b0, b1 = 1, 0  # the half twist
        faces += [[a0, b0, a1], [a1, b0, b1]]
    strip = Mesh(pts, np.array(faces))
    assert not outward_normals(strip)[1]
    s = ShapeMetric(strip, "euclidean", resolution=None)
    with pytest.warns(gromov.GromovWarning, match="orientable"):
        r = match(s, s, "euclidean", n_samples=8, resolution=None, orientation="prefer")
    assert np.isnan(r.orientation)
    with pytest.raises(ValueError, match="orientation"):
        match(s, s, "euclidean", n_samples=8, orientation="sideways")


def test_prefer_returns_the_direct_map_on_the_tosca_cat(data_dir):
    """cat0 -> cat1 with the geodesic metric and the default search (``extend_keep=1``): the
    lowest-distortion map found is the mirrored one;
    ``orientation="prefer"`` (the default) returns the direct one, with about the same
    distortion, and says so. (With ``extend_keep=0.7`` or with the signature-guided coarse
    stages, which are on by default, the search finds the direct map first on this pair, which
    would not exercise the preference: both are off here.)"""
    x = ShapeMetric(gromov.load(data_dir / "tosca" / "cat0.off.gz"), "geodesic")
    y = ShapeMetric(gromov.load(data_dir / "tosca" / "cat1.off.gz"), "geodesic")
    mirror = reflection_map(x.input)
    search = gromov.SearchOptions(extend_keep=1.0, signature_weight=0.0)
    plain = match(x, y, "geodesic", orientation="ignore", search=search)
    kept = match(x, y, "geodesic", search=search)  # orientation="prefer"
    e_plain = correspondence_error(plain, y, symmetry=mirror)
    e_kept = correspondence_error(kept, y, symmetry=mirror)
    assert e_plain.branch == "mirrored" and plain.orientation < 0.5
    assert e_kept.branch == "direct" and kept.orientation > 0.5
    assert e_kept.mean < 0.05 < e_kept.mirrored_mean
    assert kept.distortion_l2 <= (1 + gromov.gh.ORIENTATION_TOL) * plain.distortion_l2


class _Images:
    """A stand-in for a start's images: a label whose distortion the fake GMDS knows."""

    def __init__(self, label):
        self.label = label

    def vertex(self, faces):
        return np.zeros(1, dtype=np.int64)


class _FakeGMDS:
    """GMDS for the rule alone: a start's run returns its own images; distortions given."""

    def __init__(self, distortions):
        self.distortions, self.history = distortions, []

    def solve(self, img_p, img_q):
        return img_p, img_q, 1, True

    def distortion(self, img_p, img_q, norm):
        return self.distortions[img_p.label]


@pytest.mark.parametrize("ratio, agreement, direct", [
    (1.05, 0.90, True),    # within ORIENTATION_TOL: the preserving start's map, as always
    (1.15, 0.90, True),    # beyond it, within FLIP_TOL, clearly direct, nothing else: taken
    (1.15, 0.60, False),   # direct only just: the mirrored map stays
    (1.30, 0.90, False),   # beyond FLIP_TOL: the mirrored map stays
])
def test_prefer_falls_back_on_a_clearly_direct_map_within_flip_tol(monkeypatch, ratio, agreement, direct):
    """``orientation="prefer"`` for a mirrored first map whose reflections give nothing (none
    found): the best orientation-preserving start's map is kept within ``ORIENTATION_TOL`` of
    the mirrored map's distortion and, failing every other alternative, when it is clearly
    direct (agreement above 1/2 + ``DIRECT_MARGIN``) within ``FLIP_TOL`` -- a body against its
    own copy at another density, where the two meshes disagree by more than the body's
    asymmetry."""
    from types import SimpleNamespace

    from gromov.gh import _Fit, _prefer_direct

    monkeypatch.setattr(gromov.gh, "pair_orientation",
                        lambda sx, sy, P, Q, p, q: agreement if p.label == "alt" else 0.1)
    shape = SimpleNamespace(distances=None, mesh=SimpleNamespace(faces=None), symmetry=lambda n, seed: None)
    gm = _FakeGMDS({"first": 1.0, "alt": ratio})
    first = _Fit(_Images("first"), _Images("first"), orientation=0.1)
    candidates = ([(_Images("alt"), _Images("alt"))], np.array([0.9]), np.array([ratio]))
    kept = _prefer_direct(shape, shape, None, None, gm, candidates, first, 100, 0)
    assert (kept.img_p.label == "alt") == direct
    assert (kept.orientation > 0.5) == direct


@pytest.mark.parametrize("mirrored_mismatch, turned", [(0.7, True), (0.95, False)])
def test_prefer_undoes_a_half_turn_through_a_reflection(monkeypatch, mirrored_mismatch, turned):
    """``orientation="prefer"`` for a direct first map: when no clearly direct start keeps the
    smoothed curvature better by ``TURN_MARGIN`` but a clearly mirrored start within
    ``TURN_TOL`` does, that start composed with a reflection (which keeps the curvature) is run,
    and its map replaces the first one when it is clearly direct and within both tolerances."""
    from types import SimpleNamespace

    from gromov.gh import _Fit, _prefer_curvature

    orientations = {"first": 0.85, "direct": 0.85, "mirrored": 0.15, "turned": 0.85}
    mismatches = {"first": 1.0, "direct": 0.98, "mirrored": mirrored_mismatch, "turned": mirrored_mismatch}
    monkeypatch.setattr(gromov.gh, "pair_orientation", lambda sx, sy, P, Q, p, q: orientations[p.label])
    monkeypatch.setattr(gromov.gh, "curvature_mismatch", lambda sx, sy, P, Q, p, q: mismatches[p.label])
    monkeypatch.setattr(gromov.gh, "_reflected",
                        lambda sx, sy, P, Q, p, q, n, seed: iter([(_Images("turned"), _Images("turned"))]))
    shape = SimpleNamespace()
    gm = _FakeGMDS({"first": 1.0, "direct": 1.02, "mirrored": 1.01, "turned": 1.03})
    first = _Fit(_Images("first"), _Images("first"), orientation=0.85)
    starts = [(_Images("direct"), _Images("direct")), (_Images("mirrored"), _Images("mirrored"))]
    candidates = (starts, np.array([0.85, 0.15]), np.array([1.02, 1.01]))
    kept = _prefer_curvature(shape, shape, None, None, gm, candidates, first, 100, 0)
    assert kept.img_p.label == ("turned" if turned else "first")


def test_symmetry_of_an_ellipsoid_is_a_reflection():
    """With Euclidean distances an ellipsoid's orientation-reversing isometries are its three
    plane reflections and the point reflection: the map found keeps the distances, reverses
    the orientation and is an involution."""
    from gromov.gh import pair_orientation
    from gromov.gmds import SurfacePoints

    s = ShapeMetric(_ellipsoid(), "euclidean", resolution=None)
    S = s.symmetry(40, 0)
    assert S is not None and S.shape == (s.mesh.n_vertices,)
    D = s.distances
    P = s.samples(40, 0)
    err = np.abs(D[np.ix_(S[P], S[P])] - D[np.ix_(P, P)])
    edge = s.mesh.mean_edge_length
    assert np.median(err) < 2 * edge
    assert np.median(D[S[S], np.arange(len(S))]) < 2 * edge
    at = SurfacePoints.at_vertices(s.mesh, S[P])
    assert pair_orientation(s, s, P, P, at, at) < 0.2


def test_symmetry_of_the_tosca_wolf_is_its_left_right_reflection(data_dir):
    """A reflection is its own inverse. Without that check the wolf's diffusion self-map sent
    a sixth of the vertices to the wrong leg (17.5% farther than 5% of the bounding box's
    diagonal from the left/right mirror); with it (``INVOLUTION_TOL``) 1.3%."""
    s = ShapeMetric(gromov.load(data_dir / "tosca" / "wolf0.off.gz"), "diffusion")
    S = s.symmetry(100, 0)
    assert S is not None
    V = s.mesh.vertices
    diag = np.linalg.norm(V.max(0) - V.min(0))
    mirrored = V * [-1, 1, 1] + [V[:, 0].max() + V[:, 0].min(), 0, 0]  # wolf0: the plane x = centre
    wrong = np.linalg.norm(V[S] - mirrored, axis=1) > 0.05 * diag
    assert wrong.mean() < 0.05
    back = np.linalg.norm(V[S[S]] - V, axis=1) > 0.05 * diag
    assert back.mean() < 0.05
