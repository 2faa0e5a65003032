"""Tracking without correspondences in 3D: a tet10 block with a 6-DOF grip seen by one range camera.

The 3D case of :mod:`benchmarks.correspondence` (its ``--dim 3``; the same options): a 40 x 20 x
20 mm block clamped at its left face, its right face moved by a random 6-DOF rigid motion,
optionally hiding a stiff sphere, seen as the points where a range camera's rays meet its surface
(depth noise 0.02 mm). Writes benchmarks/results/correspondence3d.json and .png.
"""

from __future__ import annotations

import sys

from benchmarks import correspondence


def main(argv=None) -> int:
    return correspondence.main(["--dim", "3", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    raise SystemExit(main())
