"""ROC, equal error rate and MDS maps on hand-made distance matrices with known answers."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from gromov.experiments import recognition
from gromov.errors import GromovWarning
from gromov.experiments.recognition import (diffusion_rerank, diffusion_roc, equal_error_rate, local_roc,
                                             local_scaling, mds_map, plot_mds, plot_roc, roc)


def _matrix(n, entries):
    d = np.zeros((n, n))
    for (i, j), v in entries.items():
        d[i, j] = d[j, i] = v
    return d


# Five shapes, classes [0, 0, 0, 1, 1]. Positive pairs have distances 1, 2, 5, 7; negative
# pairs 3, 4, 5, 8, 9, 10 -- the positive (1, 2) ties the negative (1, 3) at 5.
HAND = _matrix(5, {(0, 1): 1, (0, 2): 2, (1, 2): 5, (3, 4): 7,
                   (0, 3): 3, (0, 4): 4, (1, 3): 5, (1, 4): 8, (2, 3): 9, (2, 4): 10})
HAND_LABELS = np.array([0, 0, 0, 1, 1])


def _png_size(path):
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def _separated(seed=0):
    rng = np.random.default_rng(seed)
    labels = np.repeat([0, 1, 2], 4)
    same = labels[:, None] == labels[None, :]
    d = np.where(same, rng.uniform(0.0, 1.0, (12, 12)), rng.uniform(2.0, 3.0, (12, 12)))
    d = np.triu(d, 1)
    return d + d.T, labels


# ---------------------------------------------------------------- roc / equal_error_rate


def test_hand_computed_curve_and_eer():
    r = roc(HAND, HAND_LABELS)
    assert (r.n_positive, r.n_negative) == (4, 6)
    np.testing.assert_array_equal(r.thresholds, [-np.inf, 1, 2, 3, 4, 5, 7, 8, 9, 10, np.inf])
    np.testing.assert_array_equal(r.far, np.array([0, 0, 0, 1, 2, 3, 3, 4, 5, 6, 6]) / 6)
    np.testing.assert_array_equal(r.frr, np.array([4, 3, 2, 2, 2, 1, 0, 0, 0, 0, 0]) / 4)
    # FAR - FRR: -1/6 at t = 4 (1/3, 1/2), +1/4 at t = 5 (1/2, 1/4): lambda = (1/6) / (5/12)
    # = 2/5 and EER = 1/3 + 2/5 * 1/6 = 1/2 - 2/5 * 1/4 = 2/5.
    assert r.eer == pytest.approx(0.4, abs=1e-15)
    assert r.eer_threshold == 5.0
    assert equal_error_rate(HAND, HAND_LABELS) == r.eer
    # Without the tie the crossing is a vertical step and the EER is min_t max(FAR, FRR).
    untied = HAND.copy()
    untied[1, 3] = untied[3, 1] = 6
    ru = roc(untied, HAND_LABELS)
    assert ru.eer == pytest.approx(1 / 3, abs=1e-15)
    assert ru.eer == pytest.approx(np.min(np.maximum(ru.far, ru.frr)), abs=1e-15)
    assert ru.eer_threshold == 5.0


def test_curve_is_read_only():
    r = roc(HAND, HAND_LABELS)
    with pytest.raises(ValueError, match="read-only"):
        r.far[0] = 0.5


def test_mask_keeps_only_selected_pairs():
    # Only pairs involving shape 4: negatives 4, 8, 10 and the positive 7.
    mask = np.zeros((5, 5), dtype=bool)
    mask[4, :] = mask[:, 4] = True
    r = roc(HAND, HAND_LABELS, mask=mask)
    assert (r.n_positive, r.n_negative) == (1, 3)
    np.testing.assert_array_equal(r.thresholds, [-np.inf, 4, 7, 8, 10, np.inf])
    np.testing.assert_array_equal(r.far, np.array([0, 1, 1, 2, 3, 3]) / 3)
    np.testing.assert_array_equal(r.frr, [1, 1, 0, 0, 0, 0])
    assert r.eer == pytest.approx(1 / 3, abs=1e-15)
    assert r.eer_threshold == 7.0


def test_ordered_pairs_with_symmetric_mask_give_the_same_curve():
    a, b = roc(HAND, HAND_LABELS), roc(HAND, HAND_LABELS, pairs="all")
    np.testing.assert_array_equal(a.far, b.far)
    np.testing.assert_array_equal(a.frr, b.frr)
    assert (b.n_positive, b.n_negative) == (8, 12)
    assert a.eer == b.eer


def test_separated_classes_have_zero_eer_and_monotone_rates():
    d, labels = _separated()
    r = roc(d, labels)
    assert r.eer == 0.0
    assert r.eer_threshold == d[labels[:, None] == labels[None, :]].max()
    assert np.all(np.diff(r.far) >= 0) and np.all(np.diff(r.frr) <= 0)
    assert np.all(np.diff(r.thresholds) > 0)
    assert (r.far[0], r.frr[0], r.far[-1], r.frr[-1]) == (0.0, 1.0, 1.0, 0.0)


def test_reversed_classes_have_eer_one():
    d, labels = _separated()
    off = ~np.eye(12, dtype=bool)
    r = roc(np.where(off, 10.0 - d, 0.0), labels)
    assert r.eer == 1.0


def test_constant_distances_give_one_half():
    labels = np.array([0, 0, 1, 1, 2, 2])
    r = roc(np.full((6, 6), 3.0) - 3.0 * np.eye(6), labels)
    np.testing.assert_array_equal(r.thresholds, [-np.inf, 3.0, np.inf])
    assert r.eer == 0.5
    assert r.eer_threshold == 3.0


def test_random_distances_give_about_one_half():
    rng = np.random.default_rng(1)
    d = np.triu(rng.uniform(size=(80, 80)), 1)
    labels = rng.integers(0, 4, 80)
    assert abs(equal_error_rate(d + d.T, labels) - 0.5) < 0.05


def test_eer_is_invariant_under_increasing_transforms():
    d, labels = _separated(seed=3)
    rng = np.random.default_rng(3)
    noisy = d + np.triu(rng.uniform(0, 2.5, d.shape), 1)
    noisy = np.triu(noisy, 1) + np.triu(noisy, 1).T
    e = equal_error_rate(noisy, labels)
    assert 0 < e < 0.5
    assert equal_error_rate(np.exp(noisy) * 7 + 1, labels) == pytest.approx(e, abs=1e-15)


def test_roc_errors():
    with pytest.raises(ValueError, match=r"square \(n, n\).*\(3, 4\)"):
        roc(np.zeros((3, 4)), [0, 0, 1])
    with pytest.raises(ValueError, match="finite, got 2 NaN"):
        d = HAND.copy()
        d[0, 1] = d[1, 0] = np.nan
        roc(d, HAND_LABELS)
    with pytest.raises(ValueError, match="symmetric, got max"):
        d = HAND.copy()
        d[0, 1] += 1e-3
        roc(d, HAND_LABELS)
    with pytest.raises(ValueError, match=r"labels.*length n = 5, got shape \(4,\)"):
        roc(HAND, [0, 0, 1, 1])
    with pytest.raises(ValueError, match="pairs must be 'upper' or 'all', got 'lower'"):
        roc(HAND, HAND_LABELS, pairs="lower")
    with pytest.raises(ValueError, match=r"mask must be a boolean.*shape \(4, 4\)"):
        roc(HAND, HAND_LABELS, mask=np.ones((4, 4), dtype=bool))
    with pytest.raises(ValueError, match="dtype int"):
        roc(HAND, HAND_LABELS, mask=np.ones((5, 5), dtype=int))
    with pytest.raises(ValueError, match="got 0 positive and 10 negative"):
        roc(HAND, [0, 1, 2, 3, 4])
    with pytest.raises(ValueError, match="got 10 positive and 0 negative"):
        equal_error_rate(HAND, [7] * 5)


def test_tiny_asymmetry_is_tolerated():
    d = HAND.copy()
    d[0, 1] += 1e-12
    assert roc(d, HAND_LABELS).n_positive == 4


# ---------------------------------------------------------------- mds_map


def _pairwise(x):
    return np.linalg.norm(x[:, None, :] - x[None, :, :], axis=-1)


def test_errors_at_names_the_confused_classes():
    """Three classes; only b and c overlap: b2 is closer to c0 than to its own class."""
    from gromov.experiments.recognition import errors_at

    lab = ["a", "a", "b", "b", "b", "c", "c"]
    pos = np.array([0.0, 0.1, 5.0, 5.2, 6.4, 6.0, 6.1])     # points on a line
    D = np.abs(pos[:, None] - pos[None, :])
    r = roc(D, lab)
    e = errors_at(D, lab, r.eer_threshold)
    assert e["threshold"] == r.eer_threshold
    assert set(e["false_accept"]) <= {"b / c"} and "a / b" not in e["false_accept"]
    # counts agree with the rates of the ROC at that threshold
    k = int(np.searchsorted(r.thresholds, r.eer_threshold))
    fa = sum(v[0] for v in e["false_accept"].values())
    fr = sum(v[0] for v in e["false_reject"].values())
    assert e["far"] == pytest.approx(r.far[k]) == pytest.approx(fa / r.n_negative)
    assert e["frr"] == pytest.approx(r.frr[k]) == pytest.approx(fr / r.n_positive)
    assert e["false_accept"]["b / c"][1] == 6    # 3 x 2 cross pairs
    # hand count at t = 0.25: no false acceptance (the closest b-c pair is at 0.3); b's
    # pairs at 1.2 and 1.4 rejected
    e = errors_at(D, lab, 0.25)
    assert e["false_accept"] == {} and e["far"] == 0.0
    assert e["false_reject"] == {"b": [2, 3]} and e["frr"] == pytest.approx(2 / 5)
    # at t = 0.5: b4-c0 (0.4), b4-c1 (0.3) accepted; at 1.3 all six b-c pairs, and only
    # b0-b4 (1.4) rejected
    assert errors_at(D, lab, 0.5)["false_accept"] == {"b / c": [2, 6]}
    e = errors_at(D, lab, 1.3)
    assert e["false_accept"] == {"b / c": [6, 6]} and e["false_reject"] == {"b": [1, 3]}
    mask = np.zeros((7, 7), bool)
    mask[0, 1] = mask[1, 0] = True
    assert errors_at(D, lab, 0.05, mask=mask)["false_reject"] == {"a": [1, 1]}
    with pytest.raises(ValueError, match="labels"):
        errors_at(D, lab[:3], 1.0)
    # labels of any type roc() takes, e.g. an object array
    obj = np.array(lab, dtype=object)
    assert errors_at(D, obj, 1.3) == errors_at(D, lab, 1.3)


# ---------------------------------------------------------------- local_scaling


def test_local_scaling_by_hand():
    """D'_ij = D_ij / sqrt(s_i s_j), s_i the distance to the k-th nearest other shape."""
    # k = 1: the row minima of HAND are 1, 1, 2, 3, 4
    s = np.array([1.0, 1.0, 2.0, 3.0, 4.0])
    got = local_scaling(HAND, 1)
    assert got[0, 1] == 1.0 and got[0, 2] == pytest.approx(2 / np.sqrt(2))
    assert got[3, 4] == pytest.approx(7 / np.sqrt(12)) and got[2, 4] == pytest.approx(10 / np.sqrt(8))
    assert np.allclose(got, HAND / np.sqrt(np.outer(s, s)) * (1 - np.eye(5)))
    # k = 2: the second smallest of each row's other entries: 2, 5, 5, 5, 7
    s2 = np.array([2.0, 5.0, 5.0, 5.0, 7.0])
    assert np.allclose(local_scaling(HAND, 2), HAND / np.sqrt(np.outer(s2, s2)))
    got = local_scaling(HAND, 3)
    assert np.array_equal(got, got.T) and np.all(np.diag(got) == 0)
    # dimensionless: a common unit cancels
    assert np.allclose(local_scaling(7.5 * HAND, 2), local_scaling(HAND, 2))


