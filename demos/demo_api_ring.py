"""A hyperelastic ring squeezed between two plates, with friction: two contact pairs, load
steps, reactions and ParaView output — fenicsx_mortar's library API in a plain DOLFINx script.

Problem: a ring (inner radius 0.6, outer radius 1; compressible Neo-Hooke, E = 100,
ν = 0.3, plane strain) between two plates 3 × 0.3 (E = 10 000, ν = 0.3) that touch it at
(0, ∓1). The lower plate's bottom is fixed; the upper plate's top moves down by
δ(t) = 0.3 t (u_x = 0 there) over the pseudo-time t ∈ (0, 1], in four load steps. Two
contact pairs — ring's lower arc on the lower plate, upper arc on the upper plate — with
Lagrange multipliers (semi-smooth Newton) and Coulomb friction μ = 0.2. Two nodes of the
ring on the symmetry axis, (0, ±0.6), have u_x = 0: with μ = 0 the ring could otherwise
slide sideways at no cost.

What the script uses: ``ContactPair`` (from the facet tags), ``ContactProblem`` (the
script's own UFL residual and Dirichlet conditions), ``LoadStepper`` (load steps with step
cutting), ``problem.reaction`` (support forces, summed over MPI ranks), ``pair.record()``
and ``pair.fields()`` (contact pressure, gap, tangential traction, stick/slip as DOLFINx
Functions), written with the displacement to ``ring.xdmf`` for ParaView.

Expected result (checked at the end, to round-off unless said otherwise):
* the two supports' reactions balance (the ring's axis supports carry nothing);
* each plate is in equilibrium: the reaction at its support equals the force the ring's
  contact puts on it; so the two contact forces are equal and opposite;
* the problem is symmetric about x = 0: no net horizontal force (below 1e-8 of the vertical
  one) and a tangential traction with zero sum;
* the squeeze force grows with δ; the pressure peaks on the axis (|x| below two ring
  elements).
"""
import sys
from pathlib import Path

from mpi4py import MPI  # first: DOLFINx's pip wheel loads its MPI through mpi4py

import gmsh
import numpy as np
import ufl
from dolfinx import fem, io
from dolfinx import mesh as dmesh
from petsc4py import PETSc

import fenicsx_mortar as fm
from fenicsx_mortar.meshes import ring_between_plates

try:                                                   # DOLFINx <= 0.9
    from dolfinx.io.gmshio import model_to_mesh
except ImportError:                                    # DOLFINx >= 0.10
    from dolfinx.io.gmsh import model_to_mesh

OUT = Path(sys.argv[1] if len(sys.argv) > 1 else "results/demo_api_ring")
RING, LOWER, UPPER = 1, 2, 3                            # the generator's cell tags
RING_LOWER, RING_UPPER, LOWER_TOP, LOWER_BOTTOM, UPPER_BOTTOM, UPPER_TOP = 4, 5, 6, 7, 8, 9
E = {RING: 100.0, LOWER: 1e4, UPPER: 1e4}
NU, MU, SQUEEZE = 0.3, 0.2, 0.3

comm = MPI.COMM_WORLD
gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
if comm.rank == 0:
    ring_between_plates.build(gmsh.model, ring_nr=6, ring_nc=96, plate_nx=30, plate_ny=3)
msh, cell_tags, facet_tags = model_to_mesh(gmsh.model, comm, 0, gdim=2)[:3]
gmsh.finalize()

if hasattr(fem, "functionspace"):                      # DOLFINx >= 0.7
    V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
    Q = fem.functionspace(msh, ("DG", 0))
else:                                                  # DOLFINx 0.5
    V = fem.VectorFunctionSpace(msh, ("Lagrange", 1))
    Q = fem.FunctionSpace(msh, ("DG", 0))
u = fem.Function(V, name="displacement")
v = ufl.TestFunction(V)

# Young's modulus per cell; compressible Neo-Hooke: P = μ (F − F⁻ᵀ) + λ ln J F⁻ᵀ
E_cell = fem.Function(Q)
E_cell.x.array[cell_tags.indices] = [E[t] for t in cell_tags.values]
mu = E_cell / (2.0 * (1.0 + NU))
lmbda = E_cell * NU / ((1.0 + NU) * (1.0 - 2.0 * NU))
F = ufl.Identity(2) + ufl.grad(u)
Finv_T = ufl.inv(F).T
P = mu * (F - Finv_T) + lmbda * ufl.ln(ufl.det(F)) * Finv_T
residual = ufl.inner(P, ufl.grad(v)) * ufl.dx(metadata={"quadrature_degree": 2})

# supports: the lower plate's bottom fixed, the upper plate's top moved down by δ(t)
msh.topology.create_connectivity(1, 2)
msh.topology.create_connectivity(0, 2)


