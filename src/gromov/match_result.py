"""The outcome of a match: :class:`MatchResult`, the distance, the correspondence and its maps."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["MatchResult"]


@dataclass(frozen=True, eq=False)
class MatchResult:
    """The outcome of :func:`match`. Indices refer to the input meshes (file numbering).

    Attributes
    ----------
    distance : float
        GH estimate: half the distortion in the chosen norm, in the metric's units.
    relative_distance : float
        ``distance`` divided by the larger of the two shapes' diameters in that metric.
    distortion_l2, distortion_linf : float
        RMS and maximum distortion of the final correspondence (over ordered pairs).
    x_samples, y_samples : ndarray (M,), (K,)
        Input vertex ids of the samples.
    x_to_y_face, x_to_y_bary, x_to_y_vertex : ndarray
        Images of X's samples on Y's input mesh: face, barycentric coordinates, nearest vertex.
        Vertex ids are the file's numbering. Face ids are the file's too unless loading had to
        drop degenerate or repeated faces (a ``GromovWarning`` says so); then they index the
        repaired mesh's faces. On a point cloud: face -1, NaN coordinates, and the image point.
    y_to_x_face, y_to_x_bary, y_to_x_vertex : ndarray
        The same for Y's samples on X.
    x_to_y_dense_face, x_to_y_dense_bary, x_to_y_dense_vertex : ndarray (n_X,), (n_X, 3), (n_X,)
        With ``match(..., dense=True)``: the image on Y's input mesh of *every* vertex of X's
        input (entry i for file vertex i; :mod:`gromov.dense`), as for the samples. None
        otherwise.
    y_to_x_dense_face, y_to_x_dense_bary, y_to_x_dense_vertex : ndarray (n_Y,), (n_Y, 3), (n_Y,)
        The same for every vertex of Y on X.
    input_faces : (ndarray or None, ndarray or None)
        With the dense maps: the faces of X's and Y's input meshes in file vertex ids (None
        for a point cloud), which the dense face ids index; what :meth:`transfer` interpolates on.
    orientation : float
        Fraction of small sample triangles whose sense of rotation the correspondence keeps
        (:func:`gromov.orientation.orientation_agreement`, both directions averaged): about 1
        for a direct map, about 0 for a mirrored one (left and right swapped), about 1/2 for a
        scrambled one; NaN when a mesh is not orientable or a shape is a point cloud.
    distortion_trimmed : float
        RMS distortion of the best-fitting 80% of the pairs of the final correspondence
        (:func:`gromov.gmds.trimmed_rms`, ``TRIM_KEEP``): the distortion left when the pairs a
        local topology change altered are set aside. Not the GH estimate.
    relative_trimmed : float
        Half of it divided by the larger diameter, comparable to ``relative_distance``.
    ranking_distance : float
        What recognition ranks pairs of shapes by (``PairwiseGH.trimmed``, ``gromov
        reproduce``): from :func:`match`, ``relative_trimmed``; from
        :func:`gromov.experiments.gh_matrix`, with its ``rank_tau_scale`` and the heat-kernel
        diffusion metric, the same quantity for the same correspondence measured with the heat
        distance at ``rank_tau_scale`` times the diffusion time (diameters in that metric);
        with its ``rank_residual="log"``, of the log ratios of the distances instead of their
        differences (:func:`~gromov.gh.ranking_value`). From a partial match
        (:func:`gromov.partial.match_partial`), the objective its search minimised in the
        distance's units, ÷ the whole's diameter: half the root of the weighted squared
        residuals plus the curvature term over the weights (``relative_distance`` with
        ``curvature=0`` or a whole X); :attr:`gromov.partial.PartialMatrix.score` divides it by
        the covered fraction.
    pair_distortion : ndarray (M+K, M+K)
        ``D_X(C) - D_Y(C)`` of the final two-sided correspondence C = (P x Q') u (P' x Q): rows
        and columns are first X's M samples (on Y: their images), then Y's K samples (on X:
        their images), in the order of ``x_samples`` and ``y_samples``. Where a shape's
        topology changed, the pairs whose paths run through the change can stand out.
    signature_distortion : float
        How far the correspondence is from keeping the heat kernel signature of the working
        meshes (:func:`gromov.spectrum.signature_distortion`): a factor of recognition's
        ``combined`` ranking. Only :func:`gromov.experiments.gh_matrix` with spectral
        signatures computes it (NaN otherwise).
    gh_interval : (float, float)
        A certified interval ``(lower, upper)`` around the Gromov-Hausdorff distance between
        the two sample sets, :math:`d_{GH}(P, Q)` with the shapes' distances (the metric of the
        match, the L-infinity GH; :mod:`gromov.bounds`): the lower bound from the sets of
        distances each sample sees (Mémoli 2011, §6), which holds whatever correspondence was
        found; the upper bound half the largest distortion of the correspondence found, each
        image snapped to the nearest sample of the other shape. Only :func:`match` computes it
        (NaN from :func:`gromov.experiments.gh_matrix`, whose pairs skip it).
    partial : bool
        Whether X was matched as a part of Y (``match(..., partial=True)``,
        :mod:`gromov.partial`): then ``distance`` is half the weighted RMS of the one-sided
        residuals over X's samples (``pair_distortion`` is ``(M, M)``; for an X with nothing
        missing, :func:`gromov.partial.whole_shape`, the full match's), and Y's samples outside
        the covered region have no image (face and vertex -1).
    y_covered : ndarray (n_Y,) of bool or None
        With ``partial``: the region of Y the part covers, per file vertex of Y.
    covered_fraction : float
        With ``partial``: that region's share of Y's area (NaN otherwise).
    x_weight : ndarray (M,) or None
        With ``partial``: each X sample's weight in the distortion (small near X's boundary).
    """

    distance: float
    relative_distance: float
    distortion: float
    distortion_l2: float
    distortion_linf: float
    norm: str
    metric: str
    solver: str
    n_samples: int
    x_samples: np.ndarray
    x_to_y_face: np.ndarray
    x_to_y_bary: np.ndarray
    x_to_y_vertex: np.ndarray
    y_samples: np.ndarray
    y_to_x_face: np.ndarray
    y_to_x_bary: np.ndarray
    y_to_x_vertex: np.ndarray
    n_iter: int
    converged: bool
    seconds: float
    orientation: float = float("nan")
    distortion_trimmed: float = float("nan")
    relative_trimmed: float = float("nan")
    ranking_distance: float = float("nan")
    pair_distortion: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 0)))
    history: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    gh_interval: tuple[float, float] = (float("nan"), float("nan"))
    signature_distortion: float = float("nan")
    x_to_y_dense_face: np.ndarray | None = field(repr=False, default=None)
    x_to_y_dense_bary: np.ndarray | None = field(repr=False, default=None)
    x_to_y_dense_vertex: np.ndarray | None = field(repr=False, default=None)
    y_to_x_dense_face: np.ndarray | None = field(repr=False, default=None)
    y_to_x_dense_bary: np.ndarray | None = field(repr=False, default=None)
    y_to_x_dense_vertex: np.ndarray | None = field(repr=False, default=None)
    input_faces: tuple = field(repr=False, default=(None, None))
    partial: bool = False
    y_covered: np.ndarray | None = field(repr=False, default=None)
    covered_fraction: float = float("nan")
    x_weight: np.ndarray | None = field(repr=False, default=None)

    def to_dict(self) -> dict:
        """The JSON fields of ``gromov match --json`` but ``metric_options`` (and ``store``),
        which the command adds: the result does not hold the options its metric was made with."""
        out = {"distance": self.distance, "relative_distance": self.relative_distance,
               "distortion": {"l2": self.distortion_l2, "linf": self.distortion_linf,
                              "trimmed": self.distortion_trimmed, self.norm: self.distortion},
               "relative_trimmed_distance": self.relative_trimmed,
               "norm": self.norm, "metric": self.metric, "solver": self.solver,
               "n_samples": self.n_samples, "n_iter": self.n_iter, "converged": self.converged,
               "orientation": self.orientation if np.isfinite(self.orientation) else None,
               "gh_interval": [v if np.isfinite(v) else None for v in self.gh_interval],
               "seconds": self.seconds}
        if self.partial:
            out["partial"] = True
            out["covered_fraction"] = self.covered_fraction
            out["ranking_distance"] = self.ranking_distance if np.isfinite(self.ranking_distance) else None
        return out

    @property
    def sample_distortion(self) -> tuple[np.ndarray, np.ndarray]:
        r"""``(x, y)``: RMS distortion of each sample's pairs, for X's M samples and Y's K.

        Row ``a`` of ``pair_distortion`` without its diagonal:
        :math:`e_a = (\frac{1}{M+K-1}\sum_{b \ne a} r_{ab}^2)^{1/2}`, so that the mean of
        :math:`e_a^2` over all samples is ``distortion_l2**2``. Large where the map fits badly,
        e.g. near a change of topology (the ``pair_distortion`` note).
        """
        e = np.asarray(self.pair_distortion, dtype=float)
        n = len(e)
        if n < 2:
            return np.zeros(len(self.x_samples)), np.zeros(len(self.y_samples))
        rows = np.sqrt((e**2).sum(axis=1) / (n - 1))
        m = len(self.x_samples)
        return rows[:m], rows[m:]

    @property
    def has_dense(self) -> bool:
        """Whether the dense maps were computed (``match(..., dense=True)``)."""
        return self.x_to_y_dense_vertex is not None

    def arrays(self) -> dict:
        """The arrays of ``gromov match --out``: the correspondences, ``x_distortion``,
        ``y_distortion`` (:attr:`sample_distortion`), the dense maps when computed, and with
        ``partial`` ``y_covered`` and ``x_weight``."""
        keys = ["x_samples", "x_to_y_face", "x_to_y_bary", "x_to_y_vertex",
                "y_samples", "y_to_x_face", "y_to_x_bary", "y_to_x_vertex"]
        if self.has_dense:
            keys += [f"{d}_dense_{k}" for d in ("x_to_y", "y_to_x") for k in ("vertex", "face", "bary")
                     if getattr(self, f"{d}_dense_{k}") is not None]
        out = {k: getattr(self, k) for k in keys}
        out["x_distortion"], out["y_distortion"] = self.sample_distortion
        if self.partial:
            out["y_covered"], out["x_weight"] = self.y_covered, self.x_weight
        return out

    def transfer(self, values, *, method: str = "nearest", direction: str = "x_to_y",
                 fill=None) -> np.ndarray:
        r"""Carry a per-vertex function of X to Y (or of Y to X) through the dense map.

        ``method="nearest"``: each vertex of the target takes the value at the vertex nearest
        to its image, :math:`g(y) = f(v(T(y)))` -- for labels, segmentations and other values
        that must not be mixed. ``"barycentric"``: the value interpolated at the image,
        :math:`g(y) = \sum_c \beta_c f(c)` over the corners of the image's face -- for smooth
        functions. A map carries functions backwards: values on X reach Y through the map
        from Y to X.

        Parameters
        ----------
        values : array_like (n_X, ...) or (n_Y, ...)
            One row per file vertex of the source of the function (X for ``"x_to_y"``).
        method : {"nearest", "barycentric"}
        direction : {"x_to_y", "y_to_x"}
            Which way the function goes.
        fill : scalar, optional
            The rows of target vertices without an image: those that loading dropped, and a
            partial match's whole outside the covered region. Default: NaN for floating-point
            results, -1 for signed integers; other values (booleans, unsigned integers, text)
            need ``fill`` where such rows exist.

        Returns
        -------
        ndarray (n_Y, ...) or (n_X, ...)
        """
        if not self.has_dense:
            raise ValueError("transfer needs the dense maps: match(..., dense=True)")
        if direction not in ("x_to_y", "y_to_x"):
            raise ValueError(f"direction must be 'x_to_y' or 'y_to_x', got {direction!r}")
        if method not in ("nearest", "barycentric"):
            raise ValueError(f"method must be 'nearest' or 'barycentric', got {method!r}")
        back = "y_to_x" if direction == "x_to_y" else "x_to_y"  # the target's images on the source
        if getattr(self, f"{back}_dense_vertex") is None:
            raise ValueError(f"a partial match maps the part into the whole only: transfer values "
                             f"the other way (direction={'y_to_x' if direction == 'x_to_y' else 'x_to_y'!r})")
        vertex, face, bary = (getattr(self, f"{back}_dense_{k}") for k in ("vertex", "face", "bary"))
        n_source = len(getattr(self, f"{direction}_dense_vertex"))
        v = np.asarray(values)
        if v.shape[:1] != (n_source,):
            raise ValueError(f"values must have one row per vertex of the source shape ({n_source}), "
                             f"got shape {v.shape}")
        faces = self.input_faces[0 if direction == "x_to_y" else 1]
        ok = vertex >= 0
        if method == "barycentric" and faces is None:
            raise ValueError("barycentric transfer needs faces on the shape the values live on "
                             "(a point cloud has none): use method='nearest'")
        if method == "nearest":
            out = v[np.where(ok, vertex, 0)]
        else:
            corners = faces[np.where(face >= 0, face, 0)]
            w = np.nan_to_num(bary).reshape(bary.shape + (1,) * (v.ndim - 1))
            out = (v[corners] * w).sum(axis=1)
        if not ok.all():
            if fill is None and out.dtype.kind not in "fci":
                raise ValueError(f"{int((~ok).sum())} vertices of the target have no image, and values of "
                                 f"dtype {out.dtype} have no default for them: give fill=")
            out[~ok] = fill if fill is not None else (np.nan if out.dtype.kind in "fc" else -1)
        return out
