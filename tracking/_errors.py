"""Exceptions raised by the tracking package."""


class TrackingError(ValueError):
    """Base class of every error the tracking package raises on purpose.

    The message names the problem and what to change (a region of interest, an option, an image).
    """


class ImageError(TrackingError):
    """The images cannot be used: unreadable, NaN or infinite values, different shapes."""


class RoiError(TrackingError):
    """The region of interest is malformed or lies (partly) outside the image."""


class GridNotFoundError(TrackingError):
    """No regular grid of lines could be detected in the reference image."""
