"""The report of ``gromov reproduce``: Voronoi cells, the correspondence figure, index.html."""

from __future__ import annotations

import copy
import re

import numpy as np
import pytest

from gromov.experiments.report import PAPER, plot_correspondence, voronoi_labels, write_report
from gromov.shapes import icosphere, torus

PNG = b"\x89PNG\r\n\x1a\n"


# ---------------------------------------------------------------------------- voronoi_labels
def test_voronoi_labels_hand_made():
    d = np.array([[0.0, 1.0, 3.0, 1.0, np.inf],
                  [2.0, 0.5, 0.0, 2.0, np.inf],
                  [4.0, 1.5, 1.0, 1.0, np.inf]])
    # column 3 ties rows 0 and 2: the smaller index wins; column 4 is unreachable
    np.testing.assert_array_equal(voronoi_labels(d), [0, 1, 1, 0, -1])
    assert voronoi_labels(d).dtype == np.int64


def test_voronoi_labels_partly_unreachable_and_one_sample():
    d = np.array([[np.inf, 2.0], [3.0, np.inf]])
    np.testing.assert_array_equal(voronoi_labels(d), [1, 0])
    np.testing.assert_array_equal(voronoi_labels([[5.0, 0.0, 1.0]]), [0, 0, 0])


def test_voronoi_labels_of_samples_are_their_own_cells():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(50, 3))
    idx = np.array([3, 17, 29, 41])
    d = np.linalg.norm(v[idx][:, None] - v[None], axis=2)
    lab = voronoi_labels(d)
    np.testing.assert_array_equal(lab[idx], np.arange(4))
    np.testing.assert_array_equal(lab, np.argmin(d, axis=0))


@pytest.mark.parametrize("bad, match", [
    (np.zeros(4), "2-D"),
    (np.zeros((2, 2, 2)), "2-D"),
    (np.zeros((0, 5)), "at least one row"),
    (np.array([[0.0, np.nan]]), "NaN"),
    (np.array([[0.0, -1.0]]), "non-negative"),
    (np.array([[0.0, -np.inf]]), "non-negative"),
])
def test_voronoi_labels_validation(bad, match):
    with pytest.raises(ValueError, match=match):
        voronoi_labels(bad)


# ---------------------------------------------------------------------------- the figure
@pytest.fixture(scope="module")
def sphere():
    return icosphere(2)


def _cells(mesh, k, seed):
    v = mesh.vertices
    idx = np.random.default_rng(seed).choice(len(v), k, replace=False)
    return voronoi_labels(np.linalg.norm(v[idx][:, None] - v[None], axis=2))


def test_plot_correspondence_writes_png(tmp_path, sphere):
    matplotlib = pytest.importorskip("matplotlib")
    backend = matplotlib.get_backend()
    lab = _cells(sphere, 12, 0)
    y = sphere.with_vertices(sphere.vertices * [2.0, 1.0, 0.5])
    out = plot_correspondence(sphere, y, lab, lab, tmp_path / "a.png", title="sphere <x>")
    assert matplotlib.get_backend() == backend  # the user's backend is left alone
    assert out == tmp_path / "a.png"
    data = out.read_bytes()
    assert data[:8] == PNG
    assert len(data) > 10_000
    # image size: 9 inches wide at the default 110 dpi
    width = int.from_bytes(data[16:20], "big")
    assert width == 990


