"""Scenes: what is simulated, as validated dataclasses, read from TOML or built in Python.

A scene declares its effects (materials, loads, contact pairs, friction, smoothing) and the
run builds only those. Field-by-field documentation: ``docs/scenes.md``.
"""
from __future__ import annotations

import dataclasses
import importlib
import math
import re
import stat
import tomllib
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, Union

from .settings import CONDENSED_SOLVERS, SolverSettings

#: upper bounds of the numbers that drive memory or time (docs/scenes.md): cells of a
#: generated mesh (estimated before meshing) or of a mesh file, load steps, cuts in a row,
#: Gauss points per mortar segment, bulk quadrature degree, Newton iterations per solve,
#: ALM updates per step, and the size of a scene file
LIMITS = {"cells": 1_000_000, "steps": 100_000, "max_cuts": 50, "n_gauss": 16,
          "quadrature_degree": 16, "max_iterations": 1000, "max_augmentations": 1000,
          "scene_bytes": 8 << 20}
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

    # ------------------------------------------------------------------ validation
    def validate(self) -> "Scene":
        """Semantic checks that do not need the mesh; raise SceneError naming the key.
        Every float must be finite (TOML has nan and inf), every number lie in its range
        (docs/scenes.md), and the numbers that drive memory or time have upper bounds
        (LIMITS; the cell count of a generator's mesh is estimated before meshing)."""
        _check_finite(self, "")
        self._check_mesh()
        self._check_bodies()
        self._check_curves()
        self._check_loads()
        self._check_dirichlet()
        self._check_contacts()
        self._check_steps()
        self._check_solver()
        return self

    def _check_mesh(self) -> None:
        ms = self.mesh
        if (ms.generator is None) == (ms.file is None):
            raise SceneError("mesh: give exactly one of 'generator' or 'file'")
        if ms.file is not None:
            _check_mesh_file(self.mesh_file())
            if ms.params:
                raise SceneError("mesh.params: generator parameters, but the mesh is a file")
            if ms.cell is not None:
                raise SceneError(f"mesh.cell = {ms.cell!r}: for generators only (a mesh file's "
                                 "cells are its own)")
            return
        if ms.generator not in generators():
            raise SceneError(f"mesh.generator = {ms.generator!r}: no such generator "
                             f"(known: {', '.join(generators())})")
        _check_generator(ms)

    def _check_bodies(self) -> None:
        if not self.bodies:
            raise SceneError("bodies: a scene needs at least one body")
        _unique([b.name for b in self.bodies], "bodies[].name")
        regions: dict[str, int] = {}
        for i, b in enumerate(self.bodies):
            m, key = b.material, f"bodies[{i}].material"
            if not (m.E > 0 and math.isfinite(m.E)):
                raise SceneError(f"{key}.E = {m.E}: Young's modulus must be positive")
            if not (-1.0 < m.nu < 0.5):
                raise SceneError(f"{key}.nu = {m.nu}: Poisson's ratio must lie in (-1, 0.5)")
            _check_group(b.group, f"bodies[{i}].region")
            if b.group in regions:
                raise SceneError(f"bodies[{i}].region = {b.group!r}: also the region of "
                                 f"bodies[{regions[b.group]}] (one body per region: two would "
                                 "add their stiffness)")
            regions[b.group] = i

    def _check_curves(self) -> None:
        for name, c in self.curves.items():
            key = f"curves.{name}"
            if len(c.t) != len(c.value) or len(c.t) < 2:
                raise SceneError(f"{key}: 't' and 'value' need the same length (>= 2)")
            if any(b <= a for a, b in zip(c.t, c.t[1:])):
                raise SceneError(f"{key}.t must increase strictly")
            # the interpolation divides by t[k] - t[k-1]: an infinite difference would make
            # the curve 0 inside that interval, silently
            if any(not math.isfinite(b - a) for a, b in zip(c.t, c.t[1:])):
                raise SceneError(f"{key}.t: the span between two points overflows "
                                 "(beyond 1.8e308)")
        for kind, items in (("dirichlet", self.dirichlet), ("pressures", self.pressures),
                            ("tractions", self.tractions)):
            for i, item in enumerate(items):
                if item.curve != "ramp" and item.curve not in self.curves:
                    raise SceneError(f"{kind}[{i}].curve = {item.curve!r}: no such curve "
                                     f"(define [curves.{item.curve}])")

    def _check_loads(self) -> None:
        for kind, items in (("pressures", self.pressures), ("tractions", self.tractions)):
            for i, item in enumerate(items):
                _check_groups(item.boundary, f"{kind}[{i}].boundary")
        for i, t in enumerate(self.tractions):
            if len(t.value) != 2:
                raise SceneError(f"tractions[{i}].value must be [tx, ty]")

    def _check_dirichlet(self) -> None:
        names = [b.name for b in self.bodies]
        held: dict[tuple, str] = {}   # (where, component) -> the entry prescribing it
        for i, d in enumerate(self.dirichlet):
            key = f"dirichlet[{i}]"
            if (d.boundary is None) == (d.point is None):
                raise SceneError(f"{key}: give exactly one of 'boundary' or 'point'")
            if d.name is not None:
                _check_name(d.name, f"{key}.name")
            if d.point is not None:
                if len(d.point) != 2:
                    raise SceneError(f"{key}.point must be [x, y]")
                if d.body not in names:
                    raise SceneError(f"{key}.body = {d.body!r}: a point condition names one "
                                     f"of the bodies ({', '.join(names)})")
                places = [(d.body, *d.point)]
            else:
                _check_groups(d.boundary, f"{key}.boundary")
                if d.body is not None:
                    raise SceneError(f"{key}.body = {d.body!r}: for a 'point' condition only "
                                     "(a boundary names its own nodes)")
                places = as_list(d.boundary)
            if d.motion is not None:
                if d.boundary is None or d.x is not None or d.y is not None:
                    raise SceneError(f"{key}.motion: a rigid motion moves a whole 'boundary' "
                                     "(both components); do not give 'x', 'y' or 'point'")
                m = d.motion
                if len(m.center) != 2 or len(m.translation) != 2:
                    raise SceneError(f"{key}.motion: center and translation must be [x, y]")
                for c in (m.translation_curve, m.rotation_curve):
                    if c != "ramp" and c not in self.curves:
                        raise SceneError(f"{key}.motion: no such curve {c!r}")
                comps = ("x", "y")
            elif d.x is None and d.y is None:
                raise SceneError(f"{key}: prescribe at least one component ('x' or 'y')")
            else:
                comps = tuple(c for c in ("x", "y") if getattr(d, c) is not None)
            for place in places:
                for c in comps:
                    if (place, c) in held:
                        raise SceneError(f"{key}.{c}: {_place(place)} has its {c} prescribed "
                                         f"by {held[place, c]} already (one value per node)")
                    held[place, c] = key
        free = [c for c in ("x", "y") if not any(k[1] == c for k in held)]
        if free:
            raise SceneError(f"dirichlet: no entry prescribes {' or '.join(free)}: the bodies "
                             f"could move rigidly along {' and '.join(free)} (a singular "
                             "stiffness; contact between the bodies does not hold them)")

    def _check_contacts(self) -> None:
        _unique([c.name for c in self.contacts], "contacts[].name")
        from .contact.registry import ENFORCEMENTS, FRICTION_LAWS, METHODS, SMOOTHINGS
        for i, c in enumerate(self.contacts):
            key = f"contacts[{i}]"
            _check_name(c.name, f"{key}.name")
            for name, value, registry in (("method", c.method, METHODS),
                                          ("smoothing", c.smoothing, SMOOTHINGS),
                                          ("enforcement.type", c.enforcement.type, ENFORCEMENTS),
                                          ("friction.law", c.friction.law, FRICTION_LAWS)):
                if value not in registry:
                    raise SceneError(f"{key}.{name} = {value!r}: must be one of "
                                     f"{', '.join(map(repr, registry.names()))}")
            if c.slave_smoothing != "none" and (c.slave_smoothing not in SMOOTHINGS
                                                or not METHODS[c.method].two_sided):
                raise SceneError(f"{key}.slave_smoothing = {c.slave_smoothing!r}: only the "
                                 "mortar method smooths the slave surface, with a local curve "
                                 "('hermite')")
            if c.basis is not None and c.basis not in METHODS[c.method].bases:
                raise SceneError(f"{key}.basis = {c.basis!r}: method {c.method!r} offers "
                                 f"{', '.join(map(repr, METHODS[c.method].bases))}")
            _check_groups(c.slave, f"{key}.slave")
            _check_groups(c.master, f"{key}.master")
            both = sorted(set(as_list(c.slave)) & set(as_list(c.master)))
            if both:
                raise SceneError(f"{key}: slave and master surfaces must differ "
                                 f"(both name {both})")
            for j, other in enumerate(self.contacts[:i]):
                if (set(as_list(c.slave)) & set(as_list(other.slave))
                        and set(as_list(c.master)) & set(as_list(other.master))):
                    raise SceneError(f"{key}: the same slave and master surfaces as "
                                     f"contacts[{j}] ({other.name!r}): the contact would be "
                                     "counted twice (with multipliers: a singular system)")
                if (set(as_list(c.slave)) & set(as_list(other.master))
                        and set(as_list(c.master)) & set(as_list(other.slave))):
                    raise SceneError(f"{key}: the surfaces of contacts[{j}] ({other.name!r}) "
                                     "with slave and master swapped: the contact would be "
                                     "counted twice (with multipliers: a singular system)")
            e = c.enforcement
            lu = self.solver.petsc.get("-pc_factor_mat_solver_type", "mumps")
            setting = ("solver.linear_solver", self.solver.linear_solver) if lu == "mumps" \
                else ("solver.petsc -pc_factor_mat_solver_type", lu)
            multipliers = getattr(ENFORCEMENTS[e.type], "unknowns", 0)
            dual = c.basis == "dual" or (c.basis is None and "dual" in METHODS[c.method].bases)
            condensed = self.solver.linear_solver in CONDENSED_SOLVERS
            if multipliers and condensed and not dual:
                raise SceneError(
                    f"solver.linear_solver = {self.solver.linear_solver!r} condenses the "
                    f"multipliers, which needs the dual basis; {key} (basis "
                    f"{c.basis or 'standard'!r}, method {c.method!r}) has a saddle-point "
                    "system: use 'mumps' (or 'auto'), or the mortar method's dual basis")
            if multipliers and not condensed and setting[1] not in ("mumps", "auto"):
                raise SceneError(
                    f"{setting[0]} = {setting[1]!r}: cannot solve the "
                    f"saddle-point system of {key}'s multipliers (enforcement "
                    f"{e.type!r}: zero pivots that need MUMPS's pivoting); use 'mumps', or "
                    "a condensed solver with the dual basis, or enforcement 'alm' or "
                    "'penalty'")
            if e.epsilon is not None and not e.epsilon > 0:
                raise SceneError(f"{key}.enforcement.epsilon = {e.epsilon}: must be positive")
            if not e.tolerance > 0:
                raise SceneError(f"{key}.enforcement.tolerance must be positive")
            _check_range(e.tolerance, f"{key}.enforcement.tolerance", 1e-14, 1e-2,
                         "a KKT residual relative to the pressure scale: below 1e-14 it is "
                         "round-off, above 1e-2 the pressures are not converged")
            # with multipliers there is nothing to augment; else 0 would fail every step
            # that needs a multiplier update or a penalty raise
            _check_range(e.max_augmentations, f"{key}.enforcement.max_augmentations",
                         0 if multipliers else 1, LIMITS["max_augmentations"])
            if c.friction.mu < 0:
                raise SceneError(f"{key}.friction.mu = {c.friction.mu}: must be >= 0")
            if c.friction.law == "none" and c.friction.mu != 0:
                raise SceneError(f"{key}.friction: mu given but law = 'none' "
                                 "(use law = 'coulomb')")
            if c.search_radius is not None and not c.search_radius > 0:
                raise SceneError(f"{key}.search_radius = {c.search_radius}: must be positive")
            if c.n_gauss is not None and c.n_gauss < 2:
                raise SceneError(f"{key}.n_gauss = {c.n_gauss}: at least 2")
            if c.n_gauss is not None:
                _check_range(c.n_gauss, f"{key}.n_gauss", 2, LIMITS["n_gauss"])

    def _check_steps(self) -> None:
        st = self.steps
        if st.count is not None and st.times is not None:
            raise SceneError("steps: give 'count' or 'times', not both")
        if st.count is not None and st.count < 1:
            raise SceneError(f"steps.count = {st.count}: at least one load step")
        if st.count is not None:
            _check_range(st.count, "steps.count", 1, LIMITS["steps"])
        if st.times is not None:
            if (not st.times or st.times[0] <= 0
                    or any(b <= a for a, b in zip(st.times, st.times[1:]))):
                raise SceneError("steps.times must be a non-empty, strictly increasing list of "
                                 "positive pseudo-times")
            if len(st.times) > LIMITS["steps"]:
                raise SceneError(f"steps.times: {len(st.times)} times, more than "
                                 f"{LIMITS['steps']} load steps")
        if not st.end > 0:
            raise SceneError(f"steps.end = {st.end}: must be positive")
        if st.max_cuts < 0:
            raise SceneError("steps.max_cuts must be >= 0")
        _check_range(st.max_cuts, "steps.max_cuts", 0, LIMITS["max_cuts"],
                     "each cut halves the increment: 2^-50 is round-off")
        if st.min_increment is not None:
            if not st.min_increment > 0:
                raise SceneError("steps.min_increment must be positive")
            final = st.targets()[-1]
            _check_range(st.min_increment, "steps.min_increment", 1e-12 * final, math.inf,
                         "below 1e-12 of the final time t + dt rounds to t")

    def _check_solver(self) -> None:
        sv = self.solver
        for k in ("atol", "rtol"):
            if not getattr(sv, k) > 0:
                raise SceneError(f"solver.{k} must be positive")
        if not sv.rtol <= 1:
            raise SceneError(f"solver.rtol = {sv.rtol}: must be <= 1 (a relative decrease; 1: "
                             "none required, atol alone decides)")
        if sv.quadrature_degree < 1:
            raise SceneError("solver.quadrature_degree must be >= 1")
        _check_range(sv.quadrature_degree, "solver.quadrature_degree", 1,
                     LIMITS["quadrature_degree"], "the JIT compile time grows fast with it")
        if sv.max_iterations < 1:
            raise SceneError("solver.max_iterations must be >= 1")
        _check_range(sv.max_iterations, "solver.max_iterations", 1, LIMITS["max_iterations"])
        for k, v in sv.petsc.items():
            _check_petsc_option(k, v)

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


