"""Exceptions raised by the tracking package."""


class TrackingError(ValueError):
    """Base class of every error the tracking package raises on purpose.

    The message names the problem and what to change (a region of interest, an option, an image).
    It is a ``ValueError``, so callers that caught ``ValueError`` before still catch it.
    """


class ImageError(TrackingError):
    """The images cannot be used: unreadable, NaN or infinite values, different shapes."""


class RoiError(TrackingError):
    """The region of interest is malformed or lies (partly) outside the image."""


class OptionError(TrackingError):
    """An option of a tracker or of a function has a value it cannot take; the message lists the valid ones."""


class GridNotFoundError(TrackingError):
    """No regular grid of lines could be detected in the reference image.

    ``stage`` names where the grid tracker stopped: ``"lattice"`` (the spectrum shows no two
    line families: pitch and orientation unknown), ``"mask"`` (the grid's texture covers almost
    none of the region of interest) or ``"crossings"`` (too few crossings found, labelled or
    measured); None where no stage applies. The message says what to try.
    """

    def __init__(self, message: str, stage: str | None = None):
        super().__init__(message)
        self.stage = stage
