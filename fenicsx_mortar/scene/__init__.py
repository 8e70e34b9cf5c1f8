"""The scene layer: a scene file (TOML, :mod:`.reading`) → dataclasses (:mod:`.model`),
checked (:mod:`.validation`) → mesh,
bulk forms, supports and contact pairs (:mod:`.meshing`, :mod:`.bulk`, :mod:`.supports`)
→ the runner (:mod:`.runner`: the core's ContactProblem and LoadStepper, with the outputs
of :mod:`fenicsx_mortar.io` as observers). The core never imports this package.
"""
from .model import (LIMITS, Body, Contact, Dirichlet, Enforcement, Friction, LoadCurve,
                    Material, MeshSource, OutputSettings, Pressure, RigidMotion, Scene,
                    SceneError, SolverSettings, Steps, Traction, as_list, generators)
from .reading import from_dict, json_loads, load_scene, load_scene_json, read_text

__all__ = ["LIMITS", "Body", "Contact", "Dirichlet", "Enforcement", "Friction", "LoadCurve",
           "Material", "MeshSource", "OutputSettings", "Pressure", "RigidMotion", "Scene",
           "SceneError", "SolverSettings", "Steps", "Traction", "as_list", "from_dict",
           "generators", "json_loads", "load_scene", "load_scene_json", "read_text"]