def test_local_scaling_undoes_half_of_a_shape_wide_inflation():
    """Two classes on a line; every distance of shape 0 is inflated c = 4 times (as a weld
    moves a whole row of the diffusion distances). One threshold no longer separates the
    classes; after local scaling it does again. Where the other shape's scale is untouched
    (class b: shape 0 is not among its k nearest) the inflation is exactly sqrt(c)."""
    pos = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 2.0, 2.1, 2.2, 2.3, 2.4])
    lab = np.repeat(["a", "b"], 5)
    D = np.abs(pos[:, None] - pos[None, :])
    c = 4.0
    Dc = D.copy()
    Dc[0, :] *= c
    Dc[:, 0] *= c
    assert equal_error_rate(D, lab) == 0.0 and equal_error_rate(Dc, lab) > 0.0
    assert equal_error_rate(local_scaling(Dc, 2), lab) == 0.0
    ratio = local_scaling(Dc, 2)[0, 5:] / local_scaling(D, 2)[0, 5:]
    assert np.allclose(ratio, np.sqrt(c))


def test_local_scaling_of_coincident_shapes_and_errors():
    # shapes 0 and 1 coincide: k = 1 gives them scale 0, replaced by the smallest positive
    # distance (1), so every entry stays finite; an all-zero matrix stays zero
    D = _matrix(3, {(0, 1): 0.0, (0, 2): 1.0, (1, 2): 1.0})
    got = local_scaling(D, 1)
    assert np.all(np.isfinite(got)) and got[0, 1] == 0.0 and got[0, 2] == pytest.approx(1.0)
    assert np.array_equal(local_scaling(np.zeros((3, 3)), 2), np.zeros((3, 3)))
    for k in (0, 5, True, 2.0, "2"):
        with pytest.raises(ValueError, match="k must be an integer"):
            local_scaling(HAND, k)
    with pytest.raises(ValueError, match="non-negative"):
        local_scaling(-HAND, 1)
    with pytest.raises(ValueError, match="symmetric"):
        local_scaling(np.triu(HAND), 1)


