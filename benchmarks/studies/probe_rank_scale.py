"""Does recognition's ranking gain from how it treats the two shapes' scales? (Variants not taken.)

Run:  .venv/bin/python benchmarks/studies/probe_rank_scale.py [--sets close0.5,close1,stretched,synthetic,heldout]
                                                      [--metrics diffusion] [--json OUT]

The same correspondences as :mod:`bench_rank_residual` (each pair matched once as
:func:`gromov.experiments.gh_matrix` matches it), ranked by the default value -- half the trimmed
RMS of the log ratios of corresponding heat distances at half the diffusion time, each shape at
its own time ``t = tau * area`` ("own") -- and by variants that treat the scale differently:

- ``pair``, ``pair.35``, ``pair.7``, ``pairmax``, ``pairmin``: both shapes measured at one
  common absolute diffusion time, ``f * tau`` times the geometric mean (f = 0.5, 0.35, 0.7) or
  the larger / smaller of the two areas, instead of each at its own; the floor from the largest
  distance measured.
- ``own*sqrtA``, ``own*A``: each shape's distances times a per-shape constant, the square root
  of its area (which removes the ``1 / sqrt(area)`` that raw heat distances scale with) or its
  area (the ``"length"`` units' ``t``): a global scale offset of the log ratios.
- ``shape``: the log ratios less their median (a fitted global scale); ``shape+size``,
  ``own+size``: that, or the default value, combined in quadrature with the log ratio of a pure
  scaling with the working meshes' areas, ``0.5 log(A_X / A_Y)``; ``|size|`` that term alone;
  ``med``: the absolute median of the log ratios alone (the fitted scale).

Printed per ranking: EER and margin (smallest different-class over largest same-class
distance), as in :mod:`bench_rank_residual`. Heat-kernel diffusion only.
"""

from __future__ import annotations

import numpy as np
import bench_rank_residual as B

from gromov.gh import RANK_LOG_FLOOR, RANK_TAU_SCALE, _match, ranking_value
from gromov.gmds import EmbeddedDistance, SurfacePoints, SymmetricGMDS, log_ratio_residuals, trimmed_rms


def _tau(s) -> tuple[float, float]:
    """(tau, area) of a shape's heat solver (through a hole-filling wrapper)."""
    inner = getattr(s.solver, "inner", s.solver)
    return inner.tau, inner.area


def _at(s, tau: float) -> EmbeddedDistance:
    return EmbeddedDistance(s.mesh, s.solver.at_tau(tau).embedding)


def _pair(ij):
    i, j = ij
    x, y = B._SHAPES[i], B._SHAPES[j]
    n = B._N
    if x.ranking_surface(RANK_TAU_SCALE) is None:
        raise SystemExit("this probe needs the heat-kernel diffusion metric")
    r = _match(x, y, x.metric, n_samples=n, seed=0, orientation="ignore", as_prepared=True,   # as gh_matrix
               rank_tau_scale=RANK_TAU_SCALE, rank_residual="log")
    ip, iq = SurfacePoints(r.x_to_y_face, r.x_to_y_bary), SurfacePoints(r.y_to_x_face, r.y_to_x_bary)
    P, Q = x.samples(n, 0), y.samples(n, 0)
    (sx, dmx), (sy, dmy) = x.ranking_surface(RANK_TAU_SCALE), y.ranking_surface(RANK_TAU_SCALE)
    diam = max(dmx, dmy)
    ex, ey = SymmetricGMDS(sx, sy, P, Q).blocks(ip, iq)
    out = {"own": ranking_value(ex, ey, diam, "log")}
    if not np.isclose(out["own"], r.ranking_distance, rtol=1e-9):
        raise AssertionError(f"own: {out['own']} vs match's {r.ranking_distance}")
    (tau, ax), (_, ay) = _tau(x), _tau(y)
    out["own*sqrtA"] = ranking_value(ex * np.sqrt(ax), ey * np.sqrt(ay), diam * np.sqrt(max(ax, ay)), "log")
    out["own*A"] = ranking_value(ex * ax, ey * ay, diam * max(ax, ay), "log")
    for name, f, a in (("pair", 0.5, np.sqrt(ax * ay)), ("pair.35", 0.35, np.sqrt(ax * ay)),
                       ("pair.7", 0.7, np.sqrt(ax * ay)), ("pairmax", 0.5, max(ax, ay)),
                       ("pairmin", 0.5, min(ax, ay))):
        fx, fy = SymmetricGMDS(_at(x, f * tau * a / ax), _at(y, f * tau * a / ay), P, Q).blocks(ip, iq)
        out[name] = ranking_value(fx, fy, max(fx.max(), fy.max()), "log")
    lr = log_ratio_residuals(ex, ey, RANK_LOG_FLOOR * diam)
    size = 0.5 * np.log(x.mesh.area / y.mesh.area)
    med = float(np.median(lr))
    shape = trimmed_rms(lr - med)
    out["shape"] = 0.5 * shape
    out["shape+size"] = 0.5 * np.hypot(shape, size)
    out["own+size"] = 0.5 * np.hypot(trimmed_rms(lr), size)
    out["|size|"] = 0.5 * abs(size)
    out["med"] = abs(med)
    return out


B._pair = _pair

if __name__ == "__main__":
    B.main(None if len(__import__("sys").argv) > 1 else
           ["--sets", "close0.5,close1,stretched,synthetic,heldout", "--metrics", "diffusion"])
