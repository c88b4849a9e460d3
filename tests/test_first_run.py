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
