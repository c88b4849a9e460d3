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
            "heavy = ('numba', 'scipy', 'gromov.gh', 'gromov.metrics')\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in heavy or m in heavy))\n"
            "from gromov.cli import main\n"
            "with contextlib.suppress(SystemExit), contextlib.redirect_stdout(io.StringIO()):\n"
            "    main(['--help'])\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('numba', 'scipy')\n"
            "             or m.startswith(('gromov.gh', 'gromov.metrics', 'gromov.perturb'))))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.splitlines() == ["[]", "[]"], out
    import gromov

    assert gromov.match.__module__ == "gromov.gh" and "match" in dir(gromov)
