"""Optimisers, one method per module, all returning a :class:`RefineResult`.

- :func:`least_squares` (Gauss-Newton / Levenberg-Marquardt, exact Jacobians) and
  :func:`levenberg_marquardt` (the same on a :class:`~refine.model.Compiled` model, reused across
  point sets): a handful of unknowns;
- :func:`lbfgsb`: bounded L-BFGS with adjoint gradients, for fields of many unknowns;
- :func:`pade_least_squares`: Pade steps on the equilibrium's Taylor series, one unknown;
- :func:`tensor_least_squares`: third-order Taylor models of the residuals;
- :func:`brent_search`, :func:`cubic_brent_search`, :func:`coordinate_brent_search`: the paper's
  one-parameter searches (baselines), on any scalar function.
"""

from refine.optimize.brent import brent_search, parabola_vertex
from refine.optimize.coordinate import coordinate_brent_search
from refine.optimize.cubic import cubic_brent_search, cubic_minimum, spread_points
from refine.optimize.lbfgsb import lbfgsb
from refine.optimize.least_squares import least_squares
from refine.optimize.levenberg_marquardt import levenberg_marquardt
from refine.optimize.pade import pade_least_squares
from refine.optimize.result import RefineResult
from refine.optimize.tensor_method import tensor_least_squares

__all__ = ["RefineResult", "brent_search", "coordinate_brent_search", "cubic_brent_search", "cubic_minimum",
           "lbfgsb", "least_squares", "levenberg_marquardt", "pade_least_squares", "parabola_vertex",
           "spread_points", "tensor_least_squares"]
