"""SearchOptions, the keywords of match that moved into it, and one answer for a shape
whether it is given as a file or as a prepared ShapeMetric."""

import dataclasses
import warnings

import numpy as np
import pytest

import gromov
from gromov import SearchOptions, ShapeMetric, match
from gromov.shapes import grid, rolled_grid

WOLF = ("wolf0.off.gz", "wolf1.off.gz")


def _same(a, b) -> None:
    """Two MatchResults with the same numbers and the same maps, bit for bit."""
    for f in ("distance", "distortion_l2", "distortion_linf", "distortion_trimmed", "ranking_distance",
              "n_iter"):
        assert getattr(a, f) == getattr(b, f), f
    assert np.array_equal(a.orientation, b.orientation, equal_nan=True)
    for f in ("x_to_y_face", "x_to_y_vertex", "y_to_x_face", "y_to_x_vertex", "pair_distortion", "history"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    np.testing.assert_array_equal(a.x_to_y_bary, b.x_to_y_bary)


@pytest.fixture(scope="module")
def sheets():
    return grid(21, 11), rolled_grid(21, 11)


def test_search_options_defaults_are_the_search_defaults(sheets):
    """SearchOptions() is match's default search, and is frozen."""
    from gromov.search import DEFAULT_COARSE_STAGES, DEFAULT_N_EXTEND, DEFAULT_N_STARTS

    s = SearchOptions()
    assert (s.n_starts, s.n_extend, s.coarse_stages) == (DEFAULT_N_STARTS, DEFAULT_N_EXTEND, DEFAULT_COARSE_STAGES)
    assert (s.search_vertices, s.extend_keep, s.signature_weight, s.max_iter, s.tol) == (None, 1.0, 1.0, 100, 1e-6)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.n_starts = 3
    assert SearchOptions(coarse_stages=[[12, None], [20, 60]]).coarse_stages == ((12, None), (20, 60))
    assert SearchOptions(coarse_stages=[(12, None), (20, 60)]).subsets == [60]
    x, y = sheets
    _same(match(x, y, "geodesic", n_samples=20, resolution=None),
          match(x, y, "geodesic", n_samples=20, resolution=None, search=SearchOptions()))


def test_search_options_refuse_bad_values():
    for bad in ({"n_starts": 0}, {"n_extend": 2.5}, {"search_vertices": True}, {"max_iter": -1},
                {"extend_keep": 0.0}, {"signature_weight": float("nan")}, {"tol": -1e-3},
                {"coarse_stages": []}, {"coarse_stages": [(12,)]}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            SearchOptions(**bad)
    with pytest.raises(TypeError, match="SearchOptions"):
        match(grid(5, 4), grid(5, 4), "geodesic", n_samples=5, resolution=None, search={"n_starts": 4})
    with pytest.raises(TypeError, match="n_start"):
        match(grid(5, 4), grid(5, 4), "geodesic", n_samples=5, resolution=None, n_start=4)


def test_old_keywords_warn_and_give_the_same_result(sheets):
    """The keywords that moved into SearchOptions still work for one release: a
    DeprecationWarning names the replacement, and the result is the same, bit for bit."""
    x, y = sheets
    old = {"n_starts": 16, "n_extend": 4, "coarse_stages": [(8, None), (12, 60)], "extend_keep": 0.8,
           "signature_weight": 0.5, "max_iter": 30, "tol": 1e-5}
    new = match(x, y, "geodesic", n_samples=20, resolution=None, search=SearchOptions(**old))
    for name, value in old.items():
        with pytest.warns(DeprecationWarning, match=rf"match\({name}=\.\.\.\).*SearchOptions\({name}=") as w:
            r = match(x, y, "geodesic", n_samples=20, resolution=None,
                      search=dataclasses.replace(SearchOptions(**old), **{name: getattr(SearchOptions(), name)}),
                      **{name: value})
        assert w[0].filename == __file__   # points at the caller
        _same(r, new)
    with pytest.warns(DeprecationWarning, match="search_vertices"):
        r = match(x, y, "geodesic", n_samples=20, resolution=None, search_vertices=60)
    _same(r, match(x, y, "geodesic", n_samples=20, resolution=None, search=SearchOptions(search_vertices=60)))
    # the ranking keywords belong to recognition (gh_matrix); still taken, with a warning
    from gromov.gh import _match

    with pytest.warns(DeprecationWarning, match="gh_matrix"):
        r = match(x, y, "diffusion", n_samples=20, resolution=None, rank_tau_scale=0.5, rank_residual="log")
    _same(r, _match(x, y, "diffusion", n_samples=20, resolution=None, rank_tau_scale=0.5, rank_residual="log"))
    assert r.ranking_distance != match(x, y, "diffusion", n_samples=20, resolution=None).ranking_distance


def test_match_pairs_and_gh_matrix_take_the_old_keywords_with_a_warning(sheets):
    from gromov.experiments.pairwise import gh_matrix, match_pairs

    x, y = sheets
    with pytest.warns(DeprecationWarning, match=r"match_pairs\(n_extend=\.\.\.\)"):
        (old,) = match_pairs([x, y], [(0, 1)], "geodesic", n_samples=15, resolution=None, n_extend=4)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        (new,) = match_pairs([x, y], [(0, 1)], "geodesic", n_samples=15, resolution=None,
                             search=SearchOptions(n_extend=4))
        m = gh_matrix([x, y], "geodesic", n_samples=15, resolution=None, search=SearchOptions(n_extend=4))
    _same(old, new)
    with pytest.warns(DeprecationWarning, match=r"gh_matrix\(n_extend=\.\.\.\)"):
        m_old = gh_matrix([x, y], "geodesic", n_samples=15, resolution=None, n_extend=4)
    np.testing.assert_array_equal(m.distance, m_old.distance)
    np.testing.assert_array_equal(m.trimmed, m_old.trimmed)


def test_a_prepared_shape_gives_the_match_of_its_file(data_dir):
    """ShapeMetric(file, "diffusion") with its default options (raw heat units, recognition's)
    handed to match gives the match of the file itself (normalised units, the
    correspondence's), bit for bit, whichever side it is on; named units are kept."""
    files = [str(data_dir / "tosca" / f) for f in WOLF]
    kw = dict(n_samples=30, resolution=800)
    want = match(*files, **kw)
    sx = ShapeMetric(files[0], "diffusion", resolution=800)
    assert sx.metric_options == {} and sx.for_correspondence().metric_options == {"units": "normalized"}
    assert sx.for_correspondence() is sx.for_correspondence()   # made once
    with warnings.catch_warnings():
        warnings.simplefilter("error")   # no warning that the two sides measure differently
        _same(match(sx, files[1], **kw), want)
        _same(match(files[0], ShapeMetric(files[1], "diffusion", resolution=800), **kw), want)
    # raw units named: kept (that ShapeMetric is its own correspondence metric), another result
    raw = ShapeMetric(files[0], "diffusion", resolution=800, metric_options={"units": "raw"})
    assert raw.for_correspondence() is raw
    other = match(raw, files[1], **kw)
    assert other.distance != want.distance
    _same(other, match(*files, metric_options={"units": "raw"}, **kw))


def test_the_package_emits_no_deprecation_warning(sheets):
    x, y = sheets
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        match(x, y, "geodesic", n_samples=15, resolution=None, search=SearchOptions(search_vertices=60))
        gromov.SearchOptions(n_starts=8)
