"""Property (issue 18): any TOML document built from the scene schema's keys with arbitrary
values gives ``fenicsx-mortar check`` exit 0, 1 or 2 — never a traceback — within a time
bound; an exit 2 is one line naming the problem.

The documents come from the dataclasses of fenicsx_mortar/scene.py (the schema): any
subset of each table's keys, each value either of the key's type (nested tables and lists
recursively, names from the schema's vocabulary, numbers from tame to nan, inf and 2^63)
or any TOML value at all. Most are refused while the scene is read; those that pass are
meshed (generators' small parameters), so every layer up to the mesh checks runs.
"""
from __future__ import annotations

import contextlib
import dataclasses
import io
import tempfile
import types
import typing
from pathlib import Path
from typing import Literal, Union

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fenicsx_mortar.cli import main
from fenicsx_mortar.scene import Scene, generators
from hostile._toml import dumps
from hostile.cases import BASE, BLOCK, edit

NAMES = ["block", "slab", "lower", "upper", "bottom", "top", "left", "right", "block_top",
         "block_bottom", "slab_top", "slab_bottom", "ramp", "c", "penalty", "alm", "mortar",
         "nts", "coulomb", "none", "hermite", "mumps", "neo-hooke", "svk", "linear", "",
         "../x", "a" * 70, *generators()]
TEXT = st.text(st.characters(blacklist_categories=("Cs",)), max_size=12)
FLOATS = st.one_of(st.floats(-10, 10), st.sampled_from([0.0, 1e-300, 1e300, -1e300]),
                   st.floats(allow_nan=True, allow_infinity=True))
INTS = st.one_of(st.integers(-3, 24), st.integers(-2 ** 63, 2 ** 63 - 1))
ANY = st.recursive(st.one_of(st.booleans(), INTS, FLOATS, TEXT),
                   lambda inner: st.one_of(st.lists(inner, max_size=3),
                                           st.dictionaries(TEXT, inner, max_size=3)),
                   max_leaves=8)


def typed(tp) -> st.SearchStrategy:
    """A value of type ``tp`` (the schema's annotation), or now and then anything."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (Union, types.UnionType):
        return st.one_of(*(typed(a) for a in args if a is not type(None)))
    if origin is Literal:
        return st.sampled_from(args)
    if origin is list:
        return st.lists(typed(args[0]), max_size=3)
    if origin is dict:
        return st.dictionaries(st.sampled_from(NAMES) | TEXT, typed(args[1]), max_size=3)
    if dataclasses.is_dataclass(tp):
        return table(tp)
    return {float: FLOATS, int: INTS, bool: st.booleans(),
            str: st.sampled_from(NAMES) | TEXT}[tp]


def table(cls) -> st.SearchStrategy:
    """A dict of ``cls``'s fields: mostly its required ones and some others, sometimes any
    subset of them."""
    hints = typing.get_type_hints(cls)
    fields = [f for f in dataclasses.fields(cls) if f.name != "base_dir"]
    values = {f.name: st.one_of(typed(hints[f.name]), ANY) for f in fields}
    if cls is Scene:
        values["mesh"] = st.one_of(MESH, values["mesh"])
    required = {f.name for f in fields if f.default is dataclasses.MISSING
                and f.default_factory is dataclasses.MISSING}
    full = st.fixed_dictionaries({k: v for k, v in values.items() if k in required},
                                 optional={k: v for k, v in values.items() if k not in required})
    return st.one_of(full, st.fixed_dictionaries({}, optional=values))


#: generated meshes of a few cells, so that documents that pass validation mesh quickly
MESH = st.fixed_dictionaries({"generator": st.sampled_from(generators())},
                             optional={"params": st.fixed_dictionaries(
                                 {}, optional={"nx": st.integers(-1, 6),
                                               "ny": st.integers(-1, 6),
                                               "width": FLOATS})})


def leaf_paths(doc, prefix: str = "") -> list[str]:
    if isinstance(doc, dict):
        return [p for k, v in doc.items()
                for p in [f"{prefix}.{k}" if prefix else k, *leaf_paths(v, f"{prefix}.{k}"
                                                                       if prefix else k)]]
    if isinstance(doc, list):
        return [p for i, v in enumerate(doc) for p in [f"{prefix}[{i}]",
                                                       *leaf_paths(v, f"{prefix}[{i}]")]]
    return []


#: keys the valid documents leave at their defaults
EXTRA = ["steps.max_cuts", "steps.min_increment", "steps.times", "steps.end", "solver.atol",
         "solver.rtol", "solver.max_iterations", "solver.quadrature_degree", "solver.petsc",
         "solver.line_search", "solver.linear_solver", "contacts[0].n_gauss",
         "contacts[0].search_radius", "contacts[0].method", "contacts[0].smoothing",
         "contacts[0].enforcement", "contacts[0].friction", "output.xdmf", "tractions",
         "curves", "dirichlet[0].motion", "dirichlet[0].name", "dirichlet[0].point",
         "mesh.cell", "mesh.file", "bodies[0].region", "pressures[0].curve"]
PATHS = sorted(set(leaf_paths(BASE) + leaf_paths(BLOCK) + EXTRA))


def mutate(doc: dict, changes: list) -> dict:
    """``doc`` with some keys set to other values (those that do not fit its shape, e.g.
    a contacts[0] key of a scene without contacts, skipped)."""
    for change in changes:
        try:
            doc = edit(doc, change)
        except (KeyError, IndexError, TypeError, AttributeError):
            pass
    return doc


#: valid scenes (a block; a block on a slab with contact) with one to three keys changed
MUTATED = st.builds(mutate, st.sampled_from([BASE, BLOCK]), st.lists(st.tuples(
    st.sampled_from(PATHS), st.one_of(ANY, st.sampled_from(NAMES))), min_size=1, max_size=3))


@settings(max_examples=300, deadline=20_000, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(st.one_of(MUTATED, table(Scene)))
def test_any_scene_document_exits_0_1_or_2(doc):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "scene.toml"
        path.write_text(dumps(doc), encoding="utf-8")
        err, out = io.StringIO(), io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            code = main(["check", str(path)])
    err = err.getvalue()
    assert code in (0, 1, 2)
    assert "Traceback" not in err
    if code == 2:
        assert err.startswith("fenicsx-mortar: error: ") and err.count("\n") == 1, err


def test_the_documents_reach_the_mesh():
    """The strategy is not all noise: valid documents exist in it (a minimal one here)."""
    doc = {"mesh": {"generator": "block"},
           "bodies": [{"name": "block", "material": {"model": "svk", "E": 1.0, "nu": 0.0}}],
           "dirichlet": [{"boundary": "bottom", "x": 0.0, "y": 0.0}]}
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "scene.toml"
        path.write_text(dumps(doc))
        assert main(["check", str(path)]) == 0
