"""A built-in, procedurally generated stand-in for TOSCA: two animals and two people, posed.

TOSCA (Bronstein, Bronstein & Kimmel, *Numerical Geometry of Non-Rigid Shapes*, Springer
2008) holds classes of shapes in several poses; within a class every pose has the same
vertices in the same order, so the ground-truth correspondence between two poses is the
identity on vertex indices. The experiments of Bronstein, Bronstein, Mahmoudi, Kimmel &
Sapiro (IJCV 89, 2010, §5) use four of its classes: cat, dog, a man (david) and a woman
(victoria). :class:`Synthetic` builds a collection with the same structure from numbers
alone, so demos and tests need no data directory. It reads like
:class:`gromov.experiments.datasets.TOSCA` (``classes``, ``poses``, ``load``, ``shapes``)
and uses TOSCA's class names, so :func:`~gromov.experiments.datasets.experiment1` and
:func:`~gromov.experiments.datasets.experiment2` accept it as they accept a TOSCA reader.

Classes
-------
``"cat"`` and ``"dog"``
    Quadrupeds of about the same size. The cat has a long thin tail, short legs, a round
    head and a short snout; the dog long legs, a deeper chest, a long snout and a short
    thick tail.
``"david"`` and ``"victoria"``
    A man and a woman standing in an A-pose (not the TOSCA scans: synthetic people named
    after the TOSCA classes they stand in for). The man is taller, with broad shoulders,
    narrow hips and thick limbs; the woman has narrow shoulders, wide hips, a narrow waist,
    a smaller head and a bust.

As in TOSCA, the classes come in similar pairs: cat and dog differ only in proportions,
and so do the two people, so telling the members of a pair apart is the hard part of
recognition, while a quadruped against a person is easy. Every mesh is one closed,
oriented 2-manifold of genus 0 (a sphere).

Poses
-----
Pose 0 is the rest pose; poses 1-6 are articulations, named in :data:`POSE_NAMES` --
``tail_curl``, ``groom``, ``sit``, ``curl``, ``stalk``, ``cross`` for the animals,
``arm_down``, ``arm_up``, ``legs_crossed``, ``knee_up``, ``side_bend``, ``hand_on_chest``
for the people: rotations of the legs, arms, tail, neck and head, and a little bending of
the spine, about the joints of a skeleton. Most motions swing a part *until it nearly touches* another one
-- an arm down to the hip, a leg across the other, a tail curled round to a hind leg, a
head bent down to a raised paw: the joint turns, at most by a set angle, until the moving
part comes within :data:`CONTACT_GAP` mean edge lengths of a part that was far from it at
rest, or until a triangle would turn over or become a sliver. These near-contacts, close
in space and far along the surface, are where :func:`gromov.perturb.weld` finds weld sites
(the self-contacts of TOSCA and of SHREC'16 "Topological KIDS"), and since they are
measured in edge lengths they are weldable at every resolution without the parts passing
through each other. ``seed`` jitters every angle of poses 1-6 (set angles and the caps
of closing joints) by up to :data:`JITTER_DEGREES`; the rest pose does not depend on it.

Construction
------------
1. **Rest surface.** The body is the zero level set of a smooth union of tapered capsules
   along the segments of a skeleton,

   .. math::

       f(x) = -k \\log \\sum_c e^{-d_c(x)/k}, \\qquad
       d_c(x) = \\min_{s \\in c} \\big(\\|x - p_s(x)\\| - r_s(x)\\big),

   where ``c`` runs over chains of segments (a limb, the tail, the torso), ``p_s(x)`` is
   the closest point of segment ``s`` and ``r_s`` its radius there, linear between the
   ends, and ``k`` the fillet radius (the log-sum-exp "smooth minimum"; Quilez, *Smooth
   minimum*, 2013). Segments of one chain share their end radii and are joined by a plain
   minimum, so limbs do not bulge at their joints.
2. **Polygonisation** by marching tetrahedra (Doi & Koide, IEICE Trans. E74, 1991) on a
   cubic grid split into six tetrahedra per cube along the main diagonal (Kuhn's
   triangulation, which is conforming), so the result is a closed, oriented 2-manifold.
   The spacing gives about four times ``n_vertices`` vertices, and is at most 1.25 times
   the thinnest radius so that thin parts stay connected; ``f`` is evaluated exactly only
   in a band around the surface (a coarse grid and the Lipschitz bound of ``f`` rule out
   the other cells).
3. **Remeshing** to ``n_vertices`` with :func:`gromov.simplify` (topology-preserving
   quadric edge collapses), removal of valence-3 vertices, a few rounds of tangential
   Laplacian relaxation with projection back onto ``f = 0`` (Newton steps along
   ``grad f``), and Delaunay edge flips. At 1500 vertices the smallest angle of a rest
   mesh is 8-18 degrees, and 99 % of the triangles have all their angles above 20 degrees.
4. **Skinning.** Each vertex belongs to the bone of its nearest segment. The weight of
   bone ``b`` at a vertex ``v`` of its region (``b`` and its descendants) rises as the
   smoothstep ``S(t) = 3t^2 - 2t^3`` of ``t = d(v) / w_b`` from 0 at the border of the region
   to 1 at a blend width ``w_b`` (five joint radii for a limb) inside it, ``d`` the
   edge-path distance to the border; outside the region the weight is 0. Measured along
   the surface, a hand never drags the thigh it rests against, and the parent part stays
   rigid. A pose gives bones rotations ``(a_b, theta_b)`` about their joints ``c_b``
   (axis in rest coordinates), applied children first:

   .. math::

       x \\leftarrow c_b + R\\big(a_b,\\, w_b(v)\\,\\theta_b\\big)\\,(x - c_b).

   This is forward kinematics with rotation angles (not matrices) blended, which does
   not collapse the way linear blend skinning does. Parts move rigidly away from their
   joints, so poses are nearly isometric: geodesic distances change by 1-2 % on average
   (each pose below about 3.5 %). TOSCA's poses are not (2.5-9 %); ``pose_stretch`` stretches
   the rest mesh of each pose by a smooth random displacement first (:func:`_stretched`), a
   validation set whose variation within a class is TOSCA's.

Generating the rest mesh takes a few tenths of a second per class and is cached per
process (per class and ``n_vertices``); a pose takes a few hundredths of a second and is
cached by the :class:`Synthetic` instance. Everything is deterministic.
"""

from __future__ import annotations

import logging
import numbers
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from ..mesh import Mesh, repair
from ..resolution import delaunay_flips, simplify

__all__ = ["Synthetic", "CLASSES", "POSE_NAMES", "CONTACT_GAP", "JITTER_DEGREES",
           "MIN_VERTICES", "MAX_VERTICES"]

logger = logging.getLogger(__name__)

CLASSES = ("cat", "dog", "david", "victoria")
"""Class names: two quadrupeds and two people, named after the TOSCA classes they replace."""

CONTACT_GAP = 2.0
"""Clearance at which a closing joint stops, in mean edge lengths of the rest mesh.

Below the default search radius of :func:`gromov.perturb.weld` (5 mean edges) and above one
edge: a contact is weldable and the parts do not touch."""

JITTER_DEGREES = 5.0
"""Largest seeded change of a joint angle, or of the cap of a closing joint, in poses 1-6
(uniform in ``[-J, J]``)."""

MIN_VERTICES = 500
"""Smallest ``n_vertices``: below it the thin parts (tail, hands) have too few vertices."""

MAX_VERTICES = 20000
"""Largest ``n_vertices``: the polygonisation grid grows with it."""

