"""B-spline interpolation of images: values anywhere, exact gradients on the pixel lattice."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import ndimage
from scipy.interpolate import BSpline

from ._errors import OptionError

_MODE = "mirror"


@lru_cache(maxsize=None)
def _bspline_kernels(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Centred B-spline of ``order`` and its derivative sampled at the integers -r..r."""
    radius = (order + 1) // 2
    ticks = np.arange(-radius, radius + 1, dtype=np.float64)

    def basis(m):
        return BSpline.basis_element(np.arange(m + 2) - (m + 1) / 2.0, extrapolate=False)

    values = np.nan_to_num(basis(order)(ticks))
    lower = basis(order - 1)
    derivative = np.nan_to_num(lower(ticks + 0.5)) - np.nan_to_num(lower(ticks - 0.5))
    return values, derivative


@dataclass(frozen=True)
class SplineImage:
    """An image seen through its B-spline interpolant (order 3 = bicubic, 5 = quintic).

    Attributes:
        image: (rows, cols) float64 grey values.
        coefficients: (rows, cols) B-spline coefficients (mirror boundary).
        order: spline order.
    """

    image: np.ndarray
    coefficients: np.ndarray
    order: int

    @property
    def shape(self) -> tuple[int, int]:
        return self.image.shape

    def values(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Interpolated grey values at (x, y) (any equal shapes, pixels); outside: mirrored image."""
        x = np.asarray(x, dtype=np.float64)
        coords = np.stack([np.asarray(y, dtype=np.float64).ravel(), x.ravel()])
        out = ndimage.map_coordinates(self.coefficients, coords, order=self.order,
                                      prefilter=False, mode=_MODE)
        return out.reshape(x.shape)

    def lattice_gradient(self) -> tuple[np.ndarray, np.ndarray]:
        """Exact derivatives (d/dx, d/dy) of the interpolant at the pixel centres, two (rows, cols)."""
        values, derivative = _bspline_kernels(self.order)
        # f'(j) = sum_m c[j - m] beta'(m): a true convolution, which is what convolve1d does
        gx = ndimage.convolve1d(self.coefficients, derivative, axis=1, mode=_MODE)
        gx = ndimage.convolve1d(gx, values, axis=0, mode=_MODE)
        gy = ndimage.convolve1d(self.coefficients, derivative, axis=0, mode=_MODE)
        gy = ndimage.convolve1d(gy, values, axis=1, mode=_MODE)
        return gx, gy

    def inside(self, x: np.ndarray, y: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Bool, same shape as x: the point lies at least ``margin`` px inside the pixel centres."""
        rows, cols = self.shape
        return ((x >= margin) & (y >= margin) & (x <= cols - 1 - margin) & (y <= rows - 1 - margin))


def spline_image(image: np.ndarray, order: int = 3) -> SplineImage:
    """Prefilter ``image`` (rows, cols) for B-spline interpolation of the given order (2..5)."""
    if order not in (2, 3, 4, 5):
        raise OptionError(f"spline order must be 2, 3, 4 or 5, got {order}; "
                          "pass one of them as the tracker's order option (3, cubic, is the default)")
    image = np.asarray(image, dtype=np.float64)
    coefficients = ndimage.spline_filter(image, order=order, mode=_MODE, output=np.float64)
    return SplineImage(image=image, coefficients=coefficients, order=order)