def _unique(names: list[str], key: str) -> None:
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise SceneError(f"{key}: duplicate name(s) {sorted(dup)}")


def _check_finite(obj, key: str) -> None:
    """Every float anywhere in the scene (lists and tables included) is finite: TOML and
    Python have nan and inf, and they would otherwise reach the solver as loads or sizes."""
    if isinstance(obj, float) and not math.isfinite(obj):
        raise SceneError(f"{key} = {obj}: must be a finite number")
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            if f.name != "base_dir":
                _check_finite(getattr(obj, f.name), f"{key}.{f.name}" if key else f.name)
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            _check_finite(v, f"{key}[{i}]")
    elif isinstance(obj, dict):
        for k, v in obj.items():
            _check_finite(v, f"{key}.{k}")


def _check_range(value, key: str, low, high, why: str = "") -> None:
    if not low <= value <= high:
        bound = f">= {low:g}" if high == math.inf else f"in [{low:g}, {high:g}]"
        raise SceneError(f"{key} = {value}: must be {bound}" + (f" ({why})" if why else ""))


def _check_name(name: str, key: str) -> None:
    """Names that become file names (interface/<pair>_<step>.csv) or labels: a safe
    pattern, so no name can leave the output directory or break a file system."""
    if not isinstance(name, str) or not NAME.fullmatch(name):
        raise SceneError(f"{key} = {name!r}: a name is 1 to 64 letters, digits, '_', '-', "
                         "'.' or '+', starting with a letter or digit")