_FILLET = 0.012        # k of the smooth minimum, in body units (metres)
_CULL = 0.15           # a chain farther than this from a point is left out of f there
_LIPSCHITZ = 1.6       # bound of |grad f| (tapering adds a little to the unit slope)
_OVERSAMPLE = 4.0      # marching-tetrahedra vertices per target vertex
_RELAX_ITER = 6        # rounds of tangential relaxation
_FLIP_DIHEDRAL = 60.0  # largest dihedral angle across an edge that may be flipped
_BLEND = 5.0           # blend width of a limb joint, in joint radii
_FAR = 3.0             # parts are "apart" at rest when at least 3 contact gaps apart
_SCAN, _BISECT = 8, 6  # closing a joint: coarse steps, then bisection steps
_MIN_ANGLE = 6.0       # closing a joint: no triangle angle squeezed below this (degrees)


# ---------------------------------------------------------------------------- skeletons
@dataclass(frozen=True)
class _Segment:
    """A tapered capsule from ``a`` (radius ``ra``) to ``b`` (radius ``rb``), part of a bone."""

    bone: str
    chain: str
    a: tuple
    b: tuple
    ra: float
    rb: float


@dataclass(frozen=True)
class _Bone:
    """A rigid part turning about ``pivot`` with its descendants, blended over ``blend``."""

    name: str
    parent: str | None
    pivot: tuple
    blend: float


class _Body:
    """Segments (the geometry) and bones (the kinematics) of one class."""

    def __init__(self, segments: list[_Segment], bones: list[_Bone]):
        self.segments = segments
        self.bones = {b.name: b for b in bones}
        self.bone_names = [b.name for b in bones]
        self.chains = sorted({s.chain for s in segments})
        self.chain_segments = [np.array([i for i, s in enumerate(segments) if s.chain == c])
                               for c in self.chains]
        ends = [np.array([p for i in idx for p in (segments[i].a, segments[i].b)])
                for idx in self.chain_segments]
        reach = [max(max(segments[i].ra, segments[i].rb) for i in idx) + _CULL
                 for idx in self.chain_segments]
        self.chain_boxes = ([e.min(axis=0) - r for e, r in zip(ends, reach)],
                            [e.max(axis=0) + r for e, r in zip(ends, reach)])
        a = np.array([s.a for s in segments], dtype=float)
        ab = np.array([s.b for s in segments], dtype=float) - a
        L2 = (ab * ab).sum(axis=1)
        self.arrays = (a, ab, np.array([s.ra for s in segments]),
                       np.array([s.rb - s.ra for s in segments]),
                       np.divide(1.0, L2, out=np.zeros_like(L2), where=L2 > 0))
        # children before parents: a breadth-first order from the roots, reversed
        order, frontier = [], [b.name for b in bones if b.parent is None]
        while frontier:
            order.extend(frontier)
            frontier = [b.name for b in bones if b.parent in frontier]
        self.leaves_first = order[::-1]

    def subtree(self, name: str) -> list[str]:
        """``name`` and all its descendants."""
        out, frontier = [name], [name]
        while frontier:
            frontier = [b for b in self.bone_names if self.bones[b].parent in frontier]
            out.extend(frontier)
        return out

    def point(self, bone: str, t: float) -> np.ndarray:
        """Rest position at fraction ``t`` of the way from the start to the end of ``bone``."""
        segs = [s for s in self.segments if s.bone == bone]
        a, b = np.asarray(segs[0].a), np.asarray(segs[-1].b)
        return a + t * (b - a)


def _quadruped(cls: str) -> _Body:
    """Cat or dog (metres), facing +x, standing on the plane z = 0, its left side at +y.

    Bones: ``front`` (front half of the torso, the root) and ``rear`` (hind half, turning
    about the middle of the back), ``neck``, ``head``, ``tail1``-``tail4``, and per leg
    ``{fore,hind}_{upper,lower,paw}_{l,r}``.
    """
    if cls == "cat":
        h = 0.27                                       # height of the spine
        torso = (0.075, 0.080, 0.085, 0.17)            # radii rear, middle, chest; half length
        neck_top, head_c, head_r = (0.27, 0.0, h + 0.12), (0.31, 0.0, h + 0.16), 0.060
        snout, snout_r = (0.38, 0.0, h + 0.14), 0.028
        tail = [(-0.21 - 0.09 * k, 0.0, h + 0.03 + 0.025 * k - 0.002 * k * k) for k in range(6)]
        tail_r = (0.022, 0.016)
        hind = [(-0.15, 0.055, h - 0.045), (-0.09, 0.060, h - 0.11), (-0.16, 0.060, 0.06),
                (-0.12, 0.060, 0.021)]
        fore = [(0.15, 0.055, h - 0.04), (0.12, 0.060, h - 0.11), (0.14, 0.060, 0.05),
                (0.18, 0.060, 0.021)]
        leg_r = (0.040, 0.029, 0.021, 0.021)
    else:
        h = 0.42
        torso = (0.075, 0.085, 0.100, 0.19)
        neck_top, head_c, head_r = (0.30, 0.0, h + 0.14), (0.34, 0.0, h + 0.18), 0.058
        snout, snout_r = (0.48, 0.0, h + 0.14), 0.032
        tail = [(-0.23 - 0.05 * k, 0.0, h + 0.03 + 0.02 * k) for k in range(6)]
        tail_r = (0.028, 0.020)
        hind = [(-0.16, 0.060, h - 0.05), (-0.10, 0.065, h - 0.18), (-0.17, 0.065, 0.09),
                (-0.12, 0.065, 0.024)]
        fore = [(0.17, 0.060, h - 0.05), (0.15, 0.065, h - 0.18), (0.16, 0.065, 0.07),
                (0.21, 0.065, 0.024)]
        leg_r = (0.045, 0.032, 0.023, 0.023)
    r_rear, r_mid, r_chest, L = torso
    P, M, C = (-L, 0.0, h), (0.0, 0.0, h + 0.005), (L, 0.0, h + 0.01)
    neck_base = (L + 0.05, 0.0, h + 0.05)
    segs = [
        _Segment("rear", "torso", P, M, r_rear, r_mid),
        _Segment("front", "torso", M, C, r_mid, r_chest),
        _Segment("neck", "neck", neck_base, neck_top, 0.060, 0.045),
        _Segment("head", "head", neck_top, head_c, 0.045, head_r),
        _Segment("head", "head", head_c, snout, head_r, snout_r),
    ]
    r_tail = np.linspace(tail_r[0], tail_r[1], len(tail))
    for i in range(len(tail) - 1):
        segs.append(_Segment(f"tail{min(i, 3) + 1}", "tail", tail[i], tail[i + 1],
                             float(r_tail[i]), float(r_tail[i + 1])))
    bones = [
        _Bone("front", None, M, 0.0),
        _Bone("rear", None, M, 0.30),
        _Bone("neck", "front", neck_base, 0.16),
        _Bone("head", "neck", neck_top, 0.08),
        _Bone("tail1", "rear", tail[0], 0.06),
        _Bone("tail2", "tail1", tail[1], 0.08),
        _Bone("tail3", "tail2", tail[2], 0.08),
        _Bone("tail4", "tail3", tail[3], 0.08),
    ]
    for side, tag in ((1.0, "l"), (-1.0, "r")):
        for limb, pts, parent in (("hind", hind, "rear"), ("fore", fore, "front")):
            pts = [(p[0], side * p[1], p[2]) for p in pts]
            names = [f"{limb}_upper_{tag}", f"{limb}_lower_{tag}", f"{limb}_paw_{tag}"]
            for i, name in enumerate(names):
                segs.append(_Segment(name, f"{limb}_{tag}", pts[i], pts[i + 1], leg_r[i], leg_r[i + 1]))
                bones.append(_Bone(name, parent if i == 0 else names[i - 1], pts[i],
                                   _BLEND * leg_r[i]))
    return _Body(segs, bones)


# body parameters of the two people: scale, (shoulder_y, chest_y, chest_r, waist_r, hip_y,
# hip_r), (head_r, neck_r), arm radii (shoulder, elbow, wrist, finger tips), leg radii (hip,
# knee, ankle, toes), bust radius (0: none)
_MAN = (1.0, (0.19, 0.065, 0.115, 0.100, 0.085, 0.115), (0.095, 0.050),
        (0.048, 0.040, 0.031, 0.029), (0.085, 0.053, 0.036, 0.030), 0.0)
