"""fenicsx_mortar: 2D finite-deformation mortar contact for FEniCSx (DOLFINx).

Two ways in:

* the library API, for a DOLFINx script with its own forms: :class:`ContactPair` (a slave
  and a master boundary from facet meshtags) and :class:`ContactProblem` (the user's
  residual, Dirichlet conditions and pairs, solved by PETSc SNES);
* scenes: build a :class:`Scene` (or :func:`load_scene` a TOML file) and call
  :func:`solve`. DOLFINx is imported only when solving, so scenes can be built and checked
  without it.
"""
from .scene import (Body, Contact, Dirichlet, Enforcement, Friction, LoadCurve, Material,
                    MeshSource, OutputSettings, Pressure, RigidMotion, Scene, SceneError,
                    SolverSettings, Steps, Traction, load_scene)

__all__ = ["Body", "Contact", "ContactPair", "ContactProblem", "Dirichlet", "Enforcement",
           "Friction", "LoadCurve", "Material", "MeshSource", "OutputSettings", "Pressure",
           "RigidMotion", "Scene", "SceneError", "SolverSettings", "Steps", "Traction",
           "load_scene", "solve"]


def solve(scene, out=None, **kwargs):
    """Run ``scene``; see :func:`fenicsx_mortar.run.solve`."""
    from .run import solve as _solve
    return _solve(scene, out, **kwargs)


def __getattr__(name):
    # the library API imports DOLFINx: only when asked for
    if name == "ContactPair":
        from .contact.pair import ContactPair
        return ContactPair
    if name == "ContactProblem":
        from .problem import ContactProblem
        return ContactProblem
    raise AttributeError(f"module 'fenicsx_mortar' has no attribute {name!r}")
