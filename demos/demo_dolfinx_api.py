"""Hertz contact (B2) as a plain DOLFINx script: fenicsx_mortar's library API, no scene file.

Problem (docs/benchmarks.md B2): a half-disk of radius R = 1 (the lower half of the circle
centred at (0, 1)) is pressed onto the block [−1, 1] × [−1, 0] by a dead traction 0.5 on its
flat edge, total force F = 1 per unit thickness; E = 1000, ν = 0.3 for both, plane strain,
compressible Neo-Hooke. Element size h_c = a/10 near the contact point. The disk is held
vertically by contact alone: its arc is the slave surface, the block's top the master.

What the script does, as a DOLFINx user would: the gmsh model (the package's B2 generator)
becomes a mesh with cell and facet tags through gmshio (0.10+: ``dolfinx.io.gmsh``); the
Neo-Hooke residual, the traction and the Dirichlet conditions are the script's own UFL and
DOLFINx objects; the contact is a ``ContactPair`` from the facet tags, and
``ContactProblem`` solves everything with PETSc SNES, in two load steps.

Analytic (small strain): 1/E* = 2(1 − ν²)/E, a = 2√(F R/(π E*)), p₀ = 2F/(π a),
p(x) = p₀ √(1 − x²/a²).

Expected result: p_max/p₀ − 1 within 2 %, a relative L2 pressure error over [−a, a] of a
few per cent, and the contact force on the disk equal to the applied force.
"""
from mpi4py import MPI  # first: PyPI's DOLFINx wheel loads MPICH through mpi4py

import gmsh
import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from petsc4py import PETSc
from scipy.integrate import trapezoid

import fenicsx_mortar as fm
from fenicsx_mortar.meshes import hertz

F_TOTAL, R, E, NU = 1.0, 1.0, 1000.0, 0.3
E_star = E / (2.0 * (1.0 - NU**2))
a = 2.0 * np.sqrt(F_TOTAL * R / (np.pi * E_star))
p0 = 2.0 * F_TOTAL / (np.pi * a)
# the generator's physical groups
DISK_ARC, DISK_TOP, BLOCK_TOP, BLOCK_BOTTOM = 3, 4, 5, 6

comm = MPI.COMM_WORLD
gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
if comm.rank == 0:
    hertz.build(gmsh.model, h_contact=a / 10, h_far=0.1)
try:                                   # DOLFINx >= 0.10: io.gmsh, returns MeshData
    from dolfinx.io import gmsh as gmshio
except ImportError:                    # DOLFINx 0.5-0.9
    from dolfinx.io import gmshio
msh, cell_tags, facet_tags = gmshio.model_to_mesh(gmsh.model, comm, 0, gdim=2)[:3]
gmsh.finalize()

if hasattr(fem, "functionspace"):                      # DOLFINx >= 0.7
    V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
else:                                                  # DOLFINx 0.5
    V = fem.VectorFunctionSpace(msh, ("Lagrange", 1))
u = fem.Function(V, name="displacement")
v = ufl.TestFunction(V)

# compressible Neo-Hooke, total Lagrangian: P = μ (F − F⁻ᵀ) + λ ln J F⁻ᵀ
mu = E / (2.0 * (1.0 + NU))
lmbda = E * NU / ((1.0 + NU) * (1.0 - 2.0 * NU))
Fd = ufl.Identity(2) + ufl.grad(u)
Finv_T = ufl.inv(Fd).T
P = mu * (Fd - Finv_T) + lmbda * ufl.ln(ufl.det(Fd)) * Finv_T
traction = fem.Constant(msh, np.array([0.0, 0.0], dtype=PETSc.ScalarType))
metadata = {"quadrature_degree": 2}
dx = ufl.Measure("dx", domain=msh, metadata=metadata)
ds = ufl.Measure("ds", domain=msh, subdomain_data=facet_tags, metadata=metadata)
residual = ufl.inner(P, ufl.grad(v)) * dx - ufl.dot(traction, v) * ds(DISK_TOP)

# supports: block bottom u_y = 0; u_x = 0 at (0, −1) on the block and at (0, 1), (0, 0.5) on
# the disk (two points on the axis: a circle on a frictionless support could spin)
bottom = facet_tags.indices[facet_tags.values == BLOCK_BOTTOM]
# (DOLFINx >= 0.9: locate_dofs_topological needs the entity-to-cell connectivity made first)
msh.topology.create_connectivity(1, 2)
msh.topology.create_connectivity(0, 2)
bcs = [fem.dirichletbc(PETSc.ScalarType(0.0),
                       fem.locate_dofs_topological(V.sub(1), 1, bottom), V.sub(1))]
for px, py in ((0.0, -1.0), (0.0, 1.0), (0.0, 0.5)):
    vertex = dmesh.locate_entities(msh, 0, lambda X: np.hypot(X[0] - px, X[1] - py) < 1e-10)
    bcs.append(fem.dirichletbc(PETSc.ScalarType(0.0),
                               fem.locate_dofs_topological(V.sub(0), 0, vertex), V.sub(0)))

pair = fm.ContactPair(V, facet_tags, slave=DISK_ARC, master=BLOCK_TOP, name="hertz",
                      method="mortar", enforcement="lagrange", E=E)
problem = fm.ContactProblem(residual, u, bcs, [pair])
for load in (0.5, 1.0):
    traction.value = np.array([0.0, -0.5 * load])
    result = problem.solve()
    assert result.converged, result.reason
    print(f"load {load:.2f}: {result.iterations} Newton iterations, "
          f"{result.augmentations} augmentations (SNES: {problem.snes.getType()})")

d = pair.interface()
order = np.argsort(d["x"])
x, p = d["x"][order], d["pressure"][order]
xs = np.linspace(-a, a, 4001)
exact = p0 * np.sqrt(np.clip(1.0 - xs**2 / a**2, 0.0, None))
l2 = np.sqrt(trapezoid((np.interp(xs, x, p) - exact) ** 2, xs) / trapezoid(exact**2, xs))
force = pair.record()["hertz"]["force_on_slave"][1]   # the block pushes the disk up
p_err = p.max() / p0 - 1.0
if comm.rank == 0:
    print(f"analytic: a = {a:.5f}, p0 = {p0:.4f}; "
          f"{fm.__name__} on {V.dofmap.index_map.size_global * 2} dofs")
    print(f"p_max/p0 - 1 = {100 * p_err:+.2f} %")
    print(f"relative L2 pressure error on [-a, a] = {100 * l2:.2f} %")
    print(f"|contact force - F| / F = {abs(force - F_TOTAL) / F_TOTAL:.1e}")
assert abs(p_err) < 0.02 and l2 < 0.06 and abs(force - F_TOTAL) < 1e-8
if comm.rank == 0:
    print("OK: p_max within 2 % of p0, L2 error below 6 %, force balance to round-off")
