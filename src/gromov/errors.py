"""Exceptions raised by gromov.

Every error that a user can cause derives from :class:`GromovError` and from the
built-in exception that fits it (``ValueError``, ``FileNotFoundError``...), so
``except ValueError`` keeps working for callers that do not know our types.
"""

from __future__ import annotations

__all__ = ["GromovError", "GromovWarning", "MeshError", "MeshFormatError", "MetricError", "SmallPartWarning"]


class GromovError(Exception):
    """Base class of the errors gromov raises on purpose."""


class MeshError(GromovError, ValueError):
    """A mesh or point cloud is invalid (NaN coordinates, bad face indices, empty...)."""


class MeshFormatError(MeshError):
    """A mesh file cannot be read: unknown format, truncated or malformed content.

    The message always names the file.
    """


class MetricError(GromovError, ValueError):
    """A distance cannot be computed on the given shape with the given parameters."""


class GromovWarning(UserWarning):
    """Something was repaired or approximated; the result is still usable."""


class SmallPartWarning(GromovWarning):
    """A part given to partial matching holds a small share of the whole's area
    (:data:`gromov.partial.SMALL_PART`): it gets a map and a distance, but where it lies on the
    whole is unreliable, and a small part fits almost anywhere with a low distance."""
