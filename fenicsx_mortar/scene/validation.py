"""The checks of a scene that need no mesh, each naming the key at fault: every float
finite and at most MAGNITUDE in size (also every load or prescribed value times its curve),
every number in its range (docs/scenes.md; the numbers that drive memory or time have upper
bounds, LIMITS: the cell count of a generator's mesh is estimated before meshing), names,
groups, curves, supports, contacts, steps and the solver's PETSc options."""
from __future__ import annotations

import dataclasses
import importlib
import math
import re
import warnings
from pathlib import Path

from ..settings import CONDENSED_SOLVERS, check_number
from .model import (LIMITS, MAGNITUDE, NAME, RAMP, MeshSource, Scene, SceneError, as_list,
                    generators)


def validate(scene: Scene) -> None:
    """Semantic checks that do not need the mesh; raise SceneError naming the key.
    Every float must be finite (TOML has nan and inf) and at most MAGNITUDE in size, as
    every load or prescribed value times its curve; every number lie in its range
    (docs/scenes.md), and the numbers that drive memory or time have upper bounds
    (LIMITS; the cell count of a generator's mesh is estimated before meshing)."""
    _check_finite(scene, "")
    _check_mesh(scene)
    _check_bodies(scene)
    _check_curves(scene)
    _check_scaled(scene)
    _check_loads(scene)
    _check_dirichlet(scene)
    _check_contacts(scene)
    _check_steps(scene)
    _check_solver(scene)


def _check_mesh(scene: Scene) -> None:
    ms = scene.mesh
    if (ms.generator is None) == (ms.file is None):
        raise SceneError("mesh: give exactly one of 'generator' or 'file'")
    if ms.file is not None:
        _check_mesh_file(scene.mesh_file())
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

def _check_bodies(scene: Scene) -> None:
    if not scene.bodies:
        raise SceneError("bodies: a scene needs at least one body")
    _unique([b.name for b in scene.bodies], "bodies[].name")
    regions: dict[str, int] = {}
    for i, b in enumerate(scene.bodies):
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

def _check_curves(scene: Scene) -> None:
    for name, c in scene.curves.items():
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
    for kind, items in (("dirichlet", scene.dirichlet), ("pressures", scene.pressures),
                        ("tractions", scene.tractions)):
        for i, item in enumerate(items):
            if item.curve != "ramp" and item.curve not in scene.curves:
                raise SceneError(f"{kind}[{i}].curve = {item.curve!r}: no such curve "
                                 f"(define [curves.{item.curve}])")

def _check_scaled(scene: Scene) -> None:
    """A value times its curve (piecewise linear: its largest point) within MAGNITUDE:
    each alone may be, their product overflow later (six cuts naming no key)."""
    def check(value, curve: str, key: str) -> None:
        c = scene.curve(curve) if curve == "ramp" or curve in scene.curves else None
        if c is None or not value:
            return
        k = max(range(len(c.value)), key=lambda j: abs(c.value[j]))
        if not abs(value) * abs(c.value[k]) <= MAGNITUDE:
            where = "the ramp" if c is RAMP else f"curves.{curve}.value[{k}]"
            raise SceneError(f"{key} = {value:g} times {where} = {c.value[k]:g}: beyond "
                             f"{MAGNITUDE:g} in size (the solve's products would overflow)")
    for i, p in enumerate(scene.pressures):
        check(p.value, p.curve, f"pressures[{i}].value")
    for i, t in enumerate(scene.tractions):
        for j, v in enumerate(t.value):
            check(v, t.curve, f"tractions[{i}].value[{j}]")
    for i, d in enumerate(scene.dirichlet):
        for c in ("x", "y"):
            if getattr(d, c) is not None:
                check(getattr(d, c), d.curve, f"dirichlet[{i}].{c}")
        if d.motion is not None:
            m = d.motion
            for j, v in enumerate(m.translation):
                check(v, m.translation_curve, f"dirichlet[{i}].motion.translation[{j}]")
            check(m.rotation, m.rotation_curve, f"dirichlet[{i}].motion.rotation")