def _check_group(name: str, key: str) -> None:
    if not name or "\x00" in name:
        raise SceneError(f"{key} = {name!r}: not a physical group name")


def _check_groups(groups: str | list[str], key: str) -> None:
    """One group or a non-empty list of distinct groups: an empty list would drop the
    load or support, a repeated group would apply it twice."""
    names = as_list(groups)
    if not names:
        raise SceneError(f"{key} = []: name at least one physical group")
    for n in names:
        _check_group(n, key)
    if len(set(names)) < len(names):
        raise SceneError(f"{key} = {names}: a group named twice (its load or support would "
                         "count twice)")


def _place(place) -> str:
    return repr(place) if isinstance(place, str) else f"the node of {place[0]!r} at " \
        f"({place[1]:g}, {place[2]:g})"


def _check_mesh_file(path: Path) -> None:
    """A mesh file must be gmsh MSH data (:mod:`.mshfile`): a script would be run by gmsh,
    a FIFO block it, a device be read forever."""
    from . import mshfile
    try:
        mshfile.check(path)
    except mshfile.MeshFileError as e:
        raise SceneError(str(e)) from None


def _check_generator(ms: MeshSource) -> None:
    """The generator's own parameter checks and its cell estimate (a generator module may
    define ``cells(cell=..., **params)``), before any meshing: gmsh aborts the process on
    some geometries and allocates without bound on others."""
    module = importlib.import_module(f"fenicsx_mortar.meshes.{ms.generator}")
    estimate = getattr(module, "cells", None)
    if estimate is None:
        return
    try:
        n = estimate(cell=ms.cell or "quadrilateral", **ms.params)
    except (TypeError, ValueError) as e:
        raise SceneError(f"mesh.params for generator {ms.generator!r}: {e}") from None
    if n > LIMITS["cells"]:
        raise SceneError(f"mesh.params for generator {ms.generator!r}: about {n:.3g} cells, "
                         f"more than the limit of {LIMITS['cells']:,} (memory and time)")


