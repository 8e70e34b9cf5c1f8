"""Scenes: what is simulated, as validated dataclasses, read from TOML or built in Python.

A scene declares its effects (materials, loads, contact pairs, friction, smoothing) and the
run builds only those. Field-by-field documentation: ``docs/scenes.md``.
"""
from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, Union



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
    cell: Literal["quadrilateral", "triangle"] = "quadrilateral"
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
            return "+".join(_as_list(self.boundary))
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
class SolverSettings:
    """Newton (PETSc SNES) settings. A step converges when the residual norm is below
    ``atol`` and below ``rtol`` times the first residual of the step (and, with contact,
    the KKT residual is below the pair's tolerance)."""
    atol: float = 1e-9
    rtol: float = 1e-8
    max_iterations: int = 25
    line_search: Literal["basic", "bt", "l2", "cp"] = "l2"
    linear_solver: Literal["mumps", "superlu_dist", "gmres-hypre"] = "mumps"
    quadrature_degree: int = 2  # bulk forms: full Gauss integration of P1/Q1 (2x2 on quads)
    petsc: dict[str, bool | int | float | str] = field(default_factory=dict)


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
            out.append(f"pressure ({kind}): {'+'.join(_as_list(p.boundary))}")
        for t in self.tractions:
            out.append(f"traction (dead): {'+'.join(_as_list(t.boundary))}")
        for c in self.contacts:
            fr = "frictionless" if c.friction.law == "none" else f"coulomb mu={c.friction.mu:g}"
            out.append(f"contact {c.name}: {c.method}, {c.enforcement.type}, {fr}, "
                       f"smoothing {c.smoothing}")
        return out

    # ------------------------------------------------------------------ validation
    def validate(self) -> "Scene":
        """Semantic checks that do not need the mesh; raise SceneError naming the key."""
        ms = self.mesh
        if (ms.generator is None) == (ms.file is None):
            raise SceneError("mesh: give exactly one of 'generator' or 'file'")
        if ms.generator is not None and ms.generator not in generators():
            known = generators()
            raise SceneError(f"mesh.generator = {ms.generator!r}: no such generator "
                             f"(known: {', '.join(known)})")
        if ms.file is not None and not self.mesh_file().is_file():
            raise SceneError(f"mesh.file: {self.mesh_file()} does not exist")
        if not self.bodies:
            raise SceneError("bodies: a scene needs at least one body")
        names = [b.name for b in self.bodies]
        _unique(names, "bodies[].name")
        for i, b in enumerate(self.bodies):
            m, key = b.material, f"bodies[{i}].material"
            if not (m.E > 0 and math.isfinite(m.E)):
                raise SceneError(f"{key}.E = {m.E}: Young's modulus must be positive")
            if not (-1.0 < m.nu < 0.5):
                raise SceneError(f"{key}.nu = {m.nu}: Poisson's ratio must lie in (-1, 0.5)")
        for name, c in self.curves.items():
            key = f"curves.{name}"
            if len(c.t) != len(c.value) or len(c.t) < 2:
                raise SceneError(f"{key}: 't' and 'value' need the same length (>= 2)")
            if any(b <= a for a, b in zip(c.t, c.t[1:])):
                raise SceneError(f"{key}.t must increase strictly")
        for kind, items in (("dirichlet", self.dirichlet), ("pressures", self.pressures),
                            ("tractions", self.tractions)):
            for i, item in enumerate(items):
                if item.curve != "ramp" and item.curve not in self.curves:
                    raise SceneError(f"{kind}[{i}].curve = {item.curve!r}: no such curve "
                                     f"(define [curves.{item.curve}])")
        for i, d in enumerate(self.dirichlet):
            key = f"dirichlet[{i}]"
            if (d.boundary is None) == (d.point is None):
                raise SceneError(f"{key}: give exactly one of 'boundary' or 'point'")
            if d.point is not None:
                if len(d.point) != 2:
                    raise SceneError(f"{key}.point must be [x, y]")
                if d.body not in names:
                    raise SceneError(f"{key}.body = {d.body!r}: a point condition names one "
                                     f"of the bodies ({', '.join(names)})")
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
            elif d.x is None and d.y is None:
                raise SceneError(f"{key}: prescribe at least one component ('x' or 'y')")
        for i, t in enumerate(self.tractions):
            if len(t.value) != 2:
                raise SceneError(f"tractions[{i}].value must be [tx, ty]")
        _unique([c.name for c in self.contacts], "contacts[].name")
        from .contact.registry import ENFORCEMENTS, FRICTION_LAWS, METHODS, SMOOTHINGS
        for i, c in enumerate(self.contacts):
            key = f"contacts[{i}]"
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
            if set(_as_list(c.slave)) & set(_as_list(c.master)):
                raise SceneError(f"{key}: slave and master surfaces must differ "
                                 f"(both name "
                                 f"{sorted(set(_as_list(c.slave)) & set(_as_list(c.master)))})")
            e = c.enforcement
            if e.epsilon is not None and not e.epsilon > 0:
                raise SceneError(f"{key}.enforcement.epsilon = {e.epsilon}: must be positive")
            if not e.tolerance > 0:
                raise SceneError(f"{key}.enforcement.tolerance must be positive")
            if c.friction.mu < 0:
                raise SceneError(f"{key}.friction.mu = {c.friction.mu}: must be >= 0")
            if c.friction.law == "none" and c.friction.mu != 0:
                raise SceneError(f"{key}.friction: mu given but law = 'none' "
                                 "(use law = 'coulomb')")
            if c.n_gauss is not None and c.n_gauss < 2:
                raise SceneError(f"{key}.n_gauss = {c.n_gauss}: at least 2")
        st = self.steps
        if st.count is not None and st.times is not None:
            raise SceneError("steps: give 'count' or 'times', not both")
        if st.count is not None and st.count < 1:
            raise SceneError(f"steps.count = {st.count}: at least one load step")
        if st.times is not None:
            if (not st.times or st.times[0] <= 0
                    or any(b <= a for a, b in zip(st.times, st.times[1:]))):
                raise SceneError("steps.times must be a non-empty, strictly increasing list of "
                                 "positive pseudo-times")
        if not st.end > 0:
            raise SceneError(f"steps.end = {st.end}: must be positive")
        if st.max_cuts < 0:
            raise SceneError("steps.max_cuts must be >= 0")
        if st.min_increment is not None and not st.min_increment > 0:
            raise SceneError("steps.min_increment must be positive")
        sv = self.solver
        for k in ("atol", "rtol"):
            if not getattr(sv, k) > 0:
                raise SceneError(f"solver.{k} must be positive")
        if sv.quadrature_degree < 1:
            raise SceneError("solver.quadrature_degree must be >= 1")
        if sv.max_iterations < 1:
            raise SceneError("solver.max_iterations must be >= 1")
        for k in sv.petsc:
            if not k.startswith(("-snes_", "-ksp_", "-pc_", "-mat_")):
                raise SceneError(f"solver.petsc: option {k!r} is not a "
                                 "-snes_/-ksp_/-pc_/-mat_ option")
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
                facets.update(_as_list(item.boundary))
        for c in self.contacts:
            facets.update(_as_list(c.slave))
            facets.update(_as_list(c.master))
        return cells, facets


def _as_list(v: str | list[str]) -> list[str]:
    return [v] if isinstance(v, str) else list(v)


def _unique(names: list[str], key: str) -> None:
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise SceneError(f"{key}: duplicate name(s) {sorted(dup)}")


# --------------------------------------------------------------------------- TOML → dataclasses


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file. Raises SceneError with the file and key named."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise SceneError(f"{path}: cannot read scene file ({e.strerror})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SceneError(f"{path}: TOML syntax error: {e}") from None
    try:
        scene = from_dict(Scene, data, "")
        scene.base_dir = str(path.resolve().parent)
        return scene.validate()
    except SceneError as e:
        raise SceneError(f"{path}: {e}") from None


def load_scene_json(path: str | Path) -> Scene:
    """A scene saved by a run (``DIR/scene.json``), for restarts."""
    import json
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise SceneError(f"{path}: cannot read the saved scene ({e})") from None
    base_dir = data.pop("base_dir", ".")
    scene = from_dict(Scene, data, "")
    scene.base_dir = base_dir
    return scene.validate()


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
        return float(value)
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
