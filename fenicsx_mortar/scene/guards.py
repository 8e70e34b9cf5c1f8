"""The scene runner's checks of its input and its steps (the physical acceptance of a
converged state is the core's, acceptance.py, and runs in every solve):

* :func:`check_petsc_options` asks PETSc itself, before meshing, whether it takes every
  option of ``solver.petsc`` (a value it rejects, an option it never reads);
* :func:`check_tolerance` compares ``solver.atol`` with the loads' residual scale;
* :func:`penetration_warning`: a penalty pair whose penetration exceeds a tenth of the
  local slave element size (the answer is then far from the contact constraint).
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

from .. import _dolfinx as dx
from .. import petsc_options as po
from .model import Scene, SceneError, SolverSettings

#: atol against the loads' residual scale: above, u = 0 passes as converged; below, it is
#: round-off
ATOL_RANGE = (1e-15, 1e-3)


def check_petsc_options(settings: SolverSettings) -> None:
    """Every ``solver.petsc`` option is taken by PETSc and read when the solver is set up
    or, for ``-mat_mumps_*``, at its first factorization (an option read never, as
    ``-snes_foo``, or not for this solver, as ``-mat_mumps_*`` with SuperLU_dist, would be
    silently ignored). Raises SceneError naming the option."""
    user = po.normalize(settings.petsc)
    try:
        unread = po.unread(settings, user, key="solver.petsc")
    except ValueError as e:
        raise SceneError(str(e)) from None
    if unread:
        raise SceneError(po.unread_message(unread, key="solver.petsc"))


# ---------------------------------------------------------------------- tolerances


def check_tolerance(scene: Scene, bulk, samples: int = 16) -> None:
    """``solver.atol`` within ATOL_RANGE of the loads' residual scale: the largest ‖R(u =
    0)‖ (bulk forms, Dirichlet rows included, as Newton's first residual) over the load
    path, sampled at up to ``samples`` load-step targets (the last one included) and as
    many evenly spaced pseudo-times (a step's cuts visit those: a full turn in one step has
    no load at its target); and not below the residual's round-off floor
    (:func:`roundoff_floor`), which no Newton iterate gets under. A scene without loads
    (scale 0) is checked against the floor only. Collective; call before the first step
    (u = 0). Raises SceneError naming the key to change."""
    targets = scene.steps.targets()
    m = min(samples, len(targets))
    times = {targets[round(i * (len(targets) - 1) / max(m - 1, 1))] for i in range(m)}
    times |= {targets[-1] * (i + 1) / samples for i in range(samples)}
    b = dx.create_vector(bulk.residual)
    x = b.duplicate()
    x.set(0.0)
    scale = 0.0
    for t in sorted(times):
        bulk.set_time(t)
        dx.assemble_residual(b, bulk.residual, bulk.jacobian, bulk.bcs, x)
        scale = max(scale, b.norm())
    bulk.set_time(0.0)
    b.destroy()
    x.destroy()
    floor, stiffest = roundoff_floor(scene, bulk)
    atol = scene.solver.atol
    low, high = ATOL_RANGE
    if scale > 0 and floor > high * scale:
        raise SceneError(
            f"{stiffest}: the loads' residual scale {scale:.3g} (|R| at u = 0 over the load "
            f"path) is within {1 / high:g}x of the residual's round-off floor {floor:.3g} "
            "(double precision x E x the bodies' size): no solver.atol can tell an answer "
            "from u = 0 here; loads this small against E need other units (scale E and the "
            "loads together)")
    if scale > 0 and atol > high * scale:
        raise SceneError(f"solver.atol = {atol:g}: must lie in [{max(low * scale, floor):.3g}, "
                         f"{high * scale:.3g}] ({high:g} x the loads' residual scale "
                         f"{scale:.3g}, |R| at u = 0 over the load path): a larger atol "
                         "passes u = 0 as converged")
    if scale > 0 and atol < low * scale:
        raise SceneError(f"solver.atol = {atol:g}: must lie in [{max(low * scale, floor):.3g}, "
                         f"{high * scale:.3g}] x the loads' residual scale {scale:.3g} (|R| at "
                         f"u = 0 over the load path): a smaller one is below round-off")
    if atol < floor:
        top = f", {high * scale:.3g}]" if scale > 0 else "]"
        raise SceneError(f"solver.atol = {atol:g}: below the residual's round-off floor "
                         f"{floor:.3g} at this problem's scale (double precision x E x the "
                         f"bodies' size, from {stiffest}): no Newton iterate gets under it, "
                         f"every step would fail; set solver.atol in [{floor:.3g}{top}")


def roundoff_floor(scene: Scene, bulk) -> tuple[float, str]:
    """The round-off floor of the residual's norm and the key of the body that sets it:
    a cell's stress is computed to about ε E (the strain is a difference of O(1) terms),
    its nodal forces to ε E h, so over the mesh ‖δR‖ ≈ ε (Σ_b E_b² A_b)^½ (A_b: the body's
    area); a block 5e5 wide with E = 1000 stalls at |R| ≈ 1e-7 (collective)."""
    dom = bulk.domain
    msh = dom.mesh
    x = dx.node_coordinates(msh)
    n_own = dx.num_owned_cells(msh)
    cells = dx.cell_nodes(msh)[:n_own]
    if cells.shape[1] == 4:                  # DOLFINx's quadrilaterals: tensor order
        cells = cells[:, [0, 1, 3, 2]]
    p = x[cells]
    q = np.roll(p, -1, axis=1)
    area = 0.5 * np.abs(np.sum(p[..., 0] * q[..., 1] - q[..., 0] * p[..., 1], axis=1))
    tag = np.full(dx.num_cells(msh), -1)
    tag[dom.cell_tags.indices] = dom.cell_tags.values
    tag = tag[:n_own]
    comm = msh.comm
    total, stiffest, worst = 0.0, "bodies[0].material.E", -1.0
    for i, body in enumerate(scene.bodies):
        a = comm.allreduce(float(area[tag == dom.cell_groups[body.group]].sum()), op=MPI.SUM)
        part = body.material.E ** 2 * a
        total += part
        if part > worst:
            stiffest, worst = f"bodies[{i}].material.E", part
    return float(np.finfo(float).eps * np.sqrt(total)), stiffest


def penetration_warning(pair, step: int) -> str | None:
    """For a penalty pair: the largest penetration −g̃_j/A_j against a tenth of the slave
    node's element size (its segments' mean reference length), or None."""
    st, s = pair.state, pair.slave
    if st is None or not len(s.seg):
        return None
    A = st.A
    pen = np.where(A > 0, -st.g / np.where(A > 0, A, 1.0), 0.0)
    length = np.linalg.norm(s.X[s.seg[:, 1]] - s.X[s.seg[:, 0]], axis=1)
    size, count = np.zeros(s.n), np.zeros(s.n)
    for col in (0, 1):
        np.add.at(size, s.seg[:, col], length)
        np.add.at(count, s.seg[:, col], 1.0)
    size /= np.maximum(count, 1.0)
    ratio = pen / np.where(size > 0, size, np.inf)
    j = int(np.argmax(ratio))
    if not ratio[j] > 0.1:
        return None
    x = st.xs[j]
    return (f"contact {pair.name}: penetration {pen[j]:.3g} at slave node ({x[0]:.4g}, "
            f"{x[1]:.4g}) in step {step} exceeds a tenth of the local slave element size "
            f"{size[j]:.3g}: the penalty is too soft for this load (raise "
            "enforcement.epsilon, or use type = 'alm')")