_PETSC_PREFIXES = ("-snes_", "-ksp_", "-pc_", "-mat_")
#: options that would replace the convergence rule (docs/scenes.md §2.7) or open a window
_PETSC_REFUSED = {"-snes_type": "the solver is Newton (newtonls); its convergence rule "
                                "depends on it",
                  "-snes_convergence_test": "it would replace the convergence rule"}


def _check_petsc_option(k: str, v) -> None:
    """Before PETSc sees them (guards.check_petsc_options then asks PETSc itself): the
    option's form, and no value that names a file (a viewer writes where it says)."""
    if not k.startswith(_PETSC_PREFIXES):
        raise SceneError(f"solver.petsc: option {k!r} is not a -snes_/-ksp_/-pc_/-mat_ option")
    if not re.fullmatch(r"-[a-z][a-z0-9_]*", k):
        raise SceneError(f"solver.petsc: option {k!r} is not an option name "
                         "(lower-case letters, digits and '_')")
    if k in _PETSC_REFUSED and not (k == "-snes_type" and v == "newtonls"):
        raise SceneError(f"solver.petsc: {k} = {v!r}: not allowed ({_PETSC_REFUSED[k]})")
    if "draw" in k or "_lg_" in k or (isinstance(v, str) and v.split(":")[0] in _WINDOWS):
        raise SceneError(f"solver.petsc: {k} = {v!r}: would open a window")
    if isinstance(v, str) and not re.fullmatch(r"[A-Za-z0-9_.+-]*", v):
        raise SceneError(f"solver.petsc: {k} = {v!r}: a value is a word or a number (no "
                         "viewer files: outputs go to --out only)")
    if isinstance(v, str) and v.lower() in _FILE_VIEWERS:
        raise SceneError(f"solver.petsc: {k} = {v!r}: a {v} viewer writes a file into the "
                         "working directory (outputs go to --out only); 'ascii' prints")
    if k in _MUMPS_STREAMS and not (isinstance(v, (int, float)) and (v <= 0 or v == 6)):
        raise SceneError(f"solver.petsc: {k} = {v!r}: a MUMPS output stream other than 6 "
                         "(the log) or <= 0 (none) writes a fort.N file into the working "
                         "directory")
    if k in _OWN_KEYS:
        raise SceneError(f"solver.petsc: {k}: set {_OWN_KEYS[k]} instead (the package's "
                         "Newton loop and convergence rule use the scene's value)")


