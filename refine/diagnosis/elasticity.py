"""Ground-truth and relative elasticity (the paper's Sec. 2.2, eqs. 6-8).

All functions accept floats or numpy arrays (broadcast) and use any consistent unit set.
"""

from __future__ import annotations

import numpy as np

from refine.exceptions import ExperimentError

STANDARD_GRAVITY = 9.80665
"""Standard acceleration of gravity g, m/s^2."""


def strip_modulus(length, area, elongation, *, force=None, mass=None, g=STANDARD_GRAVITY):
    """Young's modulus of a homogeneous strip under a hanging weight, eq. (6): E = P L / (A dL).

    The strip's strain dL / L equals the stress P / A over E (eqs. 3-5), with the weight P = m g.
    Give either ``force`` (P) or ``mass`` (m, then P = m g).

    Args:
        length: unstretched length L of the stretchable part.
        area: cross-section A = width x thickness.
        elongation: change of length dL under the load (same unit as L).
        force: the pulling force P, e.g. N.
        mass: the hanging mass m, e.g. kg (with g in m/s^2 this gives P in N).
        g: acceleration of gravity, default 9.80665 m/s^2.

    Returns:
        E in force / area: with P in N and A in m^2, Pa; with P in mN and A in mm^2, kPa.
    """
    if (force is None) == (mass is None):
        raise ExperimentError("give exactly one of force= (P) or mass= (m, with P = m g)")
    load = np.asarray(force if force is not None else np.asarray(mass, np.float64) * g, np.float64)
    length, area, elongation = (np.asarray(v, np.float64) for v in (length, area, elongation))
    if np.any(area <= 0) or np.any(elongation <= 0) or np.any(length <= 0):
        raise ExperimentError("length, area and elongation must be positive")
    return _plain(load * length / (area * elongation))


def apparent_modulus(modulus, true_thickness, assumed_thickness):
    """What a model with the wrong thickness recovers, eq. (7): E2 b2 / b1.

    A region of modulus E2 and thickness b2, modelled with thickness b1, behaves like (and is
    identified as) a region of modulus E2 b2 / b1: only the product E b is observable.

    Args:
        modulus: the region's true modulus E2, stress unit.
        true_thickness: its true thickness b2, length unit.
        assumed_thickness: the thickness b1 the model uses, same length unit.

    Returns:
        The apparent modulus, stress unit.
    """
    b1 = np.asarray(assumed_thickness, np.float64)
    if np.any(b1 <= 0):
        raise ExperimentError(f"assumed_thickness must be positive, got {assumed_thickness!r}")
    return _plain(np.asarray(modulus, np.float64) * np.asarray(true_thickness, np.float64) / b1)


def relative_elasticity(region_modulus, background_modulus, region_thickness=1.0, background_thickness=1.0):
    """Relative elasticity, eq. (8): E_R = (E2 b2) / (E1 b1), dimensionless.

    With both moduli fitted under the same assumed thickness (the usual case: thickness unknown),
    leave the thicknesses at 1: the ratio of the fitted moduli is E_R. 0 for a hole; > 1 stiffer.

    Args:
        region_modulus: E2 of the abnormal region, stress unit.
        background_modulus: E1 of the surrounding material, same unit, > 0.
        region_thickness: b2, length unit.
        background_thickness: b1, same unit.
    """
    denominator = np.asarray(background_modulus, np.float64) * np.asarray(background_thickness, np.float64)
    if np.any(denominator <= 0):
        raise ExperimentError("background modulus and thickness must be positive")
    return _plain(np.asarray(region_modulus, np.float64) * np.asarray(region_thickness, np.float64) / denominator)


def _plain(value: np.ndarray):
    """A float for scalar input, the array otherwise."""
    return float(value) if value.ndim == 0 else value
