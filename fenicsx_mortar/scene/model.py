"""Scenes: what is simulated, as validated dataclasses, read from TOML or built in Python.

A scene declares its effects (materials, loads, contact pairs, friction, smoothing) and the
run builds only those. Field-by-field documentation: ``docs/scenes.md``.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from ..settings import SolverSettings

#: upper bounds of the sizes that drive memory or time (docs/scenes.md): cells of a
#: generated mesh (estimated before meshing) or of a mesh file, and the size of a scene file;
#: the bounds of every other number are settings.RANGES, shared with the library API
LIMITS = {"cells": 1_000_000, "scene_bytes": 8 << 20}
#: the largest size of any number of a scene: products of two stay far from the largest float
#: (1.8e308); no physical quantity in any units comes near it
MAGNITUDE = 1e100
#: the deepest nesting of tables and lists in a scene file or a saved scene (a scene needs 4:
#: contacts[0].enforcement.epsilon); deeper input is refused before Python's recursion is
MAX_DEPTH = 32
#: names that become file names or labels (contact pairs, supports)
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]{0,63}")


def generators() -> list[str]:
    """The mesh generators shipped in :mod:`fenicsx_mortar.meshes` (the ``meshes/`` folder
    of the source tree)."""
    from importlib import resources
    return sorted(p.name[:-3] for p in resources.files("fenicsx_mortar.meshes").iterdir()
                  if p.name.endswith(".py") and not p.name.startswith("_"))


class SceneError(ValueError):
    """A scene that cannot be run; the message names the offending key or file."""


# --------------------------------------------------------------------------- dataclasses


@dataclass
class MeshSource:
    """Where the mesh comes from: a generator (``fenicsx_mortar.meshes.<generator>``, the
    source tree's ``meshes/<generator>.py``) or a gmsh ``file``."""
    generator: str | None = None
    file: str | None = None
    cell: Literal["quadrilateral", "triangle"] | None = None  # generators: quadrilateral
    params: dict[str, bool | int | float | str] = field(default_factory=dict)


@dataclass
class Material:
    """Hyperelastic (or linear) material, plane strain. docs/design.md §2."""
    model: Literal["neo-hooke", "svk", "linear"]
    E: float
    nu: float


@dataclass
class Body:
    """A deformable body: the cells of one physical surface group."""
    name: str
    material: Material
    region: str | None = None  # physical surface group; defaults to ``name``

    @property
    def group(self) -> str:
        return self.region or self.name


@dataclass
class LoadCurve:
    """Piecewise-linear load factor over pseudo-time (constant beyond the ends)."""
    t: list[float]
    value: list[float]

    def __call__(self, time: float) -> float:
        t, v = self.t, self.value
        if time <= t[0]:
            return v[0]
        for k in range(1, len(t)):
            if time <= t[k]:
                w = (time - t[k - 1]) / (t[k] - t[k - 1])
                return (1.0 - w) * v[k - 1] + w * v[k]
        return v[-1]


RAMP = LoadCurve(t=[0.0, 1.0], value=[0.0, 1.0])


@dataclass
class RigidMotion:
    """x(X) = c + R(φ) (X + d − c): translation d = ``translation`` × its curve, then a turn
    φ = ``rotation`` (radians, anticlockwise) × its curve about ``center``."""
    center: list[float] = field(default_factory=lambda: [0.0, 0.0])
    translation: list[float] = field(default_factory=lambda: [0.0, 0.0])
    translation_curve: str = "ramp"
    rotation: float = 0.0
    rotation_curve: str = "ramp"

    def displacement(self, X, s_translate: float, s_rotate: float):
        """u = x(X) − X at arrays X = (x, y) for the given curve values."""
        c0, c1 = self.center
        phi = self.rotation * s_rotate
        px = X[0] + self.translation[0] * s_translate - c0
        py = X[1] + self.translation[1] * s_translate - c1
        cos, sin = math.cos(phi), math.sin(phi)
        return c0 + cos * px - sin * py - X[0], c1 + sin * px + cos * py - X[1]


@dataclass
class Dirichlet:
    """Prescribed displacement components on a boundary group or at a point of a body, or
    a rigid motion of a boundary group (both components)."""
    boundary: str | list[str] | None = None
    point: list[float] | None = None
    body: str | None = None
    x: float | None = None
    y: float | None = None
    curve: str = "ramp"
    motion: RigidMotion | None = None
    name: str | None = None

    @property
    def label(self) -> str:
        if self.name:
            return self.name
        if self.boundary is not None:
            return "+".join(as_list(self.boundary))
        return f"{self.body}@({self.point[0]:g},{self.point[1]:g})"


@dataclass
class Pressure:
    """Normal pressure p (positive pushes into the body); follower by default."""
    boundary: str | list[str]
    value: float
    follower: bool = True
    curve: str = "ramp"


@dataclass
class Traction:
    """Dead traction vector per unit reference length."""
    boundary: str | list[str]
    value: list[float]
    curve: str = "ramp"


@dataclass
class Enforcement:
    """Normal-contact enforcement: a registered name (``ENFORCEMENTS``: lagrange, penalty,
    alm, …). docs/design.md §5, §5a."""
    type: str = "lagrange"
    # default E/h (slave body; lagrange: the softer body's); ALM starts at min(epsilon, E/h)
    epsilon: float | None = None
    tolerance: float = 1e-10      # ALM: KKT residual (relative to the pressure scale)
    max_augmentations: int = 30


@dataclass
class Friction:
    """A registered friction law (``FRICTION_LAWS``: none, coulomb, …) and its coefficient."""
    law: str = "none"
    mu: float = 0.0


@dataclass
class Contact:
    """A slave (non-mortar) and a master (mortar) surface that may touch; ``method`` and
    ``smoothing`` are registered names (``METHODS``, ``SMOOTHINGS`` in
    :mod:`fenicsx_mortar.contact.registry`)."""
    name: str
    slave: str | list[str]
    master: str | list[str]
    method: str = "mortar"
    enforcement: Enforcement = field(default_factory=Enforcement)
    friction: Friction = field(default_factory=Friction)
    smoothing: str = "none"
    search_radius: float | None = None  # default: two slave element sizes
    #: the weight of the weighted gaps (the multiplier space): "standard" (the slave's hat
    #: functions) or "dual" (biorthogonal); default: dual where the multipliers are
    #: unknowns (enforcement "lagrange") and the method offers it (mortar), else standard
    basis: str | None = None
    #: two-sided smoothing: the slave's geometry in the mortar integrals from its own
    #: smoothed curve ("hermite"), its test functions linear; "none": the slave chords
    slave_smoothing: str = "none"
    n_gauss: int | None = None  # default: the master curve's (2 polyline, 4 smoothed)


@dataclass
class Steps:
    """Pseudo-time stepping: ``count`` equal increments up to ``end``, or explicit ``times``."""
    end: float = 1.0
    count: int | None = None
    times: list[float] | None = None
    max_cuts: int = 6
    min_increment: float | None = None  # floor of cut increments; default 1e-4 × final time

    def floor(self) -> float:
        return self.min_increment if self.min_increment is not None else 1e-4 * self.targets()[-1]

    def targets(self) -> list[float]:
        if self.times is not None:
            return list(self.times)
        n = self.count or 1
        return [self.end * (k + 1) / n for k in range(n)]


@dataclass
class OutputSettings:
    xdmf: bool = True
    plots: bool = True


@dataclass
class Scene:
    """Everything a run needs. ``base_dir`` resolves relative mesh files."""
    mesh: MeshSource
    bodies: list[Body]
    title: str = ""
    description: str = ""
    dirichlet: list[Dirichlet] = field(default_factory=list)
    pressures: list[Pressure] = field(default_factory=list)
    tractions: list[Traction] = field(default_factory=list)
    curves: dict[str, LoadCurve] = field(default_factory=dict)
    contacts: list[Contact] = field(default_factory=list)
    steps: Steps = field(default_factory=Steps)
    solver: SolverSettings = field(default_factory=SolverSettings)
    output: OutputSettings = field(default_factory=OutputSettings)
    base_dir: str = "."

    def curve(self, name: str) -> LoadCurve:
        return RAMP if name == "ramp" and "ramp" not in self.curves else self.curves[name]

    def effects(self) -> list[str]:
        """The physics this scene switches on, one line each (logged first in a run)."""
        out = []
        models: dict[str, list[str]] = {}
        for b in self.bodies:
            models.setdefault(b.material.model, []).append(b.name)
        for m, names in models.items():
            out.append(f"material {m}: {', '.join(names)}")
        if self.dirichlet:
            out.append(f"dirichlet: {', '.join(d.label for d in self.dirichlet)}")
        for p in self.pressures:
            kind = "follower" if p.follower else "dead"
            out.append(f"pressure ({kind}): {'+'.join(as_list(p.boundary))}")
        for t in self.tractions:
            out.append(f"traction (dead): {'+'.join(as_list(t.boundary))}")
        for c in self.contacts:
            fr = "frictionless" if c.friction.law == "none" else f"coulomb mu={c.friction.mu:g}"
            out.append(f"contact {c.name}: {c.method}, {c.enforcement.type}, {fr}, "
                       f"smoothing {c.smoothing}")
        return out

    def validate(self) -> "Scene":
        """Semantic checks that do not need the mesh (:mod:`.validation`); raise
        SceneError naming the key."""
        from .validation import validate
        validate(self)
        return self

    def mesh_file(self) -> Path:
        p = Path(self.mesh.file)
        return p if p.is_absolute() else Path(self.base_dir) / p

    def groups_used(self) -> tuple[set[str], set[str]]:
        """(surface groups, curve groups) the scene refers to, to check against the mesh."""
        cells = {b.group for b in self.bodies}
        facets: set[str] = set()
        for item in (*self.dirichlet, *self.pressures, *self.tractions):
            if item.boundary is not None:
                facets.update(as_list(item.boundary))
        for c in self.contacts:
            facets.update(as_list(c.slave))
            facets.update(as_list(c.master))
        return cells, facets


def as_list(v: str | list[str]) -> list[str]:
    return [v] if isinstance(v, str) else list(v)