def test_plot_correspondence_labels_change_the_image(tmp_path, sphere):
    pytest.importorskip("matplotlib")
    t = torus(24, 12)
    lx = _cells(sphere, 10, 1)
    ly = _cells(t, 10, 2)
    a = plot_correspondence(sphere, t, lx, ly, tmp_path / "a.png", dpi=60).read_bytes()
    b = plot_correspondence(sphere, t, lx, ly, tmp_path / "b.png", dpi=60).read_bytes()
    unassigned = ly.copy()
    unassigned[: len(ly) // 2] = -1
    c = plot_correspondence(sphere, t, lx, unassigned, tmp_path / "c.png", dpi=60).read_bytes()
    d = plot_correspondence(sphere, t, lx, (ly + 1) % 10, tmp_path / "d.png", dpi=60).read_bytes()
    assert a == b  # deterministic
    assert len({a, c, d}) == 3


def test_plot_correspondence_validation(tmp_path, sphere):
    lab = np.zeros(sphere.n_vertices, dtype=np.int64)
    p = tmp_path / "x.png"
    with pytest.raises(TypeError, match="x_mesh"):
        plot_correspondence(sphere.vertices, sphere, lab, lab, p)
    with pytest.raises(ValueError, match="y_labels"):
        plot_correspondence(sphere, sphere, lab, lab[:-1], p)
    with pytest.raises(TypeError, match="x_labels"):
        plot_correspondence(sphere, sphere, lab.astype(float), lab, p)
    with pytest.raises(ValueError, match="x_labels"):
        plot_correspondence(sphere, sphere, lab - 2, lab, p)
    with pytest.raises(TypeError, match="titles"):
        plot_correspondence(sphere, sphere, lab, lab, p, titles="XY")
    with pytest.raises(ValueError, match="dpi"):
        plot_correspondence(sphere, sphere, lab, lab, p, dpi=0)
    with pytest.raises(ValueError, match="view"):
        plot_correspondence(sphere, sphere, lab, lab, p, view=2 * np.eye(3))
    assert not p.exists()


# ---------------------------------------------------------------------------- index.html
def _results(figures):
    classes = ["cat", "dog", "<script>alert(1)</script>"]
    rec = {"entries": [f"{c}{i}" for c in classes for i in range(3)],
           "classes": [c for c in classes for _ in range(3)],
           "perturbed": [i > 0 for _ in classes for i in range(3)],
           "geodesic": {"eer": 0.3361, "nn_accuracy": 0.9, "ranked_by": "trimmed", "eer_gh": 0.4012},
           "diffusion": {"eer": 0.1734, "nn_accuracy": 0.95, "ranked_by": "trimmed", "eer_gh": 0.2222,
                         "errors_at_eer": {"threshold": 0.01, "false_accept": {"cat / dog": [3, 9]},
                                           "false_reject": {"dog": [1, 3], "cat": [1, 3]},
                                           "far": 0.11, "frr": 0.22}}}
    by_class = {c: {"clean": 0.02 + 0.01 * k, "weld": 0.03 + 0.01 * k, "holes": 0.04}
                for k, c in enumerate(classes)}
    return {
        "dataset": "tosca", "data": "/data/tosca", "quick": True, "date": "2026-11-30",
        "command": "gromov reproduce --quick --out 'a&b'", "seconds_total": 754.2,
        "eer": {"weld": {"geodesic": 0.3361, "diffusion": 0.1734},
                "holes": {"geodesic": 0.05, "diffusion": 0.0}},
        "recognition": {"weld": rec, "holes": copy.deepcopy(rec)},
        "correspondence": {
            "geodesic": {"clean": 0.0612, "weld": 0.0734, "holes": 0.1,
                         "by_class": copy.deepcopy(by_class)},
            "diffusion": {"clean": 0.0213, "weld": 0.0299, "holes": 0.0301,
                          "by_class": copy.deepcopy(by_class)}},
        "topkids": {"n_shapes": 3, "reference": "kid00", "handles": {"kid01": 4.5, "kid02": 3.0},
                    "geodesic": {"correspondence": 0.2345, "correspondence_direct": 0.2,
                                 "mirrored_fraction": 0.5, "relative_distance_mean": 0.07,
                                 "per_shape": {"kid01": 0.11, "kid02": 0.12}},
                    "diffusion": {"correspondence": 0.0987, "correspondence_direct": 0.09,
                                  "mirrored_fraction": 0.25, "relative_distance_mean": 0.05,
                                  "relative_trimmed_mean": 0.0321, "spearman_trimmed_vs_handles": 0.4321,
                                  "per_shape": {"kid01": 0.08, "kid02": 0.09}}},
        "timings": {"metrics": {"geodesic": 76.0, "diffusion": 32.5}, "pairs": 202.25},
        "params": {"n_samples": 100, "resolution": 3000, "tau": 0.005},
        "seeds": {"sampling": 0, "perturb": 12345},
        "versions": {"gromov": "0.1.0", "numpy": "2.1.0"},
        "figures": figures,
    }


@pytest.fixture()
def figure_dir(tmp_path, sphere):
    pytest.importorskip("matplotlib")
    lab = _cells(sphere, 8, 3)
    plot_correspondence(sphere, sphere, lab, lab, tmp_path / "corr.png", dpi=40)
    (tmp_path / "roc.png").write_bytes((tmp_path / "corr.png").read_bytes())
    return tmp_path


def _text(html):
    """The page's text without tags, data URIs and style."""
    html = re.sub(r"<style>.*?</style>", "", html, flags=re.S)
    return re.sub(r"<[^>]+>", " ", html)


def test_write_report_full(figure_dir):
    figures = {"roc_weld": "roc.png", "correspondence_diffusion_weld": "corr.png",
               "mds_holes_geodesic": "missing.png", "topkids_error_curve": "roc.png"}
    path = write_report(_results(figures), figure_dir)
    assert path == figure_dir / "index.html"
    assert sorted(p.name for p in figure_dir.glob("*.html")) == ["index.html"]
    html = path.read_text(encoding="utf-8")
    text = _text(html)
    assert html.startswith("<!DOCTYPE html>")
    # ours and the paper's numbers, in the stated formats
    for s in ("17.3%", "33.6%", "4.0%", "13.5%", "6.8%", "0.0%", "95.0%",
              "0.0268", "0.0291", "0.0514", "0.1586", "0.0213", "0.0299", "0.0612",
              "+13.3 pp", "+20.1 pp", "-1.8 pp", "0.2345", "0.0987", "kid02"):
        assert s in text, s
    # cats are compared with the paper: diffusion clean 0.02 < 0.0268 (better),
    # geodesic topology 0.03 < 0.1586 better; geodesic clean 0.02 < 0.0514 better
    assert "better than the paper" in text and "worse than the paper" in text
    assert "Worse than the paper in 4 of 10" in text
    # the ranking is said, and the other ranking's EER is beside ours
    assert "trimmed distortion" in text and "EER, GH estimate" in text and "40.1%" in text
    assert "0.0321" in text and "0.4321" in text and "trimmed distortion with the number of handles" in text
    # the handles per kid are a column of the per-shape table, not a metric
    assert not re.search(r"measure\s+diffusion\s+geodesic\s+handles", text)
    assert re.search(r"shape\s+diffusion\s+geodesic\s+handles\s+kid01\s+0.0800\s+0.1100\s+4.5", text)
    # where the errors are, for the runs that say it
    assert re.search(r"Experiment 1 \(welds\), diffusion: false acceptances \(pairs of classes\): "
                     r"cat / dog 3 of 9; false rejections \(within a class\): dog 1 of 3, cat 1 of 3",
                     text)
    assert "geodesic: false acceptances" not in text
    # captions, figures embedded, a missing one noted
    assert "ROC, Experiment 1 (welds)" in text
    assert "Correspondence, diffusion, welds" in text
    assert "TOPKIDS, error curve" in text
    assert html.count("data:image/png;base64,") == 3
    assert "missing.png not found" in text
    # self-contained, nothing external
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", html)
    assert "<link" not in html and "<script" not in html and "@import" not in html
    # escaped
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    assert "&#x27;a&amp;b&#x27;" in html
    for section in ("Recognition", "Correspondence", "TOPKIDS", "Timings",
                    "Parameters and seeds", "Versions"):
        assert f"<h2>{section}</h2>" in html
    assert "Quick run" in text and "754 s (12 min 34 s)" in text
    assert "not run" not in text


def test_write_report_ranked_by_the_gh_estimate(tmp_path):
    res = _results({})
    for exp in ("weld", "holes"):
        for m in ("geodesic", "diffusion"):
            rec = res["recognition"][exp][m]
            rec["ranked_by"] = "gh"
            rec.pop("eer_gh", None)
            rec["eer_trimmed"] = 0.0123
    text = _text(write_report(res, tmp_path).read_text(encoding="utf-8"))
    assert "ranking the pairs by the Gromov-Hausdorff estimate" in text
    assert "EER, trimmed" in text and "1.2%" in text and "EER, GH estimate" not in text


def test_write_report_figures_argument_overrides(figure_dir):
    path = write_report(_results({"roc_weld": "roc.png"}), figure_dir,
                        figures={"mds_weld_diffusion": "corr.png", "extra_plot": "corr.png"})
    html = path.read_text(encoding="utf-8")
    assert "MDS map, Experiment 1 (welds), diffusion" in html
    assert "extra plot" in html
    assert "ROC, Experiment 1 (welds)" not in html
    assert "Other figures" in html
    assert html.count("data:image/png;base64,") == 2


def test_write_report_missing_sections(tmp_path):
    res = _results({})
    res["topkids"] = None
    for key in ("recognition", "eer", "timings", "params", "seeds", "versions", "figures"):
        del res[key]
    res["correspondence"] = None
    out = tmp_path / "new" / "dir"
    html = write_report(res, out).read_text(encoding="utf-8")
    text = _text(html)
    for what in ("Recognition (Experiments 1 and 2): not run", "Correspondence: not run",
                 "TOPKIDS (SHREC'16 topological noise): not run", "Timings: not run",
                 "Parameters and seeds: not run", "Versions: not run"):
        assert html.count(what.replace("'", "&#x27;")) == 1, what
    assert "data:image" not in html
    assert "tosca" in text
    # an almost empty dict still gives a page
    html = write_report({}, tmp_path).read_text(encoding="utf-8")
    assert "not given" in html and "<h2>Versions</h2>" in html


def test_write_report_partial_numbers(tmp_path):
    res = {"dataset": "tosca", "eer": {"weld": {"diffusion": 0.04, "geodesic": None}},
           "correspondence": {"diffusion": {"clean": 0.03}}}
    text = _text(write_report(res, tmp_path).read_text(encoding="utf-8"))
    assert "same as the paper" in text  # 4.0% against 4.0%
    assert "n/a" in text  # geodesic EER missing
    assert "Worse than the paper in 1 of 2" in text  # d(C,C0) 0.0300 > 0.0268


def test_paper_numbers():
    assert PAPER["eer"]["weld"] == {"diffusion": 0.04, "geodesic": 0.135}
    assert PAPER["eer"]["holes"] == {"diffusion": 0.0, "geodesic": 0.068}
    assert PAPER["correspondence"]["diffusion"] == {"clean": 0.0268, "topology": 0.0291}
    assert PAPER["correspondence"]["geodesic"] == {"clean": 0.0514, "topology": 0.1586}


def test_write_report_validation(tmp_path):
    with pytest.raises(TypeError, match="results"):
        write_report([("eer", {})], tmp_path)
    with pytest.raises(TypeError, match="figures"):
        write_report({}, tmp_path, figures=["roc.png"])


def test_write_report_says_when_the_classes_are_not_the_papers(tmp_path):
    from gromov.experiments.report import PAPER_CLASSES, other_classes

    r = _results({})
    assert other_classes(r) == []   # no classes recorded: nothing to say
    r["params"]["experiment1"] = {c: 2 for c in PAPER_CLASSES}
    assert other_classes(r) == []
    r["params"]["experiment1"] = {"wolf": 2, "horse": 4}
    assert other_classes(r) == ["wolf", "horse"]
    text = _text(write_report(r, tmp_path).read_text())
    assert "Run on wolf, horse, not on the paper's classes (cat, dog, david, victoria)" in text
    assert other_classes({**r, "dataset": "synthetic"}) == []


def test_write_report_judges_only_on_the_papers_data(tmp_path):
    """On the synthetic set (or other TOSCA classes) the paper's column is labelled as its
    TOSCA numbers and no verdict is made."""
    r = _results({})
    judged = _text(write_report(r, tmp_path / "tosca").read_text())
    assert "better than the paper" in judged and "Worse than the paper in" in judged
    for other in ({**r, "dataset": "synthetic"},
                  {**r, "params": {**r["params"], "experiment1": {"wolf": 2, "horse": 4}}}):
        text = _text(write_report(other, tmp_path / str(id(other))).read_text())
        assert "paper (its TOSCA numbers)" in text
        assert not re.search(r"(better|worse) than the paper|same as the paper", text)
        assert "pp" not in text.split("Correspondence")[0].split("Recognition", 1)[1]