_WOMAN = (0.95, (0.155, 0.055, 0.100, 0.085, 0.100, 0.128), (0.088, 0.042),
          (0.041, 0.034, 0.026, 0.025), (0.088, 0.051, 0.032, 0.027), 0.058)


def _blend_params(a, b, w: float):
    """``a + w (b - a)`` through nested tuples; ``b`` itself when ``w == 1``."""
    if w == 1.0:
        return b
    if isinstance(a, tuple):
        return tuple(_blend_params(x, y, w) for x, y in zip(a, b))
    return a + w * (b - a)


def _humanoid(cls: str, blend: float = 1.0) -> _Body:
    """Man (david) or woman (victoria), metres, A-pose, facing +x, on z = 0, left side at +y.

    Bones: ``pelvis`` (the root), ``spine`` (torso and shoulders, turning about the
    waist), ``neck``, ``head``, and per side ``upperarm``, ``forearm``, ``hand``, ``thigh``,
    ``shin``, ``foot`` with suffix ``_l`` or ``_r``. ``blend`` (victoria only): her body
    parameters taken the fraction ``blend`` of the way from the man's to hers (1: hers).
    """
    params = _MAN if cls == "david" else _blend_params(_MAN, _WOMAN, float(blend))
    s, (shoulder_y, chest_y, chest_r, waist_r, hip_y, hip_r), (head_r, neck_r), arm_r, leg_r, bust = params

    def S(p):
        return (s * p[0], s * p[1], s * p[2])

    waist = S((0.0, 0.0, 1.02))
    segs = [
        _Segment("pelvis", "pelvis", S((0.0, hip_y, 0.95)), S((0.0, -hip_y, 0.95)), s * hip_r, s * hip_r),
        _Segment("neck", "neck", S((0.0, 0.0, 1.42)), S((0.005, 0.0, 1.55)), s * neck_r, s * neck_r * 0.9),
        _Segment("head", "head", S((0.01, 0.0, 1.62)), S((0.02, 0.0, 1.68)), s * head_r, s * head_r * 0.95),
        _Segment("spine", "shoulders", S((0.0, shoulder_y - 0.02, 1.42)),
                 S((0.0, -shoulder_y + 0.02, 1.42)), s * 0.055, s * 0.055),
    ]
    for side, tag in ((1.0, "l"), (-1.0, "r")):
        # two side-by-side capsules give the torso an oval cross-section
        segs.append(_Segment("spine", f"torso_{tag}", S((0.0, side * chest_y, 1.02)),
                             S((0.0, side * (chest_y + 0.01), 1.33)), s * waist_r, s * chest_r))
        if bust:
            b = S((0.075, side * 0.075, 1.24))
            segs.append(_Segment("spine", f"bust_{tag}", b, b, s * bust, s * bust))
    bones = [
        _Bone("pelvis", None, waist, 0.0),
        _Bone("spine", "pelvis", waist, 0.22 * s),
        _Bone("neck", "spine", S((0.0, 0.0, 1.45)), 0.10 * s),
        _Bone("head", "neck", S((0.0, 0.0, 1.56)), 0.10 * s),
    ]
    down = np.radians(40.0)                           # arms 40 degrees from the body
    for side, tag in ((1.0, "l"), (-1.0, "r")):
        shoulder = np.array([0.0, side * shoulder_y, 1.42])
        d = np.array([0.0, side * np.sin(down), -np.cos(down)])
        limbs = (
            ("arm", "spine", ("upperarm", "forearm", "hand"), arm_r,
             [tuple(shoulder + t * d) for t in (0.0, 0.30, 0.57, 0.75)]),
            ("leg", "pelvis", ("thigh", "shin", "foot"), leg_r,
             [(0.0, side * 0.095, 0.87), (0.0, side * 0.11, 0.50), (0.0, side * 0.12, 0.085),
              (0.16, side * 0.13, 0.03)]),
        )
        for chain, parent, parts, radii, pts in limbs:
            pts = [S(p) for p in pts]
            names = [f"{p}_{tag}" for p in parts]
            for i, name in enumerate(names):
                segs.append(_Segment(name, f"{chain}_{tag}", pts[i], pts[i + 1],
                                     s * radii[i], s * radii[i + 1]))
                bones.append(_Bone(name, parent if i == 0 else names[i - 1], pts[i],
                                   _BLEND * s * radii[i]))
    return _Body(segs, bones)


@lru_cache(maxsize=None)
def _body(cls: str, blend: float = 1.0) -> _Body:
    return _quadruped(cls) if cls in ("cat", "dog") else _humanoid(cls, blend)


# ---------------------------------------------------------------------------- implicit surface
def _capsules(body: _Body, X: np.ndarray, seg: np.ndarray, gradient: bool = False):
    """Distance-like values ``(n, len(seg))`` of ``X`` to the tapered capsules ``seg`` of ``body``.

    ``|x - p| - r`` with ``p`` the closest point of the segment and ``r`` the radius there.
    With ``gradient``, also their gradients ``(n, len(seg), 3)``.
    """
    a, ab, ra, dr, inv = (x[seg] for x in body.arrays)
    rel = X[:, None, :] - a[None]
    t_raw = np.einsum("nsk,sk->ns", rel, ab) * inv
    t = np.clip(t_raw, 0.0, 1.0)
    off = rel - t[..., None] * ab[None]
    norm = np.sqrt(np.einsum("nsk,nsk->ns", off, off))
    d = norm - (ra + t * dr)
    if not gradient:
        return d
    free = (t_raw > 0.0) & (t_raw < 1.0)
    g = off / np.maximum(norm, 1e-300)[..., None] - (free * dr * inv)[..., None] * ab[None]
    return d, g


def _field(body: _Body, X: np.ndarray, gradient: bool = False):
    """The implicit function ``f`` (negative inside): soft minimum over chains.

    A chain is evaluated only at the points inside its bounding box grown by ``_CULL``;
    elsewhere its distance counts as ``_CULL``, which changes ``f`` by less than
    ``k exp(-_CULL / k)`` per chain near the surface (nothing that matters) and keeps it
    positive far from it. With ``gradient``, returns ``(f, grad f)``: the soft-min weights
    ``softmax(-d_c / k)`` times the gradients of the closest segment of each chain.
    """
    n, nc = len(X), len(body.chains)
    D = np.full((n, nc), _CULL)
    G = np.zeros((n, nc, 3)) if gradient else None
    for c, (seg, lo, hi) in enumerate(zip(body.chain_segments, *body.chain_boxes)):
        sel = np.flatnonzero(((X >= lo) & (X <= hi)).all(axis=1))
        if not len(sel):
            continue
        out = _capsules(body, X[sel], seg, gradient)
        d = out[0] if gradient else out
        k = np.argmin(d, axis=1)
        dk = d[np.arange(len(sel)), k]
        D[sel, c] = np.minimum(dk, _CULL)
        if gradient:       # zero where the value is capped, so that f and grad f agree
            G[sel, c] = out[1][np.arange(len(sel)), k] * (dk < _CULL)[:, None]
    m = D.min(axis=1, keepdims=True)
    e = np.exp(-(D - m) / _FILLET)
    s = e.sum(axis=1)
    f = m[:, 0] - _FILLET * np.log(s)
    if not gradient:
        return f
    return f, np.einsum("nc,nck->nk", e / s[:, None], G)


# ---------------------------------------------------------------------------- marching tetrahedra
# Kuhn's six tetrahedra of the unit cube, corners numbered dx + 2 dy + 4 dz
_KUHN = np.array([[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]])
_CORNERS = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)])
_TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])


def _edge_of(i: int, j: int) -> int:
    return int(np.flatnonzero((_TET_EDGES == sorted((i, j))).all(axis=1))[0])


