"""The library's public surface (issue 27): every public callable of the API documented
with its arguments (Google style) and every parameter typed, so that ``help()`` and an
editor tell a DOLFINx user what to pass; and the core never imports the scene layer."""
from __future__ import annotations

import ast
import dataclasses
import inspect
from pathlib import Path

import pytest

import fenicsx_mortar as fm

LIBRARY = ("ContactPair", "ContactProblem", "LoadStepper", "SolverSettings", "StepResult",
           "SteppingResult", "StepDone", "StepStarted", "Retried", "Cut", "Timings", "solve")
#: the core: problem, Newton, stepping, acceptance, contact kernels (never the scenes)
CORE = ("problem", "newton", "stepping", "acceptance", "settings", "petsc_options", "system",
        "linesearch", "timings", "contact", "condensation")
SCENE_LAYER = {"scene", "io", "cli", "meshes"}


def public_callables():
    for name in LIBRARY:
        obj = getattr(fm, name)
        yield name, obj
        if inspect.isclass(obj):
            for attr, member in vars(obj).items():
                if attr.startswith("_"):
                    continue
                if isinstance(member, property):
                    yield f"{name}.{attr}", member.fget
                elif inspect.isfunction(member):
                    yield f"{name}.{attr}", member


@pytest.mark.parametrize("name, obj", list(public_callables()), ids=lambda x: str(x))
def test_public_callables_are_documented_and_typed(name, obj):
    doc = inspect.getdoc(obj) or ""
    assert doc, f"{name}: no docstring"
    if inspect.isclass(obj):
        if dataclasses.is_dataclass(obj):
            if dataclasses.fields(obj) and len(dataclasses.fields(obj)) > 1:
                assert "Attributes:" in doc or "Args:" in doc, name
            return
        init = obj.__init__
        params = [p for p in inspect.signature(init).parameters.values()
                  if p.name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
        if params:
            assert "Args:" in doc, f"{name}: no Args section for {[p.name for p in params]}"
    else:
        params = [p for p in inspect.signature(obj).parameters.values()
                  if p.name not in ("self", "cls")
                  and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
        if params:
            assert "Args:" in doc, f"{name}: no Args section for {[p.name for p in params]}"
    untyped = [p.name for p in params if p.annotation is inspect.Parameter.empty]
    assert not untyped, f"{name}: untyped parameters {untyped}"


def test_the_core_never_imports_the_scene_layer():
    root = Path(fm.__file__).parent
    bad = []
    for mod in CORE:
        paths = sorted((root / mod).rglob("*.py")) if (root / mod).is_dir() \
            else [root / f"{mod}.py"]
        for path in paths:
            tree = ast.parse(path.read_text())
            for node in ast.walk(tree):
                if isinstance(node, ast.ImportFrom) and node.level > 0:
                    parts = (node.module or "").split(".")
                    names = [parts[0]] if parts[0] else [a.name for a in node.names]
                    depth = len(path.relative_to(root).parts) - 1
                    if node.level > depth + 1:
                        continue
                    top = names if node.level == depth + 1 else []
                    if any(n in SCENE_LAYER for n in top):
                        bad.append(f"{path.relative_to(root)}: from {'.' * node.level}"
                                   f"{node.module or ''} import ...")
    assert not bad, bad


def test_the_package_is_typed():
    assert (Path(fm.__file__).parent / "py.typed").is_file()
