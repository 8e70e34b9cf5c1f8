"""gmsh mesh generators of the reference problems, installed as ``fenicsx_mortar.meshes``:
each module has ``build(model, *, cell=..., **params)`` that fills a gmsh model with the
geometry, the mesh and named physical groups (docs/scenes.md, "mesh")."""