def _case_table() -> list[list[tuple[int, int, int]]]:
    """Triangles, as triples of tetrahedron edges, for each of the 16 inside/outside patterns."""
    table = []
    for code in range(16):
        inside = [i for i in range(4) if code >> i & 1]
        outside = [i for i in range(4) if not code >> i & 1]
        if len(inside) in (0, 4):
            table.append([])
        elif len(inside) in (1, 3):
            lone = inside if len(inside) == 1 else outside
            rest = outside if len(inside) == 1 else inside
            o = lone[0]
            table.append([tuple(_edge_of(o, r) for r in rest)])
        else:
            a, b = inside
            c, d = outside
            ac, ad, bd, bc = _edge_of(a, c), _edge_of(a, d), _edge_of(b, d), _edge_of(b, c)
            table.append([(ac, ad, bd), (ac, bd, bc)])
    return table


_CASES = _case_table()


def _marching_tetrahedra(values: np.ndarray, origin: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Closed triangle mesh of ``{values < 0}`` on a regular grid (outward-oriented faces).

    ``values`` ``(nx, ny, nz)`` samples the field at ``origin + h * (i, j, k)``; it must be
    positive on the grid's border. Vertices on grid edges are shared between tetrahedra, so
    the mesh is a closed 2-manifold.
    """
    nx, ny, nz = values.shape
    F = np.where(values == 0.0, 1e-12, values).ravel()
    inside = F < 0
    ids = np.arange(nx * ny * nz).reshape(nx, ny, nz)
    base = ids[:-1, :-1, :-1].ravel()
    offs = (_CORNERS[:, 0] * ny + _CORNERS[:, 1]) * nz + _CORNERS[:, 2]
    cube = base[:, None] + offs[None, :]                 # (n_cubes, 8)
    n_in = inside[cube].sum(axis=1)
    cube = cube[(n_in > 0) & (n_in < 8)]
    tets = cube[:, _KUHN].reshape(-1, 4)                  # (n_tets, 4) grid node ids
    code = (inside[tets] * (1 << np.arange(4))).sum(axis=1)
    tris_nodes = []                                       # (t, 3, 2) node pairs of each corner
    tet_of = []
    for c in range(1, 15):
        sel = np.flatnonzero(code == c)
        if not len(sel):
            continue
        for tri in _CASES[c]:
            e = _TET_EDGES[list(tri)]                      # (3, 2) local corner pairs
            tris_nodes.append(tets[sel][:, e])             # (k, 3, 2)
            tet_of.append(sel)
    pairs = np.concatenate(tris_nodes)                    # (t, 3, 2)
    tet_of = np.concatenate(tet_of)
    pairs = np.sort(pairs, axis=2)
    key = pairs[..., 0].astype(np.int64) * (nx * ny * nz) + pairs[..., 1]
    uniq, inv = np.unique(key.ravel(), return_inverse=True)
    p, q = uniq // (nx * ny * nz), uniq % (nx * ny * nz)
    fp, fq = F[p], F[q]
    t = np.clip(fp / (fp - fq), 0.05, 0.95)

    def pos(node):
        i, rem = np.divmod(node, ny * nz)
        j, k = np.divmod(rem, nz)
        return origin + h * np.stack([i, j, k], axis=1)

    V = pos(p) + t[:, None] * (pos(q) - pos(p))
    faces = inv.reshape(-1, 3).astype(np.int64)
    # orient outwards: the normal points from the inside corners to the outside corners
    corners = tets[tet_of]
    cin = inside[corners]
    cpos = pos(corners.ravel()).reshape(-1, 4, 3)
    n_in = cin.sum(axis=1, keepdims=True)
    direction = ((~cin)[..., None] * cpos).sum(1) / (4 - n_in) - (cin[..., None] * cpos).sum(1) / n_in
    normal = np.cross(V[faces[:, 1]] - V[faces[:, 0]], V[faces[:, 2]] - V[faces[:, 0]])
    flip = np.einsum("ij,ij->i", normal, direction) < 0
    faces[flip] = faces[flip][:, ::-1]
    return V, faces


# ---------------------------------------------------------------------------- rest mesh
def _polygonise(body: _Body, h: float, stride: int = 4) -> Mesh:
    """Marching tetrahedra of ``{f < 0}`` on a grid of spacing ``h``.

    ``f`` is evaluated on a coarse grid of spacing ``H = stride * h`` first. Every point of
    a coarse cell is within ``sqrt(3) H / 2`` of a corner, so a cell whose corners all have
    ``|f| > L sqrt(3) H / 2`` (``L`` bounds ``|grad f|``) cannot meet the surface and has
    one sign throughout; its fine nodes only get that sign. The exact value is computed on
    the other cells only (a band around the surface).
    """
    lo = np.min([np.minimum(s.a, s.b) - max(s.ra, s.rb) for s in body.segments], axis=0) - 3 * h
    hi = np.max([np.maximum(s.a, s.b) + max(s.ra, s.rb) for s in body.segments], axis=0) + 3 * h
    nc = np.ceil((hi - lo) / (stride * h)).astype(int)
    shape = tuple(nc * stride + 1)
    H = stride * h
    gc = [lo[k] + H * np.arange(nc[k] + 1) for k in range(3)]
    fc = _field(body, np.stack(np.meshgrid(*gc, indexing="ij"), axis=-1).reshape(-1, 3))
    fc = fc.reshape(tuple(nc + 1))
    corners = np.stack([np.abs(fc)[i:i + nc[0], j:j + nc[1], k:k + nc[2]]
                        for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    near_coarse = corners.min(axis=0) <= _LIPSCHITZ * np.sqrt(3.0) / 2 * H
    near_cell = near_coarse.repeat(stride, 0).repeat(stride, 1).repeat(stride, 2)
    node = np.zeros(shape, bool)
    for i in (0, 1):
        for j in (0, 1):
            for k in (0, 1):
                node[i:i + shape[0] - 1, j:j + shape[1] - 1, k:k + shape[2] - 1] |= near_cell
    # far nodes: the sign of the nearest coarse node (all corners of a far cell agree)
    idx = [np.minimum(np.rint(np.arange(shape[k]) / stride).astype(int), nc[k]) for k in range(3)]
    values = np.sign(fc[np.ix_(*idx)])
    ii = np.nonzero(node)
    X = lo + h * np.stack(ii, axis=1)
    values[ii] = _field(body, X)
    V, F = _marching_tetrahedra(values, lo, h)
    mesh, _ = repair(Mesh(V, F), warn=False)
    return mesh


def _vertex_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Unit area-weighted vertex normals."""
    c = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n = np.zeros_like(V)
    for k in range(3):
        np.add.at(n, F[:, k], c)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def _project(body: _Body, V: np.ndarray, steps: int = 2) -> np.ndarray:
    """Points moved onto ``f = 0`` by Newton steps ``x - f grad f / |grad f|^2``."""
    for _ in range(steps):
        f, g = _field(body, V, gradient=True)
        V = V - (f / np.maximum((g * g).sum(axis=1), 1e-12))[:, None] * g
    return V


def _drop_valence3(mesh: Mesh) -> Mesh:
    """Remove interior vertices of valence 3, each replaced by the triangle of its link.

    Such a vertex sits in three thin triangles; its removal keeps the Euler characteristic
    (``V - 1``, ``E - 3``, ``F - 2``) and the orientation. Skipped when the link triangle
    is a face already or a link vertex would be left with valence below 3.
    """
    V, F = mesh.vertices, mesh.faces.copy()
    n = len(V)
    for _ in range(5):
        e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
        key = np.unique(e[:, 0] * n + e[:, 1])
        val = np.bincount(key // n, minlength=n) + np.bincount(key % n, minlength=n)
        cand = np.flatnonzero(val == 3)
        if not len(cand):
            break
        existing = {tuple(sorted(f)) for f in F.tolist()}
        dead_face = np.zeros(len(F), bool)
        touched = np.zeros(n, bool)
        new = []
        order = np.argsort(F.ravel(), kind="stable")
        starts = np.searchsorted(F.ravel()[order], np.arange(n + 1))
        for v in cand:
            fids = order[starts[v]:starts[v + 1]] // 3
            if len(fids) != 3 or touched[v]:
                continue
            star = F[fids]
            pos = np.argmax(star == v, axis=1)
            a = star[np.arange(3), (pos + 1) % 3]
            b = star[np.arange(3), (pos + 2) % 3]
            nxt = dict(zip(a.tolist(), b.tolist()))
            x = int(a[0])
            tri = (x, nxt[x], nxt[nxt[x]])
            if len(set(tri)) != 3 or nxt[tri[2]] != x or tuple(sorted(tri)) in existing:
                continue
            if touched[list(tri)].any() or (val[list(tri)] <= 3).any():
                continue
            touched[[v, *tri]] = True
            dead_face[fids] = True
            new.append(tri)
            existing.add(tuple(sorted(tri)))
        if not new:
            break
        F = np.concatenate([F[~dead_face], np.asarray(new, dtype=np.int64)])
    used = np.zeros(n, bool)
    used[F.ravel()] = True
    index = np.cumsum(used) - 1
    return Mesh(V[used], index[F])


def _outward(V: np.ndarray, F: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Cosine between each face normal and the outward direction ``g`` of that face."""
    c = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    den = np.linalg.norm(c, axis=1) * np.linalg.norm(g, axis=1)
    return np.einsum("ij,ij->i", c, g) / np.maximum(den, 1e-300)


def _relax(body: _Body, mesh: Mesh, iterations: int) -> Mesh:
    """Tangential Laplacian relaxation with projection onto the level set, and edge flips.

    Each round moves every vertex halfway to the centroid of its neighbours, within the
    tangent plane, then projects it back onto ``f = 0``; a move that would turn a face
    against ``grad f`` is undone for that face's vertices. Finally non-Delaunay edges are
    flipped (:func:`gromov.resolution.delaunay_flips`).
    """
    V, F = mesh.vertices.copy(), mesh.faces
    e = mesh.edges
    n = len(V)
    A = sp.coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
                      shape=(n, n)).tocsr()
    deg = np.asarray(A.sum(axis=1)).ravel()
    for _ in range(iterations):
        nrm = _vertex_normals(V, F)
        d = (A @ V) / deg[:, None] - V
        d -= np.einsum("ij,ij->i", d, nrm)[:, None] * nrm
        _, g = _field(body, V[F].mean(axis=1), gradient=True)   # outward at each face
        good = _outward(V, F, g) > 0
        W = _project(body, V + 0.5 * d)
        for _ in range(10):   # keep vertices of faces that would fold where they were
            bad = good & (_outward(W, F, g) <= 0)
            if not bad.any():
                break
            back = np.unique(F[bad])
            W[back] = V[back]
        V = W
    F = delaunay_flips(V, F, max_dihedral_deg=_FLIP_DIHEDRAL)
    return Mesh(V, F)


@dataclass(frozen=True, eq=False)
class _Rest:
    """Rest mesh of a class and its skinning: bone of each vertex, blend weights."""

    mesh: Mesh
    labels: np.ndarray          # (n,) index into body.bone_names
    weights: np.ndarray         # (n, n_bones)


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


@lru_cache(maxsize=16)
def _rest(cls: str, n_vertices: int, blend: float = 1.0) -> _Rest:
    """Rest mesh of ``cls`` with about ``n_vertices`` vertices (cached per process)."""
    body = _body(cls, blend)
    # grid spacing for about _OVERSAMPLE * n_vertices vertices (marching-tetrahedra vertices
    # grow as 1 / h^2: one coarse trial run calibrates), fine enough for the thinnest part
    span = np.ptp(np.concatenate([[s.a, s.b] for s in body.segments]), axis=0)
    h0 = float(span.max()) / 25
    n0 = _polygonise(body, h0).n_vertices
    r_min = min(min(s.ra, s.rb) for s in body.segments)
    h = min(h0 * np.sqrt(n0 / (_OVERSAMPLE * n_vertices)), 1.25 * r_min)
    fine = _polygonise(body, h)
    # dropping valence-3 vertices removes about 3 %; aim that much higher
    work = simplify(fine, int(round(1.03 * n_vertices)), min_quality=0.03).mesh
    mesh = _relax(body, _drop_valence3(Mesh(work.vertices, work.faces)), _RELAX_ITER)

    seg_bone = np.array([body.bone_names.index(s.bone) for s in body.segments])
    labels = seg_bone[np.argmin(_capsules(body, mesh.vertices, np.arange(len(body.segments))), axis=1)]
    W = np.zeros((mesh.n_vertices, len(body.bone_names)))
    for j, name in enumerate(body.bone_names):
        bone = body.bones[name]
        region = np.isin(labels, [body.bone_names.index(b) for b in body.subtree(name)])
        if bone.blend == 0.0 or region.all():
            W[:, j] = region
            continue
        depth = dijkstra(mesh.adjacency, directed=False, indices=np.flatnonzero(~region),
                         min_only=True)
        W[:, j] = np.where(region, _smoothstep(depth / bone.blend), 0.0)
    for a in (labels, W):
        a.flags.writeable = False
    logger.info("synthetic %s: %d vertices, %d faces", cls, mesh.n_vertices, mesh.n_faces)
    return _Rest(mesh, labels, W)


# ---------------------------------------------------------------------------- posing
#: Largest ``Synthetic(pose_stretch=...)``.
MAX_POSE_STRETCH = 0.2
#: Random plane waves in the stretch field of a pose, and their wavelength (times the rest
#: mesh's bounding-box diagonal).
_STRETCH_WAVES = 8
_STRETCH_WAVELENGTH = 0.5


def _stretched(V: np.ndarray, strain: float, rng: np.random.Generator) -> np.ndarray:
    r"""Rest vertices moved by a smooth random displacement whose strain is about ``strain``.

    .. math:: u(x) = \sum_{k=1}^{K} a_k \sin(\omega_k \cdot x + \varphi_k),

    ``K`` = :data:`_STRETCH_WAVES` plane waves of wavelength ``lambda`` =
    :data:`_STRETCH_WAVELENGTH` times the bounding-box diagonal (a limb's length), random
    directions and phases, and Gaussian amplitudes ``a_k`` scaled so that the root mean square
    of the displacement gradient's entries is ``strain``: lengths on the surface change by a few
    times ``strain`` here and there (measured in the ``pose_stretch`` note), the way an
    artist's or a scanner's poses stretch a body (TOSCA's poses change geodesic distances by
    2.5-9 %, ``benchmarks/studies/tosca_isometry.py``) while an articulated pose keeps them.
    """
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    k = 2.0 * np.pi / (_STRETCH_WAVELENGTH * diag)
    dirs = rng.normal(size=(_STRETCH_WAVES, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    phase = rng.uniform(0.0, 2.0 * np.pi, _STRETCH_WAVES)
    amp = rng.normal(size=(_STRETCH_WAVES, 3))
    # gradient entries sum_k a_ki k d_kj cos(.): mean square over the 9 entries (and over x,
    # cos^2 averaging 1/2, the waves' cross terms 0) is sum_k |a_k|^2 k^2 / 18
    rms = k * np.sqrt(np.sum(amp**2) / (2.0 * 9.0))
    amp *= strain / max(rms, 1e-300)
    return V + np.sin(V @ (k * dirs).T + phase) @ amp


def _rotation_matrices(axis: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """``(k, 3, 3)`` rotations about the unit ``axis`` by each angle (Rodrigues' formula)."""
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    c, s = np.cos(angles)[:, None, None], np.sin(angles)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def _skin(body: _Body, rest: _Rest, rotations: dict, frames: bool = False,
          subset: np.ndarray | None = None):
    """Posed vertices; ``rotations`` maps bones to ``(unit axis, angle in radians)``.

    With ``frames``, also the ``(n, 3, 3)`` rotation each vertex went through; with
    ``subset`` (vertex indices), only those vertices.
    """
    V = rest.mesh.vertices if subset is None else rest.mesh.vertices[subset]
    weights = rest.weights if subset is None else rest.weights[subset]
    V = V.copy()
    R = np.broadcast_to(np.eye(3), (len(V), 3, 3)).copy() if frames else None
    for name in body.leaves_first:
        if name not in rotations:
            continue
        axis, angle = rotations[name]
        w = weights[:, body.bone_names.index(name)]
        sel = np.flatnonzero(w > 0)
        Q = _rotation_matrices(axis, w[sel] * angle)
        c = np.asarray(body.bones[name].pivot)
        V[sel] = c + np.einsum("nij,nj->ni", Q, V[sel] - c)
        if frames:
            R[sel] = Q @ R[sel]
    return (V, R) if frames else V


def _spoilt(rest: _Rest, V: np.ndarray, R: np.ndarray, faces: np.ndarray | None = None) -> np.ndarray:
    """Mask of the faces (of ``faces``, default all) turned over or squeezed to slivers.

    Turned over: the posed normal points against the rest normal carried by the rotation
    of the face's first vertex. A sliver: an angle below ``_MIN_ANGLE`` (or above 180
    degrees minus it).
    """
    F = rest.mesh.faces if faces is None else rest.mesh.faces[faces]
    n0 = rest.mesh.face_normals if faces is None else rest.mesh.face_normals[faces]
    carried = np.einsum("fij,fj->fi", R[F[:, 0]], n0)
    e = [V[F[:, (k + 2) % 3]] - V[F[:, (k + 1) % 3]] for k in range(3)]   # edge opposite k
    posed = np.cross(e[2], -e[1])
    sq = [np.einsum("ij,ij->i", x, x) for x in e]
    # sin(angle k) = 2 area / (product of its two sides)
    area2 = np.linalg.norm(posed, axis=1)
    sin_min = np.min([area2 / np.sqrt(sq[(k + 1) % 3] * sq[(k + 2) % 3]) for k in range(3)], axis=0)
    return (np.einsum("ij,ij->i", carried, posed) <= 0) | (sin_min < np.sin(np.radians(_MIN_ANGLE)))


def _clearance(rest_v: np.ndarray, V: np.ndarray, far: float, radius: float,
               moving: np.ndarray | None = None) -> float:
    """Smallest posed distance between two vertices ``far`` or more apart at rest.

    ``radius`` if no such pair is closer than that. With ``moving`` (a vertex mask), only
    pairs between it and the other vertices count.
    """
    if moving is None:
        pairs = cKDTree(V).query_pairs(radius, output_type="ndarray").reshape(-1, 2)
        i, j = pairs[:, 0], pairs[:, 1]
    else:
        mi, si = np.flatnonzero(moving), np.flatnonzero(~moving)
        if not len(mi) or not len(si):
            return radius
        coo = cKDTree(V[mi]).sparse_distance_matrix(cKDTree(V[si]), radius, output_type="ndarray")
        i, j = mi[coo["i"]], si[coo["j"]]
    d = np.linalg.norm(V[i] - V[j], axis=1)
    d = d[np.linalg.norm(rest_v[i] - rest_v[j], axis=1) >= far]
    return float(d.min()) if len(d) else radius


def _unit(axis) -> np.ndarray:
    a = np.asarray(axis, dtype=float)
    return a / np.linalg.norm(a)


def _compose(first: tuple, then: tuple) -> tuple:
    """The rotation ``then`` after ``first`` (each ``(unit axis, angle)``) as one ``(axis, angle)``."""
    def quaternion(r):
        return np.r_[np.cos(r[1] / 2), np.sin(r[1] / 2) * r[0]]

    p, q = quaternion(first), quaternion(then)
    w = q[0] * p[0] - q[1:] @ p[1:]
    v = q[0] * p[1:] + p[0] * q[1:] + np.cross(q[1:], p[1:])
    if w < 0:
        w, v = -w, -v
    s = float(np.linalg.norm(v))
    if s < 1e-15:
        return (np.array([1.0, 0.0, 0.0]), 0.0)
    return (v / s, 2 * np.arctan2(s, w))


def _bone_transform(body: _Body, rot: dict, bone: str | None) -> tuple[np.ndarray, np.ndarray]:
    """Rigid motion ``x -> M x + t`` of ``bone`` (its rotation and its ancestors'); identity for None."""
    M, t = np.eye(3), np.zeros(3)
    while bone is not None:
        if bone in rot:
            Q = _rotation_matrices(rot[bone][0], np.array([rot[bone][1]]))[0]
            c = np.asarray(body.bones[bone].pivot)
            M, t = Q @ M, Q @ (t - c) + c
        bone = body.bones[bone].parent
    return M, t


def _close(body: _Body, rest: _Rest, rot: dict, bone: str, axis: np.ndarray, limit: float,
           gap: float) -> dict:
    """``rot`` with ``bone`` turned about ``axis`` by the largest loose angle in ``[0, limit]``.

    Loose: no vertex of the moving part (weight of ``bone`` above 1/2) within ``gap`` of a
    vertex that was ``_FAR * gap`` or more away from it at rest, and no more faces turned
    over or squeezed to slivers than before. ``_SCAN`` coarse steps, then ``_BISECT`` bisections of the first
    step that is not loose.
    """
    base = rot.get(bone)
    w = rest.weights[:, body.bone_names.index(bone)]
    moving = w > 0.5
    # only the vertices with a weight of this bone move, only the faces around them change
    touched = np.flatnonzero(w > 0)
    faces = np.flatnonzero((w[rest.mesh.faces] > 0).any(axis=1))
    V0, R0 = _skin(body, rest, rot, frames=True)
    spoilt0 = int(_spoilt(rest, V0, R0, faces).sum())

    def loose(angle):
        trial = dict(rot)
        trial[bone] = _compose(base, (axis, angle)) if base is not None else (axis, angle)
        V, R = V0.copy(), R0.copy()
        V[touched], R[touched] = _skin(body, rest, trial, frames=True, subset=touched)
        clear = _clearance(rest.mesh.vertices, V, _FAR * gap, gap, moving) >= gap
        ok = clear and int(_spoilt(rest, V, R, faces).sum()) <= spoilt0
        if not ok:
            logger.debug("%s stops before %.1f degrees: %s", bone, np.degrees(angle),
                         "contact" if not clear else "a face would turn over or become a sliver")
        return ok, trial

    best, prev = rot, 0.0
    for angle in np.linspace(0.0, limit, _SCAN + 1)[1:]:
        ok, trial = loose(angle)
        if not ok:
            a, b = prev, angle
            for _ in range(_BISECT):
                mid = (a + b) / 2
                ok, trial = loose(mid)
                if ok:
                    a, best = mid, trial
                else:
                    b = mid
            return best
        prev, best = angle, trial
    return best


def _solve_pose(cls: str, rest: _Rest, ops: list, rng: np.random.Generator,
                blend: float = 1.0) -> tuple[np.ndarray, dict]:
    """Vertices of a pose and the rotations used (``bone -> (axis, angle)``).

    ``ops`` are applied in order. ``("rot", bone, axis, degrees)`` turns ``bone`` by a set
    angle. ``("close", bone, axis, degrees)`` and ``("reach", bone, (bone, t), (bone, t),
    degrees)`` turn ``bone`` by the largest angle up to ``degrees`` that keeps the moving
    part :data:`CONTACT_GAP` mean edges from the parts it was far from at rest (see
    :func:`_close`): about ``axis``, or about the axis that swings the first point (on the
    moving part; ``t`` along the bone) towards the second, at most until it points at the
    second. ``rng`` jitters every ``degrees`` by up to :data:`JITTER_DEGREES`. ``blend``:
    victoria's body (:func:`_humanoid`).
    """
    body = _body(cls, blend)
    gap = CONTACT_GAP * rest.mesh.mean_edge_length
    rot: dict = {}
    for op in ops:
        kind, bone = op[0], op[1]
        jitter = rng.uniform(-JITTER_DEGREES, JITTER_DEGREES)
        if kind == "rot":
            r = (_unit(op[2]), np.radians(op[3] + jitter))
            rot[bone] = _compose(rot[bone], r) if bone in rot else r
            continue
        if kind == "close":
            axis, limit = _unit(op[2]), np.radians(op[3] + np.sign(op[3]) * jitter)
            if limit < 0:
                axis, limit = -axis, -limit
        else:   # reach: in the frame of the bone's parent, pivot at the origin
            M, t = _bone_transform(body, rot, body.bones[bone].parent)
            c = np.asarray(body.bones[bone].pivot)
            ends = []
            for which, frac in (op[2], op[3]):
                Mw, tw = _bone_transform(body, rot, which)
                ends.append(M.T @ (Mw @ body.point(which, frac) + tw - t) - c)
            axis = np.cross(*ends)
            norm = float(np.linalg.norm(axis))
            if norm < 1e-12:
                continue
            axis = axis / norm
            cos = ends[0] @ ends[1] / (np.linalg.norm(ends[0]) * np.linalg.norm(ends[1]))
            limit = min(np.radians(op[4] + jitter), float(np.arccos(np.clip(cos, -1.0, 1.0))))
        rot = _close(body, rest, rot, bone, axis, limit, gap)
    return _skin(body, rest, rot), rot


# A pose lists joint motions, applied in order (see _solve_pose):
#   ("rot", bone, axis, degrees)                      turn by a set angle
#   ("close", bone, axis, degrees)                    turn until near contact, at most degrees
#   ("reach", bone, (bone, t), (bone, t), degrees)    swing a point of the moving part towards
#                                                     a target point until near contact
# Every ``degrees`` is jittered by the seed. Axes are in rest coordinates: x forward, y to
# the left, z up.
_X, _Y, _Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)

_QUADRUPED_POSES = (
    ("tail_curl", (      # tail swept round to the right hind leg
        ("rot", "tail1", _Z, 40.0), ("rot", "tail2", _Z, 40.0), ("rot", "head", _Z, 20.0),
        ("reach", "tail3", ("tail4", 1.0), ("hind_upper_r", 0.4), 90.0),
        ("reach", "tail4", ("tail4", 1.0), ("hind_upper_r", 0.4), 90.0))),
    ("groom", (          # left fore paw raised, head bent down to it
        ("rot", "neck", _Y, 15.0),
        ("close", "fore_upper_l", _Y, -55.0), ("close", "fore_lower_l", _Y, -90.0),
        ("reach", "head", ("head", 1.0), ("fore_paw_l", 1.0), 80.0))),
    ("sit", (            # hind quarters lowered, hind legs folded, tail down against a hind paw
        ("close", "rear", _Y, -10.0),
        ("close", "hind_upper_l", _Y, -30.0), ("close", "hind_upper_r", _Y, -30.0),
        ("close", "hind_lower_l", _Y, 100.0), ("close", "hind_lower_r", _Y, 100.0),
        ("rot", "tail1", _Y, -30.0),
        ("reach", "tail2", ("tail4", 1.0), ("fore_paw_r", 1.0), 90.0),
        ("reach", "tail3", ("tail4", 1.0), ("fore_paw_r", 1.0), 90.0))),
    ("curl", (           # body bent sideways, head turned back, tail against the right hind leg
        ("close", "rear", _Z, 8.0),
        ("reach", "neck", ("head", 1.0), ("hind_upper_r", 0.0), 40.0),
        ("reach", "head", ("head", 1.0), ("hind_upper_r", 0.0), 50.0),
        ("reach", "tail2", ("tail4", 1.0), ("fore_paw_r", 1.0), 90.0),
        ("reach", "tail3", ("tail4", 1.0), ("fore_paw_r", 1.0), 90.0))),
    ("stalk", (          # left hind paw forward to the left fore leg, right fore paw back
        ("rot", "neck", _Z, 10.0), ("rot", "hind_lower_l", _Y, 30.0),
        ("reach", "hind_upper_l", ("hind_paw_l", 1.0), ("fore_lower_l", 0.6), 70.0),
        ("reach", "fore_upper_r", ("fore_paw_r", 1.0), ("hind_lower_r", 0.6), 70.0))),
    ("cross", (          # left fore leg across the right one, right hind leg across the left
        ("rot", "hind_upper_l", _Y, 25.0), ("rot", "tail1", _Y, 35.0),
        ("rot", "neck", _Z, -25.0),
        ("reach", "fore_upper_l", ("fore_paw_l", 0.0), ("fore_lower_r", 0.5), 45.0),
        ("reach", "hind_upper_r", ("hind_paw_r", 0.0), ("hind_lower_l", 0.5), 45.0))),
)

_HUMANOID_POSES = (
    ("arm_down", (       # right arm down until the forearm meets the hip, left arm forward
        ("rot", "upperarm_l", _Y, -60.0), ("rot", "forearm_l", _Y, -40.0),
        ("reach", "upperarm_r", ("hand_r", 1.0), ("thigh_r", 0.5), 60.0),
        ("reach", "forearm_r", ("hand_r", 1.0), ("thigh_r", 0.5), 60.0))),
    ("arm_up", (         # right arm raised over the head, left forearm down to the hip
        ("rot", "upperarm_r", _X, -70.0),
        ("reach", "forearm_r", ("hand_r", 1.0), ("head", 1.0), 150.0),
        ("reach", "upperarm_l", ("hand_l", 1.0), ("pelvis", 0.0), 60.0))),
    ("legs_crossed", (   # left leg across the right one: foot against shin
        ("rot", "thigh_l", _Y, -15.0),
        ("rot", "upperarm_l", _X, 20.0), ("rot", "upperarm_r", _X, 20.0),
        ("reach", "thigh_l", ("foot_l", 0.0), ("shin_r", 0.5), 40.0),
        ("reach", "shin_l", ("foot_l", 0.0), ("shin_r", 0.5), 40.0))),
    ("knee_up", (        # right knee raised, right arm swung towards it until it meets the hip
        ("rot", "thigh_r", _Y, -55.0), ("rot", "shin_r", _Y, 70.0),
        ("reach", "upperarm_r", ("hand_r", 1.0), ("thigh_r", 1.0), 80.0),
        ("reach", "forearm_r", ("hand_r", 1.0), ("thigh_r", 1.0), 100.0))),
    ("side_bend", (      # bent to the right, hands and forearms against the hips
        ("close", "spine", _X, 10.0),
        ("reach", "forearm_l", ("hand_l", 1.0), ("spine", 0.3), 120.0),
        ("reach", "upperarm_l", ("hand_l", 1.0), ("spine", 0.3), 60.0),
        ("reach", "upperarm_r", ("hand_r", 1.0), ("thigh_r", 0.6), 60.0))),
    ("hand_on_chest", (  # right hand across the chest, left forearm to the hip, left leg forward
        ("rot", "upperarm_r", _Y, -40.0),
        ("rot", "thigh_l", _Y, -25.0), ("rot", "shin_l", _Y, 40.0),
        ("reach", "forearm_r", ("hand_r", 1.0), ("upperarm_l", 0.0), 150.0),
        ("reach", "upperarm_l", ("hand_l", 1.0), ("thigh_l", 0.5), 60.0))),
)


def _pose_table(cls: str) -> tuple:
    return _QUADRUPED_POSES if cls in ("cat", "dog") else _HUMANOID_POSES


POSE_NAMES = {c: ("rest",) + tuple(name for name, _ in _pose_table(c)) for c in CLASSES}
"""Name of each pose of each class, by pose number; pose 0 is ``"rest"``."""


# ---------------------------------------------------------------------------- data set
def _check_int(value, name: str, lo: int, hi: int | None = None) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__} {value!r}")
    value = int(value)
    if value < lo or (hi is not None and value > hi):
        bounds = f"in [{lo}, {hi}]" if hi is not None else f">= {lo}"
        raise ValueError(f"{name} must be {bounds}, got {value}")
    return value


class Synthetic:
    """Four classes of articulated shapes in seven poses each, generated on demand.

    The same reading interface as :class:`~gromov.experiments.datasets.TOSCA`: classes
    ``"cat"``, ``"dog"``, ``"david"``, ``"victoria"``, poses ``0`` (rest) to ``6``, and
    within a class vertex ``i`` of one pose corresponds to vertex ``i`` of every other
    pose (the faces are identical). See the module docstring for the construction.

    Parameters
    ----------
    n_vertices : int, default 1500
        Approximate vertex count of every mesh (within a few percent), in
        ``[MIN_VERTICES, MAX_VERTICES]``. Mean edge lengths at 1500: about 2 cm on the
        cat, 4 cm on the man (who is 1.75 m tall).
    seed : int, default 0
        Non-negative; jitters the joint angles of poses 1-6 (by up to
        :data:`JITTER_DEGREES`). The rest pose does not depend on it.
    victoria_blend : float, default 1
        In ``(0, 1]``: victoria's body parameters (scale, shoulder and hip widths, limb,
        torso, head and bust radii) the fraction ``victoria_blend`` of the way from david's to
        hers -- a harder pair for recognition than the default (1: the woman as described
        above). Her poses are the same.
    pose_stretch : float, default 0
        In ``[0, MAX_POSE_STRETCH]``: poses 1-6 are made from a rest mesh stretched by a smooth
        random displacement whose strain is about ``pose_stretch`` (:func:`_stretched`; its own
        random stream, so the joint angles are those of the unstretched poses), so that poses
        are no longer nearly isometric. TOSCA's are not: between two poses its geodesic
        distances change by a median 2.5 % (victoria), 4.5 % (david), 8-9 % (cat, dog)
        (``benchmarks/studies/tosca_isometry.py``); at 0.1 those of the synthetic people change by
        2.4-6.5 % and the cat's by 4-5 % (rest vs poses 1-4, measured with the same benchmark's
        statistic), against 0-1 % at 0. A more faithful validation set for recognition, where
        the variation within a class competes with the difference between classes. The rest
        pose is not stretched.

    Raises
    ------
    TypeError
        ``n_vertices`` or ``seed`` is not an integer.
    ValueError
        ``n_vertices`` is out of range, ``seed`` is negative or ``victoria_blend`` is not in
        ``(0, 1]``.

    Examples
    --------
    >>> data = Synthetic(n_vertices=1500, seed=0)
    >>> data.classes
    ['cat', 'david', 'dog', 'victoria']
    >>> cat, cat3 = data.load("cat", 0), data.load("cat", 3)
    >>> bool((cat.faces == cat3.faces).all()), cat.genus
    (True, 0.0)
    """

    def __init__(self, n_vertices: int = 1500, seed: int = 0, victoria_blend: float = 1.0,
                 pose_stretch: float = 0.0):
        self.n_vertices = _check_int(n_vertices, "n_vertices", MIN_VERTICES, MAX_VERTICES)
        self.seed = _check_int(seed, "seed", 0)
        if isinstance(victoria_blend, (bool, np.bool_)) or not isinstance(victoria_blend, numbers.Real) \
                or not 0.0 < victoria_blend <= 1.0:
            raise ValueError(f"victoria_blend must be a number in (0, 1], got {victoria_blend!r}")
        self.victoria_blend = float(victoria_blend)
        if isinstance(pose_stretch, (bool, np.bool_)) or not isinstance(pose_stretch, numbers.Real) \
                or not 0.0 <= pose_stretch <= MAX_POSE_STRETCH:
            raise ValueError(f"pose_stretch must be a number in [0, {MAX_POSE_STRETCH}], got {pose_stretch!r}")
        self.pose_stretch = float(pose_stretch)
        self._poses: dict[tuple[str, int], Mesh] = {}

    def __repr__(self) -> str:
        blend = "" if self.victoria_blend == 1.0 else f", victoria_blend={self.victoria_blend:g}"
        if self.pose_stretch:
            blend += f", pose_stretch={self.pose_stretch:g}"
        return (f"Synthetic(n_vertices={self.n_vertices}, seed={self.seed}{blend}: "
                f"{len(CLASSES)} classes, {len(self.shapes())} shapes)")

    def _blend(self, cls: str) -> float:
        return self.victoria_blend if cls == "victoria" else 1.0

    @property
    def classes(self) -> list[str]:
        """Class names, sorted (as :attr:`TOSCA.classes <gromov.experiments.datasets.TOSCA.classes>`)."""
        return sorted(CLASSES)

    def _class(self, cls) -> str:
        if not isinstance(cls, str) or cls not in CLASSES:
            raise KeyError(f"no synthetic class {cls!r}; classes: {', '.join(self.classes)}")
        return cls

    def poses(self, cls: str) -> list[int]:
        """Pose numbers of ``cls``: ``[0, 1, ..., 6]``. Raises ``KeyError`` for an unknown class."""
        return list(range(len(POSE_NAMES[self._class(cls)])))

    def pose_name(self, cls: str, pose: int) -> str:
        """What pose ``pose`` of ``cls`` shows, e.g. ``"tail_curl"`` (see :data:`POSE_NAMES`)."""
        pose = self._pose(cls, pose)
        return POSE_NAMES[cls][pose]

    def _pose(self, cls, pose) -> int:
        poses = self.poses(cls)
        valid = isinstance(pose, (int, np.integer)) and not isinstance(pose, (bool, np.bool_))
        if not valid or int(pose) not in poses:
            raise KeyError(f"no pose {pose!r} of synthetic class {cls!r}; poses: "
                           f"{', '.join(map(str, poses))}")
        return int(pose)

    def load(self, cls: str, pose: int) -> Mesh:
        """The mesh of ``cls`` in ``pose``.

        Returns
        -------
        Mesh
            Closed genus-0 triangle mesh; its faces are those of every pose of ``cls`` and
            its ``input_ids`` are ``arange(n)``.

        Raises
        ------
        KeyError
            Unknown class or pose (the message lists those that exist).
        """
        pose = self._pose(cls, pose)
        key = (cls, pose)
        if key not in self._poses:
            rest = _rest(cls, self.n_vertices, self._blend(cls))
            if pose == 0:
                self._poses[key] = rest.mesh
            else:
                rng = np.random.default_rng([self.seed, CLASSES.index(cls), pose])
                if self.pose_stretch > 0.0:
                    stretch = np.random.default_rng([self.seed, CLASSES.index(cls), pose, 1])
                    rest = _Rest(rest.mesh.with_vertices(_stretched(rest.mesh.vertices, self.pose_stretch, stretch)),
                                 rest.labels, rest.weights)
                V, _ = _solve_pose(cls, rest, list(_pose_table(cls)[pose - 1][1]), rng, self._blend(cls))
                self._poses[key] = rest.mesh.with_vertices(V)
        return self._poses[key]

    def shapes(self) -> list[tuple[str, int]]:
        """All ``(class, pose)`` pairs, sorted by class then pose."""
        return [(c, p) for c in self.classes for p in self.poses(c)]

    def clearance(self, cls: str, pose: int) -> float:
        """How near the parts of a pose come to each other, in mean edge lengths.

        The smallest distance between two vertices of the pose that are at least
        ``3 * CONTACT_GAP`` mean edges (of the rest mesh) apart in the rest pose -- parts
        that were apart and came together -- divided by the mean edge length. At most
        ``3 * CONTACT_GAP`` (returned when no such pair is closer). Joints that close until
        contact stop at :data:`CONTACT_GAP`; a value below 1 would mean parts nearly touch
        at the mesh's resolution.
        """
        mesh = self.load(cls, pose)
        rest = _rest(cls, self.n_vertices, self._blend(cls))
        e = rest.mesh.mean_edge_length
        far = _FAR * CONTACT_GAP * e
        return _clearance(rest.mesh.vertices, mesh.vertices, far, far) / e