def test_local_roc_caps_k_and_warns_when_it_reaches_beyond_the_smallest_class():
    # HAND: classes of 3 and 2 shapes
    curve, scaled, k = local_roc(HAND, HAND_LABELS, 1)
    assert k == 1 and np.array_equal(scaled, local_scaling(HAND, 1))
    assert curve.eer == roc(local_scaling(HAND, 1), HAND_LABELS).eer
    with pytest.warns(GromovWarning, match=r"k = 2 is not below the smallest class \(2 shapes\)"):
        local_roc(HAND, HAND_LABELS, 2)
    with pytest.warns(GromovWarning, match="k = 4"):        # 9 is capped at n - 1 = 4
        _, scaled, k = local_roc(HAND, HAND_LABELS, 9)
    assert k == 4 and np.array_equal(scaled, local_scaling(HAND, 4))
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        local_roc(HAND, HAND_LABELS, 9, warn=False)
    for bad in (0, True, 1.5):
        with pytest.raises(ValueError, match="positive integer"):
            local_roc(HAND, HAND_LABELS, bad)


def test_diffusion_rerank_by_hand():
    """D'' = max A - A for A = P A P^T from A = P, P the row-normalised affinities
    exp(-D'^2) on each shape's k nearest and itself, D' locally scaled: a loop over the entries
    gives the same matrix; a common unit cancels; no shape order is read."""
    rng = np.random.default_rng(4)
    x = rng.normal(size=(9, 3))
    D = _pairwise(x)
    n, k, kk = 9, 3, 2
    s = np.sort(D + np.diag(np.full(n, np.inf)), axis=1)[:, kk - 1]   # each shape's scale
    W = np.array([[np.exp(-D[i, j] ** 2 / (s[i] * s[j])) if i != j else 1.0 for j in range(n)]
                  for i in range(n)])
    P = np.zeros((n, n))
    for i in range(n):
        keep = np.argsort(-W[i])[:k + 1]
        P[i, keep] = W[i, keep] / W[i, keep].sum()
    A = P.copy()
    for _ in range(2):
        A = P @ A @ P.T
    A = 0.5 * (A + A.T)
    want = A.max() - A
    np.fill_diagonal(want, 0.0)
    got = diffusion_rerank(D, k, 3, scale_k=kk)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
    assert np.array_equal(got, got.T) and np.all(got >= 0) and np.all(np.diag(got) == 0)
    np.testing.assert_allclose(diffusion_rerank(3.5 * D, k, 3, scale_k=kk), got, rtol=1e-12, atol=1e-15)
    perm = rng.permutation(n)
    np.testing.assert_allclose(diffusion_rerank(D[np.ix_(perm, perm)], k, 3, scale_k=kk),
                               got[np.ix_(perm, perm)], rtol=1e-12, atol=1e-15)
    # one step is the walk's own affinities
    np.testing.assert_allclose(diffusion_rerank(D, k, 1, scale_k=kk),
                               (lambda B: (B.max() - B) * (1 - np.eye(n)))(0.5 * (P + P.T)), rtol=1e-12)


