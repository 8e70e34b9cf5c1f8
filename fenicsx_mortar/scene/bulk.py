"""Bodies → UFL residual and Jacobian (total Lagrangian, plane strain), loads, supports.

G(u; δu) = Σ_bodies ∫ P(F) : ∇δu dX + ∫ p J F⁻ᵀN · δu dS (follower pressure)
           + ∫ p N · δu dS (dead pressure) − ∫ t₀ · δu dS (dead traction).   docs/design.md §2.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import ufl
from mpi4py import MPI

from .. import _dolfinx as dx
from .materials import LAWS, Law, lame
from .meshing import Domain
from .model import Scene, SceneError
from .supports import point_vertices

_COMPONENTS = ("x", "y")


@dataclass
class Support:
    """One Dirichlet entry: its constants (per component) and its dofs, for reactions."""
    label: str
    components: dict[str, tuple[object, float, object]]  # comp → (Constant, value, curve)
    dofs: dict[str, np.ndarray]                           # comp → local unrolled dofs


@dataclass
class Bulk:
    domain: Domain
    V: object
    u: object
    residual: object           # compiled forms
    jacobian: object
    bcs: list
    supports: list[Support]
    laws: dict[str, Law]       # body name → law
    # (Constant, value, curve) of every scaled load
    scaled: list[tuple[object, float, object]] = field(default_factory=list)
    motions: list = field(default_factory=list)  # (Function, RigidMotion, dofs, scene)

    def set_time(self, t: float) -> None:
        """Scale every load and prescribed displacement by its curve at pseudo-time t."""
        for const, value, curve in self.scaled:
            const.value = value * curve(t)
        for g, motion, dofs, scene in self.motions:
            st = scene.curve(motion.translation_curve)(t)
            sr = scene.curve(motion.rotation_curve)(t)
            g.interpolate(lambda X: np.stack(motion.displacement(X, st, sr)))
        for s in self.supports:
            for const, value, curve in s.components.values():
                const.value = value * curve(t)

    def reactions(self, b_unconstrained) -> dict[str, dict[str, float]]:
        """Σ of the unconstrained residual over each support's dofs: the force the support
        exerts on the body."""
        comm = self.domain.mesh.comm
        n_owned = dx.owned_dof_count(self.V)
        arr = b_unconstrained.array_r
        out = {}
        for s in self.supports:
            out[s.label] = {c: comm.allreduce(float(arr[d[d < n_owned]].sum()), op=MPI.SUM)
                            for c, d in s.dofs.items()}
        return out


def build_bulk(scene: Scene, dom: Domain) -> Bulk:
    msh = dom.mesh
    V = dx.vector_space(msh)
    u = dx.Function(V, name="displacement")
    v = ufl.TestFunction(V)
    du = ufl.TrialFunction(V)
    dxm, ds = dx.measures(msh, dom.cell_tags, dom.facet_tags, scene.solver.quadrature_degree)
    F = ufl.Identity(2) + ufl.grad(u)

    laws: dict[str, Law] = {}
    G = 0
    for b in scene.bodies:
        mu, lmbda = lame(b.material.E, b.material.nu)
        law = LAWS[b.material.model](dx.constant(msh, mu), dx.constant(msh, lmbda))
        laws[b.name] = law
        G += ufl.inner(law.piola(F), ufl.grad(v)) * dxm(dom.cell_groups[b.group])

    scaled = []
    for p in scene.pressures:
        c = dx.constant(msh, 0.0)
        scaled.append((c, p.value, scene.curve(p.curve)))
        N = ufl.FacetNormal(msh)
        ids = _facet_ids(dom, p.boundary)
        if p.follower:
            G += c * ufl.det(F) * ufl.dot(ufl.inv(F).T * N, v) * ds(ids)
        else:
            G += c * ufl.dot(N, v) * ds(ids)
    for t in scene.tractions:
        for i, comp in enumerate(t.value):
            if comp == 0.0:
                continue
            c = dx.constant(msh, 0.0)
            scaled.append((c, comp, scene.curve(t.curve)))
            G -= c * v[i] * ds(_facet_ids(dom, t.boundary))

    supports, bcs, motions = _supports(scene, dom, V)
    residual = dx.form(G)
    jacobian = dx.form(ufl.derivative(G, u, du))
    return Bulk(dom, V, u, residual, jacobian, bcs, supports, laws, scaled, motions)


def _facet_ids(dom: Domain, names) -> tuple[int, ...]:
    names = [names] if isinstance(names, str) else names
    return tuple(dom.facet_groups[n] for n in names)


def _supports(scene: Scene, dom: Domain, V):
    msh = dom.mesh
    comm = msh.comm
    supports, bcs, motions = [], [], []
    for i, d in enumerate(scene.dirichlet):
        label = d.label
        if any(s.label == label for s in supports):  # keep every support's reactions
            label = f"{label}#{i}"
        if d.motion is not None:
            facets = dom.facets(d.boundary)
            g = dx.Function(V)
            bcs.append(dx.dirichletbc_function(g, V, facets))
            dofs = {c: dx.facet_dofs(V, k, facets) for k, c in enumerate(_COMPONENTS)}
            motions.append((g, d.motion, dofs, scene))
            supports.append(Support(label, {}, dofs))
            continue
        if d.boundary is not None:
            facets = dom.facets(d.boundary)
            dofs = {c: dx.facet_dofs(V, k, facets) for k, c in enumerate(_COMPONENTS)}
        else:
            verts = point_vertices(dom, d.point, d.body, scene)
            if comm.allreduce(len(verts), op=MPI.SUM) == 0:
                raise SceneError(f"dirichlet[{i}].point = {d.point}: not a mesh node of body "
                                 f"{d.body!r} (point supports must sit on a node)")
            dofs = {c: dx.vertex_dofs(V, k, verts) for k, c in enumerate(_COMPONENTS)}
        comps = {}
        for k, c in enumerate(_COMPONENTS):
            value = getattr(d, c)
            if value is None:
                continue
            const = dx.constant(msh, 0.0)
            comps[c] = (const, value, scene.curve(d.curve))
            bcs.append(dx.dirichletbc(const, dofs[c], V, k))
        supports.append(Support(label, comps, {c: dofs[c] for c in comps}))
    return supports, bcs, motions


class StressOutput:
    """Cellwise (DG0) Cauchy stress σ = J⁻¹ P Fᵀ, body by body."""

    def __init__(self, bulk: Bulk, scene: Scene):
        dom = bulk.domain
        self.sigma = dx.Function(dx.tensor_dg0_space(dom.mesh), name="cauchy_stress")
        F = ufl.Identity(2) + ufl.grad(bulk.u)
        self._parts = []
        for b in scene.bodies:
            cells = dom.cells(b.group)
            expr = dx.expression(bulk.laws[b.name].cauchy(F), self.sigma.function_space)
            self._parts.append((expr, cells))

    def update(self) -> None:
        for expr, cells in self._parts:
            dx.interpolate(self.sigma, expr, cells)
        self.sigma.x.scatter_forward()

    def values(self) -> np.ndarray:
        """(n_owned_cells, 2, 2) Cauchy stress per owned cell."""
        n = dx.num_owned_cells(self.sigma.function_space.mesh)
        return self.sigma.x.array.reshape(-1, 2, 2)[:n]
