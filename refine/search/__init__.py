"""Derivative-free searches over model parameters, each returning a :class:`refine.result.RefineResult`.

- :func:`brent`: one parameter, Brent's method as in the paper (Sec. 2.1, eq. 2).
- :func:`cubic_brent`: one parameter, the paper's cubic fit over a wide bracket, then Brent (Sec. 3.1).
- :func:`coordinate_brent`: several parameters, cycled 1-D Brent searches (a baseline).
"""

from .brent import brent, parabola_vertex
from .coordinate import coordinate_brent
from .cubic import cubic_brent, cubic_minimum, spread_points

__all__ = ["brent", "coordinate_brent", "cubic_brent", "cubic_minimum", "parabola_vertex", "spread_points"]
