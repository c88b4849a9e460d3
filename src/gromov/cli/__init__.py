"""Command-line interface: ``gromov info|distances|match|index|search|pairwise|perturb|reproduce|demo``.

Thin: parses arguments, calls the library, prints. User errors (unreadable file, bad
option values, a metric that cannot be computed) print one line ``gromov: error: ...``
and exit with status 2; no traceback. A reader of stdout that stops early (``| head``) ends
the command quietly with status 141, as SIGPIPE would.

One module per command family, each parser beside its command: :mod:`.distances` (``info``,
``distances``), :mod:`.match`, :mod:`.collection` (``index``, ``search``, ``pairwise``),
:mod:`.perturb`, :mod:`.reproduce` (``reproduce``, ``demo``); the argument groups and
validators they share in :mod:`._args`, what they share when they run in :mod:`._common`.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import warnings

from .._version import __version__
from ..errors import GromovError
from ._common import _UserError
from .collection import _index_parser, _pairwise_parser, _search_parser
from .distances import _distances_parser, _info_parser
from .match import _match_parser
from .perturb import _perturb_parser
from .reproduce import _demo_parser, _reproduce_parser, cmd_demo

__all__ = ["main"]


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="gromov", description=(
        "Non-rigid shape matching in the Gromov-Hausdorff framework with diffusion geometry."))
    p.add_argument("--version", action="version", version=f"gromov {__version__}")
    p.add_argument("-v", "--verbose", action="count", default=0, help="log progress (-vv: debug)")
    sub = p.add_subparsers(dest="command", required=True)
    _info_parser(sub)
    _distances_parser(sub)
    _match_parser(sub)
    _index_parser(sub)
    _search_parser(sub)
    _pairwise_parser(sub)
    _perturb_parser(sub)
    _reproduce_parser(sub)
    _demo_parser(sub)
    return p


def _announce_compilation():
    """Say once on stderr when numba starts compiling a kernel: the first run after an
    install compiles for tens of seconds, later runs load the compiled code from the cache.
    Returns the listener, for ``numba.core.event.unregister("numba:compile", ...)``."""
    from numba.core import event

    class _Note(event.Listener):
        said = False

        def on_start(self, ev):
            if not self.said:
                self.said = True
                print("gromov: compiling kernels, first run only", file=sys.stderr, flush=True)

        def on_end(self, ev):
            pass

    note = _Note()
    event.register("numba:compile", note)
    return note


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=[logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)],
                        format="%(levelname)s %(name)s: %(message)s")
    warnings.simplefilter("default")
    warnings.formatwarning = lambda msg, cat, *a, **k: f"gromov: warning: {msg}\n"
    note = None
    if args.func is not cmd_demo and not getattr(args, "quiet", False) and sys.stderr.isatty():
        note = _announce_compilation()   # on a terminal, like the progress bars
    try:
        code = args.func(args)
        sys.stdout.flush()   # a reader that went away (``| head``) shows here, where it is handled
        return code
    except BrokenPipeError:
        # stdout's reader closed it: stop quietly, as a command stopped by SIGPIPE does, with
        # stdout sent to the null device so that the flush at exit does not fail again
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141   # 128 + SIGPIPE, the status a shell gives such a command
    except (GromovError, _UserError, FileNotFoundError, IsADirectoryError, PermissionError) as exc:
        print(f"gromov: error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # invalid parameter values that reached the library
        print(f"gromov: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # pragma: no cover
        print("gromov: interrupted", file=sys.stderr)
        return 130
    finally:
        if note is not None:
            from numba.core import event

            event.unregister("numba:compile", note)