def test_diffusion_rerank_joins_a_stretched_class_that_one_threshold_splits():
    """Two classes, each a chain of shapes along a line (each close to the next, its ends far
    apart: a class whose shapes are not isometric), the chains side by side nearer each
    other than a chain's two ends are. No threshold of D separates them (the far ends of one
    chain are farther apart than the two chains); after the diffusion one does: the walk stays
    in its chain. The EER of :func:`diffusion_roc` is that of the re-ranked matrix."""
    t = np.linspace(0.0, 6.0, 10)
    x = np.r_[np.c_[t, np.zeros(10)], np.c_[t + 0.05 * np.arange(10) ** 1.3, np.full(10, 4.0)]]
    lab = np.repeat(["a", "b"], 10)
    D = _pairwise(x)
    assert equal_error_rate(D, lab) > 0.1
    curve, reranked, k = diffusion_roc(D, lab, 3, 4)
    assert k == 3 and curve.eer == 0.0 and equal_error_rate(reranked, lab) == 0.0
    same = (lab[:, None] == lab[None]) & ~np.eye(20, dtype=bool)
    assert reranked[lab[:, None] != lab[None]].min() > reranked[same].max()
    np.testing.assert_array_equal(reranked, diffusion_rerank(D, 3, 4))
    assert equal_error_rate(local_scaling(D, 4), lab) > 0.0   # local scaling alone does not
    with pytest.warns(GromovWarning, match=r"k = 4 is not below the smallest class \(2 shapes\)"):
        _, reranked, k = diffusion_roc(HAND, HAND_LABELS, 8)
    assert k == 4 and np.array_equal(reranked, diffusion_rerank(HAND, 4))   # capped at n - 1
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        diffusion_roc(HAND, HAND_LABELS, 1)
        diffusion_roc(HAND, HAND_LABELS, 8, warn=False)


