"""fenicsx_mortar: 2D finite-deformation mortar contact for FEniCSx (DOLFINx 0.5).

Python API: build a :class:`Scene` (or :func:`load_scene` a TOML file) and call
:func:`solve`. DOLFINx is imported only when solving, so scenes can be built and checked
without it.
"""
from .scene import (Body, ContactPair, Dirichlet, Enforcement, Friction, LoadCurve, Material, RigidMotion,
                    MeshSource, OutputSettings, Pressure, Scene, SceneError, SolverSettings,
                    Steps, Traction, load_scene)

__all__ = ["Body", "ContactPair", "Dirichlet", "Enforcement", "Friction", "LoadCurve",
           "Material", "MeshSource", "OutputSettings", "Pressure", "RigidMotion", "Scene", "SceneError",
           "SolverSettings", "Steps", "Traction", "load_scene", "solve"]


def solve(scene, out=None, **kwargs):
    """Run ``scene``; see :func:`fenicsx_mortar.run.solve`."""
    from .run import solve as _solve
    return _solve(scene, out, **kwargs)
