"""fenicsx_mortar: 2D finite-deformation mortar contact for FEniCSx (DOLFINx).

Two ways in:

* the library API, for a DOLFINx script with its own forms: :class:`ContactPair` (a slave
  and a master boundary from facet meshtags), :class:`ContactProblem` (the user's residual,
  Dirichlet conditions and pairs, solved by PETSc SNES; ``reaction()``, ``pair.fields()``)
  and :class:`LoadStepper` (load steps with step cutting); docs/library.md;
* scenes: build a :class:`Scene` (or :func:`load_scene` a TOML file) and call
  :func:`solve`. DOLFINx is imported only when solving, so scenes can be built and checked
  without it.
"""
from __future__ import annotations

from .scene import (Body, Contact, Dirichlet, Enforcement, Friction, LoadCurve, Material,
                    MeshSource, OutputSettings, Pressure, RigidMotion, Scene, SceneError,
                    Steps, Traction, load_scene)
from .settings import RANGES, SolverSettings

#: the library API (imports DOLFINx when first used): name → module
_LAZY = {"ContactPair": "contact.pair", "ContactProblem": "problem",
         "LoadStepper": "stepping", "SteppingResult": "stepping", "StepDone": "stepping",
         "StepStarted": "stepping", "Retried": "stepping", "Cut": "stepping",
         "StepResult": "newton", "Timings": "timings",
         "CoarseMesh": "condensation.multigrid", "refine_gmsh": "condensation.multigrid"}

__all__ = ["Body", "CoarseMesh", "Contact", "ContactPair", "ContactProblem", "Cut", "Dirichlet",
           "Enforcement", "Friction", "LoadCurve", "LoadStepper", "Material", "MeshSource",
           "OutputSettings", "Pressure", "RANGES", "Retried", "RigidMotion", "Scene",
           "SceneError", "SolverSettings", "StepDone", "StepResult", "StepStarted",
           "SteppingResult", "Steps", "Timings", "Traction", "load_scene", "refine_gmsh", "solve"]


def solve(scene: Scene, out: str | None = None, **kwargs):
    """Run ``scene`` (see :func:`fenicsx_mortar.scene.runner.solve` for the arguments).

    Args:
        scene: A validated :class:`Scene`.
        out: Output directory (None: no files).
        **kwargs: ``comm``, ``log``, ``restart``, ``on_step``.

    Returns:
        The run's ``Result`` (converged, message, steps, pairs, the displacement ``u``).
    """
    from .scene.runner import solve as _solve
    return _solve(scene, out, **kwargs)


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'fenicsx_mortar' has no attribute {name!r}")
    import importlib
    return getattr(importlib.import_module(f".{module}", __name__), name)


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