def test_diffusion_rerank_errors():
    for name, kw in (("k", {"k": 0}), ("k", {"k": 5}), ("k", {"k": True}), ("steps", {"k": 2, "steps": 0}),
                     ("steps", {"k": 2, "steps": 1.5}), ("scale_k", {"k": 2, "scale_k": 5})):
        with pytest.raises(ValueError, match=f"{name} must be"):
            diffusion_rerank(HAND, **kw)
    with pytest.raises(ValueError, match="non-negative"):
        diffusion_rerank(-HAND, 1)
    with pytest.raises(ValueError, match="symmetric"):
        diffusion_rerank(np.triu(HAND), 1)
    with pytest.raises(ValueError, match="positive integer"):
        diffusion_roc(HAND, HAND_LABELS, 0)


def test_mds_recovers_a_planar_configuration():
    x = np.random.default_rng(0).normal(size=(15, 2)) * [3.0, 1.0]
    d = _pairwise(x)
    y = mds_map(d, 2)
    assert y.shape == (15, 2)
    np.testing.assert_allclose(_pairwise(y), d, atol=1e-9)
    np.testing.assert_allclose(y.mean(axis=0), 0, atol=1e-12)
    cov = y.T @ y
    assert cov[0, 0] > cov[1, 1] and abs(cov[0, 1]) < 1e-9  # principal axes, in order
    big = np.argmax(np.abs(y), axis=0)
    assert np.all(y[big, [0, 1]] > 0)  # sign convention
    np.testing.assert_array_equal(mds_map(d, 2), y)


def test_mds_of_a_rigid_motion_is_the_same_map():
    x = np.random.default_rng(2).normal(size=(10, 3))
    c, s = np.cos(0.7), np.sin(0.7)
    moved = x @ np.array([[c, -s, 0], [s, c, 0], [0, 0, -1]]) + [5.0, -2.0, 1.0]
    np.testing.assert_allclose(mds_map(_pairwise(moved), 3), mds_map(_pairwise(x), 3),
                               atol=1e-9)


