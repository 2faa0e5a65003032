"""Derivative-free searches over model parameters, each returning a :class:`refine.result.RefineResult`.

- :func:`brent_search`: one parameter, Brent's method as in the paper (Sec. 2.1, eq. 2).
- :func:`cubic_brent_search`: one parameter, the paper's cubic fit over a wide bracket, then Brent
  in a narrow bracket around the cubic's minimum (Sec. 3.1).
- :func:`coordinate_brent_search`: several parameters, cycled 1-D Brent searches (a baseline).
"""

from .brent import brent_search, parabola_vertex
from .coordinate import coordinate_brent_search
from .cubic import cubic_brent_search, cubic_minimum, spread_points

__all__ = [
    "brent_search",
    "coordinate_brent_search",
    "cubic_brent_search",
    "cubic_minimum",
    "parabola_vertex",
    "spread_points",
]
