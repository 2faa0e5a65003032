"""Named sides of a domain's outline: where a measured force (forces.csv) crosses the boundary.

A force is only meaningful across a well-defined piece of the outline. A rectangle has four
(``left``, ``right``, ``bottom``, ``top``); any 2D domain may name more in experiment.toml:

    domain = { polygon = [...], sides = { grip = [[120.0, 10.0], [120.0, 70.0]] } }

A side is the stretch of the outer outline that runs counter-clockwise (the material on its
left) from the place nearest its first end to the place nearest its second. An end is a
position ``[x, y]`` (length unit) or, for a polygon, the index of one of its vertices (from 0).
"""

from __future__ import annotations

import math

from refine.exceptions import ExperimentError

Side = tuple  # (name, first end, second end); an end is (x, y) or a vertex index

EXAMPLE = 'sides = { NAME = [[x0, y0], [x1, y1]] }'


def _end(value, what: str):
    if isinstance(value, int) and not isinstance(value, bool):
        if value < 0:
            raise ExperimentError(f"{what} is a vertex index and must be >= 0, got {value}")
        return value
    try:
        x, y = (float(c) for c in value)
    except (TypeError, ValueError):
        raise ExperimentError(f"{what} must be a position [x, y] or a polygon vertex index, got {value!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise ExperimentError(f"{what} has a NaN or inf coordinate")
    return (x, y)


def sides_from_toml(table) -> tuple[Side, ...]:
    """``domain.sides`` (a table name -> [first end, second end]) as a tuple of (name, a, b)."""
    if not table:
        return ()
    if not isinstance(table, dict):
        raise ExperimentError(f"domain.sides must be a table, e.g. {EXAMPLE}; got {table!r}")
    out = []
    for name, ends in table.items():
        if not isinstance(ends, (list, tuple)) or len(ends) != 2:
            raise ExperimentError(f"domain.sides.{name} must list two ends (from, to counter-clockwise), e.g. "
                                  f"{EXAMPLE}; got {ends!r}")
        out.append((str(name), _end(ends[0], f"domain.sides.{name}[0]"), _end(ends[1], f"domain.sides.{name}[1]")))
    return tuple(out)


def checked_sides(sides, n_vertices: int | None) -> tuple[Side, ...]:
    """``sides`` (pairs or the TOML table) checked: vertex indices only where the domain has
    ``n_vertices`` (a polygon), and below that count."""
    sides = sides_from_toml(sides) if isinstance(sides, dict) else tuple(
        (str(n), _end(a, f"domain.sides.{n}[0]"), _end(b, f"domain.sides.{n}[1]")) for n, a, b in sides)
    for name, *ends in sides:
        for e in ends:
            if isinstance(e, int) and (n_vertices is None or e >= n_vertices):
                raise ExperimentError(f"domain.sides.{name}: vertex index {e} " + (
                    "is only for a polygon domain; give a position [x, y]" if n_vertices is None
                    else f"is out of range (the polygon has {n_vertices} vertices)"))
    return sides


def sides_to_toml(sides) -> dict:
    """The ``sides`` entry of the domain's TOML table (empty when there are none)."""
    return {"sides": {n: [a if isinstance(a, int) else list(a), b if isinstance(b, int) else list(b)]
                      for n, a, b in sides}} if sides else {}


def undefined_side(name: str, known) -> str:
    """The message for a force on a side the domain does not define (no guess is made)."""
    listed = f"the domain's sides are {list(known)}" if known else "the domain names no sides"
    return (f"unknown edge {name!r}: the domain does not define that side ({listed}). Name it in experiment.toml, "
            f"e.g. domain = {{ ..., sides = {{ {name} = [[x0, y0], [x1, y1]] }} }}: the outline counter-clockwise "
            "from the place nearest [x0, y0] to the place nearest [x1, y1] (a polygon may give vertex indices); "
            "left/right/bottom/top are defined for a rectangle only")