def _check_loads(scene: Scene) -> None:
    for kind, items in (("pressures", scene.pressures), ("tractions", scene.tractions)):
        for i, item in enumerate(items):
            _check_groups(item.boundary, f"{kind}[{i}].boundary")
    for i, t in enumerate(scene.tractions):
        if len(t.value) != 2:
            raise SceneError(f"tractions[{i}].value must be [tx, ty]")

def _check_dirichlet(scene: Scene) -> None:
    names = [b.name for b in scene.bodies]
    held: dict[tuple, str] = {}   # (where, component) -> the entry prescribing it
    for i, d in enumerate(scene.dirichlet):
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
                if c != "ramp" and c not in scene.curves:
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

def _check_contacts(scene: Scene) -> None:
    _unique([c.name for c in scene.contacts], "contacts[].name")
    from ..contact.registry import ENFORCEMENTS, FRICTION_LAWS, METHODS, SMOOTHINGS
    for i, c in enumerate(scene.contacts):
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
        for j, other in enumerate(scene.contacts[:i]):
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
        lu = scene.solver.petsc.get("-pc_factor_mat_solver_type", "mumps")
        setting = ("solver.linear_solver", scene.solver.linear_solver) if lu == "mumps" \
            else ("solver.petsc -pc_factor_mat_solver_type", lu)
        multipliers = getattr(ENFORCEMENTS[e.type], "unknowns", 0)
        dual = c.basis == "dual" or (c.basis is None and "dual" in METHODS[c.method].bases)
        condensed = scene.solver.linear_solver in CONDENSED_SOLVERS
        if multipliers and condensed and not dual:
            raise SceneError(
                f"solver.linear_solver = {scene.solver.linear_solver!r} condenses the "
                f"multipliers, which needs the dual basis; {key} (basis "
                f"{c.basis or 'standard'!r}, method {c.method!r}) has a saddle-point "
                "system: use 'mumps', or the mortar method's dual basis")
        if multipliers and not condensed and setting[1] not in ("mumps", "auto"):
            raise SceneError(
                f"{setting[0]} = {setting[1]!r}: cannot solve the "
                f"saddle-point system of {key}'s multipliers (enforcement "
                f"{e.type!r}: zero pivots that need MUMPS's pivoting); use 'mumps', or "
                "a condensed solver with the dual basis, or enforcement 'alm' or "
                "'penalty'")
        if e.epsilon is not None:
            _number("epsilon", e.epsilon, f"{key}.enforcement.epsilon")
        _number("tolerance", e.tolerance, f"{key}.enforcement.tolerance")
        _number("max_augmentations", e.max_augmentations,
                f"{key}.enforcement.max_augmentations")
        if not multipliers and e.max_augmentations < 1:
            # 0 would fail every step that needs a multiplier update or a penalty raise
            raise SceneError(f"{key}.enforcement.max_augmentations = 0: at least 1 with "
                             f"enforcement {e.type!r} (only multipliers need none)")
        _number("mu", c.friction.mu, f"{key}.friction.mu")
        if c.friction.law == "none" and c.friction.mu != 0:
            raise SceneError(f"{key}.friction: mu given but law = 'none' "
                             "(use law = 'coulomb')")
        if e.type in ("alm", "alm-stick") and c.friction.law != "none":
            # docs/friction.md, "Partial slip" (Cattaneo-Mindlin)
            what = ("keeps the stick penalty-regularized (elastic slip): partial-slip "
                    "tractions come out wrong (the stick zone up to +30 % wide); "
                    "'alm-stick' augments the traction too" if e.type == "alm" else
                    "reaches the answer of 'lagrange' at ~8-11 augmentations a step "
                    "(11-15 Newton iterations, against ~5-9)")
            warnings.warn(f"{key}: enforcement {e.type!r} with friction {what}; prefer "
                          "'lagrange'", stacklevel=2)
        if c.search_radius is not None:
            _number("search_radius", c.search_radius, f"{key}.search_radius")
        if c.n_gauss is not None:
            _number("n_gauss", c.n_gauss, f"{key}.n_gauss")