def test_mds_iterative_path_matches_dense(monkeypatch):
    x = np.random.default_rng(4).normal(size=(40, 2)) * [2.0, 1.0]
    d = _pairwise(x)
    dense = mds_map(d, 2)
    monkeypatch.setattr(recognition, "_DENSE_MAX", 10)
    np.testing.assert_allclose(mds_map(d, 2, seed=5), dense, atol=1e-9)


def test_mds_errors():
    with pytest.raises(ValueError, match=r"dim must be an integer in \[1, n = 5\], got 6"):
        mds_map(HAND, 6)
    with pytest.raises(ValueError, match="got 0"):
        mds_map(HAND, 0)
    with pytest.raises(ValueError, match=r"got 2\.0"):
        mds_map(HAND, 2.0)
    with pytest.raises(ValueError, match="square"):
        mds_map(np.zeros(4))
    with pytest.raises(ValueError, match="symmetric"):
        mds_map(np.triu(HAND))


# ---------------------------------------------------------------- plots


def _colours(path):
    from matplotlib.image import imread

    img = imread(path)[..., :3]
    return np.unique((img.reshape(-1, 3) * 255).round().astype(int), axis=0)


def _has_colour(colours, rgb, tol=3):
    target = (np.asarray(rgb[:3]) * 255).round()
    return bool(np.any(np.all(np.abs(colours - target) <= tol, axis=1)))


def test_plot_roc_writes_a_png_of_the_requested_size(tmp_path):
    pytest.importorskip("matplotlib")
    from matplotlib import colormaps

    d, labels = _separated()
    curves = {"separated": roc(d, labels), "hand": roc(HAND, HAND_LABELS)}
    out = plot_roc(curves, tmp_path / "roc.png", figsize=(6, 4), dpi=50, title="ROC")
    assert out == tmp_path / "roc.png"
    assert _png_size(out) == (300, 200)
    colours = _colours(out)
    # Default property cycle: the first two curves are tab:blue and tab:orange.
    assert _has_colour(colours, colormaps["tab10"](0))
    assert _has_colour(colours, colormaps["tab10"](1))
    single = plot_roc(roc(HAND, HAND_LABELS), str(tmp_path / "one.png"))
    assert _png_size(single) == (500, 400)


def test_plot_mds_colours_classes(tmp_path):
    pytest.importorskip("matplotlib")
    from matplotlib import colormaps

    d, labels = _separated()
    coords = mds_map(d, 2)
    marked = np.arange(12) % 4 == 0
    out = plot_mds(coords, labels, tmp_path / "mds.png", marked=marked, title="MDS",
                   figsize=(4, 3), dpi=80)
    assert _png_size(out) == (320, 240)
    colours = _colours(out)
    for c in range(3):
        assert _has_colour(colours, colormaps["tab10"](c))
    assert not _has_colour(colours, colormaps["tab10"](3))  # only three classes drawn


def test_plot_errors(tmp_path):
    pytest.importorskip("matplotlib")
    with pytest.raises(ValueError, match="at least one ROC, got an empty mapping"):
        plot_roc({}, tmp_path / "x.png")
    with pytest.raises(TypeError, match="'a' must be a ROC, got float"):
        plot_roc({"a": 0.3}, tmp_path / "x.png")
    with pytest.raises(ValueError, match=r"coords must have shape \(n, 2\), got \(5, 3\)"):
        plot_mds(np.zeros((5, 3)), HAND_LABELS, tmp_path / "x.png")
    with pytest.raises(ValueError, match="coords must be finite"):
        plot_mds(np.full((5, 2), np.nan), HAND_LABELS, tmp_path / "x.png")
    with pytest.raises(ValueError, match=r"labels.*length n = 5"):
        plot_mds(np.zeros((5, 2)), [0, 1], tmp_path / "x.png")
    with pytest.raises(ValueError, match=r"marked must be a boolean array of shape \(5,\)"):
        plot_mds(np.zeros((5, 2)), HAND_LABELS, tmp_path / "x.png", marked=[1, 0, 0, 0, 0])
    assert not (tmp_path / "x.png").exists()

