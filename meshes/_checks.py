"""Parameter checks shared by the generators. Each generator's ``cells(**params)`` runs
them and returns the number of cells ``build`` would make, so a scene is refused before
any meshing (gmsh aborts the process on some geometries and allocates without bound on
large counts); ``build`` runs the same checks first."""
from __future__ import annotations

import math
from numbers import Integral, Real

CELLS = ("quadrilateral", "triangle")
#: lengths and coordinates gmsh's geometry kernel handles (its tolerance is 1e-8)
SHORTEST, LONGEST = 1e-6, 1e6


def cell(cell: str) -> int:
    """Cells per grid quadrilateral: 1, or 2 triangles."""
    if cell not in CELLS:
        raise ValueError(f"cell must be one of {CELLS}, got {cell!r}")
    return 1 if cell == "quadrilateral" else 2


def divisions(low: int = 1, **values) -> None:
    for name, value in values.items():
        if isinstance(value, bool) or not isinstance(value, Integral) or value < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")


def lengths(**values) -> None:
    for name, value in values.items():
        number(name, value)
        if not SHORTEST <= value <= LONGEST:
            raise ValueError(f"{name} must lie in [{SHORTEST:g}, {LONGEST:g}], got {value!r}")


def coordinates(**values) -> None:
    for name, value in values.items():
        number(name, value)
        if not abs(value) <= LONGEST:
            raise ValueError(f"{name} must lie in [-{LONGEST:g}, {LONGEST:g}], got {value!r}")


def number(name: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