_WINDOWS = ("draw", "x", "socket", "saws", "glvis")
#: PETSc viewer types that write a file of a default name (binaryoutput, output.h5, ...)
_FILE_VIEWERS = ("binary", "hdf5", "vtk", "vtu", "matlab", "adios", "adios2", "exodusii",
                 "cgns", "mathematica", "vu", "pythonviewer", "pvtk")
#: SNES settings the package's Newton loop and convergence rule replace: the scene's keys
_OWN_KEYS = {"-snes_max_it": "solver.max_iterations", "-snes_atol": "solver.atol",
             "-snes_rtol": "solver.rtol"}
#: MUMPS ICNTL(1-3): streams for errors, warnings, statistics (Fortran units)
_MUMPS_STREAMS = ("-mat_mumps_icntl_1", "-mat_mumps_icntl_2", "-mat_mumps_icntl_3")


# --------------------------------------------------------------------------- TOML → dataclasses


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file. Raises SceneError with the file and key named."""
    path = Path(path)
    try:
        data = tomllib.loads(read_text(path, "scene file"))
    except tomllib.TOMLDecodeError as e:
        raise SceneError(f"{path}: TOML syntax error: {e}") from None
    try:
        _check_unused(data)
        scene = from_dict(Scene, data, "")
        scene.base_dir = str(path.resolve().parent)
        return scene.validate()
    except SceneError as e:
        raise SceneError(f"{path}: {e}") from None


def _check_unused(data: dict) -> None:
    """Keys a file gives that the run would not use (the dataclasses cannot tell a given
    value from a default)."""
    steps = data.get("steps")
    if isinstance(steps, dict) and "times" in steps and "end" in steps:
        raise SceneError("steps.end: unused with 'times' (the run ends at the last time); "
                         "leave it out")


def read_text(path: Path, what: str) -> str:
    """A regular file of at most LIMITS["scene_bytes"], as UTF-8 text. Checked before
    opening: a FIFO would block the read, a device (/dev/zero) never end it."""
    try:
        st = path.stat()
    except OSError as e:
        raise SceneError(f"{path}: cannot read {what} ({e.strerror})") from None
    if stat.S_ISDIR(st.st_mode):
        raise SceneError(f"{path}: is a directory, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        raise SceneError(f"{path}: is not a regular file (a device, FIFO or socket), not a "
                         f"{what}")
    if st.st_size > LIMITS["scene_bytes"]:
        raise SceneError(f"{path}: {st.st_size:,} bytes; a {what} has at most "
                         f"{LIMITS['scene_bytes']:,}")
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise SceneError(f"{path}: cannot read {what} ({e.strerror})") from None
    try:
        return raw.decode("utf-8-sig")  # an editor's byte-order mark is not part of the text
    except UnicodeDecodeError as e:
        raise SceneError(f"{path}: not UTF-8 text (byte 0x{raw[e.start]:02x} at offset "
                         f"{e.start})") from None


def load_scene_json(path: str | Path) -> Scene:
    """A scene saved by a run (``DIR/scene.json``), for restarts."""
    import json
    path = Path(path)
    try:
        data = json.loads(read_text(path, "saved scene"))
    except ValueError as e:
        raise SceneError(f"{path}: cannot read the saved scene ({e})") from None
    if not isinstance(data, dict):
        raise SceneError(f"{path}: the saved scene is not a JSON object")
    base_dir = data.pop("base_dir", ".")
    try:
        scene = from_dict(Scene, data, "")
        scene.base_dir = base_dir if isinstance(base_dir, str) else "."
        return scene.validate()
    except SceneError as e:
        raise SceneError(f"{path}: {e}") from None


def from_dict(cls, data: dict, path: str):
    """Build dataclass ``cls`` from a TOML table: unknown keys and wrong types are errors."""
    if not isinstance(data, dict):
        raise SceneError(f"{path or 'scene'}: expected a table, got {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.name != "base_dir"}
    unknown = set(data) - set(fields)
    if unknown:
        where = f"{path}." if path else ""
        raise SceneError(f"unknown key(s) {', '.join(where + k for k in sorted(unknown))} "
                         f"(allowed: {', '.join(fields)})")
    kwargs = {}
    for name, f in fields.items():
        key = f"{path}.{name}" if path else name
        if name in data:
            kwargs[name] = _convert(hints[name], data[name], key)
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise SceneError(f"missing required key {key}")
    return cls(**kwargs)


def _type_name(tp) -> str:
    return getattr(tp, "__name__", str(tp)).replace("typing.", "")


def _convert(tp, value, key: str):
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (Union, types.UnionType):
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return _convert(a, value, key)
            except SceneError as e:
                errors.append(e)
        if len(errors) == 1:
            raise errors[0]
        wanted = " or ".join(_type_name(a) for a in args if a is not type(None))
        raise SceneError(f"{key} = {value!r}: expected {wanted}")
    if origin is Literal:
        if value not in args:
            raise SceneError(f"{key} = {value!r}: must be one of {', '.join(map(repr, args))}")
        return value
    if origin is list:
        if not isinstance(value, list):
            raise SceneError(f"{key}: expected a list, got {value!r}")
        return [_convert(args[0], v, f"{key}[{i}]") for i, v in enumerate(value)]
    if origin is dict:
        if not isinstance(value, dict):
            raise SceneError(f"{key}: expected a table, got {value!r}")
        return {k: _convert(args[1], v, f"{key}.{k}") for k, v in value.items()}
    if dataclasses.is_dataclass(tp):
        return from_dict(tp, value, key)
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SceneError(f"{key} = {value!r}: expected a number")
        try:
            return float(value)
        except OverflowError:   # a TOML integer of hundreds of digits
            raise SceneError(f"{key} = an integer of {len(str(abs(value)))} digits: beyond "
                             "the largest float (1.8e308)") from None
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise SceneError(f"{key} = {value!r}: expected an integer")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise SceneError(f"{key} = {value!r}: expected a string")
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise SceneError(f"{key} = {value!r}: expected true or false")
        return value
    raise TypeError(f"unsupported field type {tp} at {key}")