def facet_dofs(tag, k):
    return fem.locate_dofs_topological(V.sub(k), 1, facet_tags.find(tag))


zero = PETSc.ScalarType(0.0)
push = fem.Constant(msh, zero)
bcs = [fem.dirichletbc(zero, facet_dofs(LOWER_BOTTOM, k), V.sub(k)) for k in range(2)]
bcs += [fem.dirichletbc(zero, facet_dofs(UPPER_TOP, 0), V.sub(0)),
        fem.dirichletbc(push, facet_dofs(UPPER_TOP, 1), V.sub(1))]
axis = dmesh.locate_entities(msh, 0, lambda X: np.isclose(X[0], 0.0)
                             & np.isclose(np.abs(X[1]), 0.6))
bcs.append(fem.dirichletbc(zero, fem.locate_dofs_topological(V.sub(0), 0, axis), V.sub(0)))

common = dict(enforcement="lagrange", friction="coulomb", mu=MU, E=E, cell_tags=cell_tags)
lower = fm.ContactPair(V, facet_tags, slave=RING_LOWER, master=LOWER_TOP, name="lower",
                       **common)
upper = fm.ContactPair(V, facet_tags, slave=RING_UPPER, master=UPPER_BOTTOM, name="upper",
                       **common)
OUT.mkdir(parents=True, exist_ok=True)
xdmf = io.XDMFFile(comm, str(OUT / "ring.xdmf"), "w")
xdmf.write_mesh(msh)
history = []


def set_load(t: float) -> None:
    push.value = -SQUEEZE * t


def contact_force(pair) -> np.ndarray:
    """The force the contact puts on the slave body: normal plus friction."""
    r = pair.record()[pair.name]
    return np.add(r["force_on_slave"], r["tangential_force_on_slave"])


def on_step(step: fm.StepDone) -> None:
    """Reactions and contact forces of the step; the fields into the XDMF file."""
    history.append({
        "t": step.time,
        "bottom": problem.reaction(facet_tags, LOWER_BOTTOM),
        "top": problem.reaction(facet_tags, UPPER_TOP),
        "lower": contact_force(lower), "upper": contact_force(upper),
        "t_sum": sum(q.interface()["t_tangential"].sum() for q in (lower, upper)),
        "p_max": max(q.interface()["pressure"].max() for q in (lower, upper))})
    xdmf.write_function(u, step.time)
    for pair in (lower, upper):
        for f in pair.fields().values():
            xdmf.write_function(f, step.time)


with fm.ContactProblem(residual, u, bcs, [lower, upper],
                       petsc_options_prefix="ring_") as problem:
    stepper = fm.LoadStepper(problem, set_load, times=[0.25, 0.5, 0.75, 1.0], on_step=on_step)
    result = stepper.run()
    p = upper.interface()
xdmf.close()
assert result.completed, result.message

last = history[-1]
scale = abs(last["top"][1])
if comm.rank == 0:
    for h in history:
        print(f"t = {h['t']:.2f}: squeeze force {h['top'][1]:+.10f}, bottom reaction "
              f"{h['bottom'][1]:+.10f}, contact forces on the ring {h['lower'][1]:+.10f} / "
              f"{h['upper'][1]:+.10f}")
    print(f"force balance |R_bottom + R_top| / |R_top| = "
          f"{np.abs(last['bottom'] + last['top']).max() / scale:.1e}")
    print(f"upper plate |R_top - F_upper| / |R_top| = "
          f"{np.abs(last['top'] - last['upper']).max() / scale:.1e}")
    print(f"symmetry: |R_x| / |R_y| = {abs(last['top'][0]) / scale:.1e}, "
          f"|sum of t_T| / p_max = {abs(last['t_sum']) / last['p_max']:.1e}")
    print(f"fields written: {OUT / 'ring.xdmf'}")
forces = [h["top"][1] for h in history]
h_elem = 2.0 * np.pi / 96
peak = abs(p["x"][np.argmax(p["pressure"])])
assert all(b < a < 0 for a, b in zip(forces, forces[1:])), forces   # pushing down, growing
assert np.abs(last["bottom"] + last["top"]).max() < 1e-8 * scale
assert np.abs(last["top"] - last["upper"]).max() < 1e-8 * scale
assert np.abs(last["lower"] + last["upper"]).max() < 1e-8 * scale
assert abs(last["top"][0]) < 1e-8 * scale and abs(last["t_sum"]) < 1e-8 * last["p_max"]
assert peak < 2 * h_elem, peak
if comm.rank == 0:
    print("OK: reactions balance, each plate in equilibrium with its contact force, "
          "symmetric, the pressure peaks on the axis")
