"""The first run after an install compiles numba kernels: the CLI says so, once."""

import numpy as np
from numba import njit


def test_the_cli_says_once_when_kernels_compile(capsys):
    from gromov.cli import _announce_compilation

    from numba.core import event

    note = _announce_compilation()

    @njit
    def twice(a):
        return 2 * a

    @njit
    def thrice(a):
        return 3 * a

    try:
        assert twice(np.arange(3)).tolist() == [0, 2, 4] and thrice(1.0) == 3.0
    finally:
        event.unregister("numba:compile", note)
    assert capsys.readouterr().err == "gromov: compiling kernels, first run only\n"


def test_import_and_help_load_no_heavy_module():
    """``import gromov`` and ``gromov --help`` do not wait for numba, scipy or the kernels."""
    import subprocess
    import sys

    code = ("import sys, contextlib, io, gromov\n"
            "heavy = ('numba', 'scipy', 'gromov.gh', 'gromov.shape_metric', 'gromov.metrics')\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in heavy or m in heavy))\n"
            "from gromov.cli import main\n"
            "with contextlib.suppress(SystemExit), contextlib.redirect_stdout(io.StringIO()):\n"
            "    main(['--help'])\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('numba', 'scipy')\n"
            "             or m.startswith(('gromov.gh', 'gromov.shape_metric', 'gromov.metrics',\n"
            "                              'gromov.perturb'))))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.splitlines() == ["[]", "[]"], out
    import gromov

    assert gromov.match.__module__ == "gromov.gh" and "match" in dir(gromov)


def test_the_prepared_shape_and_the_result_keep_their_old_import_path():
    """``ShapeMetric`` and ``MatchResult`` live in gromov.shape_metric and gromov.match_result;
    code and pickles that name them in gromov.gh, where they were defined before, still find them."""
    import pickle

    import gromov
    import gromov.gh as gh
    from gromov.shapes import grid, rolled_grid

    assert gh.ShapeMetric is gromov.ShapeMetric and gromov.ShapeMetric.__module__ == "gromov.shape_metric"
    assert gh.MatchResult is gromov.MatchResult and gromov.MatchResult.__module__ == "gromov.match_result"
    r = gromov.match(grid(11, 6), rolled_grid(11, 6), "geodesic", n_samples=10, resolution=None)
    new = pickle.dumps(r, protocol=0)
    old = new.replace(b"cgromov.match_result\nMatchResult\n", b"cgromov.gh\nMatchResult\n")
    assert old != new   # a pickle written when the class was gromov.gh.MatchResult
    back = pickle.loads(old)
    assert type(back) is gromov.MatchResult and back.distance == r.distance
    assert np.array_equal(back.x_to_y_vertex, r.x_to_y_vertex)


def test_long_steps_say_what_they_do_on_a_terminal(tmp_path, capsys, monkeypatch):
    """``gromov info`` / ``distances`` / ``match`` print a status line per long step on a
    terminal, none with ``-q`` or when stderr is captured by a script."""
    import sys

    import gromov
    from gromov.cli import main
    from gromov.shapes import icosphere

    src = tmp_path / "s.off"
    gromov.save(icosphere(2), src)
    assert main(["info", str(src)]) == 0
    assert capsys.readouterr().err == ""                       # not a terminal: silent
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert main(["info", str(src)]) == 0
    assert "gromov: geodesic diameter of 162 vertices" in capsys.readouterr().err
    assert main(["info", str(src), "-q"]) == 0
    assert capsys.readouterr().err == ""
    out = tmp_path / "d.npz"
    assert main(["distances", str(src), "--out", str(out), "--metric", "geodesic"]) == 0
    err = capsys.readouterr().err
    assert "gromov: working shape of 162 vertices" in err and "geodesic metric on 162" in err
    assert main(["match", str(src), str(src), "--samples", "10", "--metric", "geodesic"]) == 0
    err = capsys.readouterr().err
    assert f"gromov: geodesic metric of {src}" in err and "gromov: matching 10 samples" in err