def _check_steps(scene: Scene) -> None:
    st = scene.steps
    if st.count is not None and st.times is not None:
        raise SceneError("steps: give 'count' or 'times', not both")
    if st.count is not None:
        _number("load_steps", st.count, "steps.count")
    if st.times is not None:
        if (not st.times or st.times[0] <= 0
                or any(b <= a for a, b in zip(st.times, st.times[1:]))):
            raise SceneError("steps.times must be a non-empty, strictly increasing list of "
                             "positive pseudo-times")
        _number("load_steps", len(st.times), "len(steps.times)")
    if not st.end > 0:
        raise SceneError(f"steps.end = {st.end}: must be positive")
    _number("max_cuts", st.max_cuts, "steps.max_cuts")
    if st.min_increment is not None:
        _number("min_increment", st.min_increment, "steps.min_increment")
        final = st.targets()[-1]
        if st.min_increment < 1e-12 * final:
            raise SceneError(f"steps.min_increment = {st.min_increment:g}: must be >= "
                             f"{1e-12 * final:g} (below 1e-12 of the final time t + dt "
                             "rounds to t)")

def _check_solver(scene: Scene) -> None:
    sv = scene.solver
    try:
        sv.check("solver")
    except ValueError as e:
        raise SceneError(str(e)) from None
    for k, v in sv.petsc.items():
        _check_petsc_option(k, v)
    refined = scene.mesh.generator is not None and (scene.mesh.params or {}).get("refine", 0)
    if sv.linear_solver == "gmres-gmg" and not refined:
        raise SceneError("solver.linear_solver = 'gmres-gmg': a geometric multigrid needs the "
                         "meshes this one was refined from; mesh with a generator's "
                         "params.refine >= 1 (hertz), or use 'gmres-gamg'")
    from ..contact.registry import ENFORCEMENTS
    if sv.linear_solver == "gmres-gmg" and not any(
            c.enforcement.type in ENFORCEMENTS
            and getattr(ENFORCEMENTS[c.enforcement.type], "unknowns", 0)
            for c in scene.contacts):
        raise SceneError("solver.linear_solver = 'gmres-gmg' solves the condensed system of "
                         "dual multipliers; no contact has them (enforcement 'lagrange'): "
                         "use 'gmres-gamg' or 'mumps'")


def _unique(names: list[str], key: str) -> None:
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise SceneError(f"{key}: duplicate name(s) {sorted(dup)}")


def _check_finite(obj, key: str) -> None:
    """Every float anywhere in the scene (lists and tables included) is finite and at most
    MAGNITUDE in size: TOML and Python have nan and inf, and they would otherwise reach the
    solver as loads or sizes; E = 1e308 overflowed in the first assembly (NaN, six cuts)."""
    if isinstance(obj, float) and not math.isfinite(obj):
        raise SceneError(f"{key} = {obj}: must be a finite number")
    # PETSc's own settings are PETSc's to bound (-pc_factor_zeropivot 1e300 is one)
    if isinstance(obj, float) and abs(obj) > MAGNITUDE and not key.startswith("solver.petsc"):
        raise SceneError(f"{key} = {obj:g}: beyond {MAGNITUDE:g} in size (the solve's "
                         "products, stiffness times strain, would overflow)")
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


def _number(name: str, value, key: str) -> None:
    """``value`` in ``settings.RANGES[name]``, the table the library API checks against."""
    try:
        check_number(name, value, key)
    except ValueError as e:
        raise SceneError(str(e)) from None


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
    from ..io import mshfile
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


#: the Newton solver's, its KSP's, PC's and matrices', and a multigrid's level solvers'
_PETSC_PREFIXES = ("-snes_", "-ksp_", "-pc_", "-mat_", "-mg_levels_", "-mg_coarse_")
#: options that would replace the convergence rule (docs/scenes.md §2.7) or open a window
_PETSC_REFUSED = {"-snes_type": "the solver is Newton (newtonls); its convergence rule "
                                "depends on it",
                  "-snes_convergence_test": "it would replace the convergence rule"}


def _check_petsc_option(k: str, v) -> None:
    """Before PETSc sees them (guards.check_petsc_options then asks PETSc itself): the
    option's form, and no value that names a file (a viewer writes where it says)."""
    if not k.startswith(_PETSC_PREFIXES):
        raise SceneError(f"solver.petsc: option {k!r} is not a -snes_/-ksp_/-pc_/-mat_/"
                         "-mg_levels_/-mg_coarse_ option")
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
