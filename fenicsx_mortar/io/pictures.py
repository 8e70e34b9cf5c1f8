"""Pictures of a run: the deformed meshes with the slave surface coloured by contact pressure
(or the cells by a field), one step as a PNG, a load path as a GIF.

A :class:`Snapshot` is the nodal state of one converged step, small and plain (numpy
arrays): take one per step with ``solve(scene, on_step=lambda rec, state:
snaps.append(snapshot(state, rec["time"])))``, draw any of them afterwards, or keep them in
an ``.npz`` file (:func:`save_snapshots`, :func:`load_snapshots`) and draw them later
without solving again. Serial runs only (one rank holds the whole mesh).
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

STATUS_CODES = {"inactive": 0, "stick": 1, "slip": 2}


@dataclass
class Snapshot:
    """One step's nodal state.

    points: (n_nodes, 2) current node positions; cells: (n_cells, k) node indices in drawing
    order (counter-clockwise polygons); body: (n_cells,) body index of each cell;
    sigma: (n_cells, 2, 2) cellwise Cauchy stress; surface: (n_slave_nodes, 2) current
    positions of the first contact pair's slave nodes, segments: (n_seg, 2) its segments;
    pressure, t_tangential: (n_slave_nodes,) nodal tractions; status: 0 inactive,
    1 stick, 2 slip (``STATUS_CODES``; all 0 when frictionless)."""
    time: float
    points: np.ndarray
    cells: np.ndarray
    body: np.ndarray
    sigma: np.ndarray
    surface: np.ndarray
    segments: np.ndarray
    pressure: np.ndarray
    t_tangential: np.ndarray
    status: np.ndarray


def snapshot(result, time: float | None = None, pair: int = 0) -> Snapshot:
    """The current state of a :class:`~fenicsx_mortar.scene.runner.Result` (or of the state
    handed to ``solve(..., on_step=...)``)."""
    from .. import _dolfinx as dx
    msh = result.domain.mesh
    if msh.comm.size > 1:
        raise NotImplementedError("pictures: serial runs only")
    V = result.bulk.V
    dofs = dx.cell_dofs(V)  # node blocks per cell, reference order
    if dofs.shape[1] == 4:  # DOLFINx quadrilaterals are tensor-ordered: 0 1 / 2 3
        dofs = dofs[:, [0, 1, 3, 2]]
    X = dx.dof_coordinates(V)
    points = X + result.u.x.array.reshape(-1, 2)[: len(X)]
    body = np.zeros(dofs.shape[0], dtype=np.int32)
    tags = result.domain.cell_tags
    body[tags.indices] = tags.values
    contact = result.pairs[pair]
    d = contact.interface()
    ns = len(d["x"])
    status = np.array([STATUS_CODES[str(s)] for s in d.get("status", ["inactive"] * ns)])
    return Snapshot(
        time=float(result.steps[-1]["time"] if time is None else time), points=points,
        cells=dofs.astype(np.int64), body=body, sigma=result.stress.values().copy(),
        surface=np.column_stack([d["x"], d["y"]]), segments=np.asarray(contact.slave.seg),
        pressure=np.asarray(d["pressure"], dtype=float).copy(),
        t_tangential=np.asarray(d.get("t_tangential", np.zeros(ns)), dtype=float).copy(),
        status=status)


def save_snapshots(path: str | Path, snaps: Sequence[Snapshot]) -> None:
    """All snapshots in one ``.npz`` (mesh connectivity stored once)."""
    s0 = snaps[0]
    np.savez_compressed(
        path, time=np.array([s.time for s in snaps]), cells=s0.cells, body=s0.body,
        segments=s0.segments,
        **{f.name: np.stack([getattr(s, f.name) for s in snaps]) for f in fields(Snapshot)
           if f.name not in ("time", "cells", "body", "segments")})


def load_snapshots(path: str | Path) -> list[Snapshot]:
    d = np.load(path)
    fixed = ("time", "cells", "body", "segments")
    per_step = [f.name for f in fields(Snapshot) if f.name not in fixed]
    return [Snapshot(time=float(t), cells=d["cells"], body=d["body"], segments=d["segments"],
                     **{k: d[k][i] for k in per_step}) for i, t in enumerate(d["time"])]


def von_mises(sigma: np.ndarray, nu: float = 0.3) -> np.ndarray:
    """Plane-strain von Mises stress per cell (σ_zz = ν(σ_xx + σ_yy), small-strain estimate)."""
    sxx, syy, sxy = sigma[:, 0, 0], sigma[:, 1, 1], sigma[:, 0, 1]
    szz = nu * (sxx + syy)
    return np.sqrt(0.5 * ((sxx - syy)**2 + (syy - szz)**2 + (szz - sxx)**2) + 3 * sxy**2)


def pressure_scale(snaps: Sequence[Snapshot], percentile: float = 98.0) -> float:
    """A colour-scale top for the pressure that one end-node spike does not flatten: the
    given percentile of all positive nodal pressures of the snapshots (larger ones are
    drawn in the top colour; the colour bar then says so with an arrow)."""
    p = np.concatenate([s.pressure[s.pressure > 0] for s in snaps] + [np.zeros(1)])
    return max(float(np.percentile(p[p > 0], percentile)) if (p > 0).any() else 1.0, 1e-300)


def draw(ax, snap: Snapshot, *, p_max: float | None = None, cell_values: np.ndarray | None = None,
         cell_limits: tuple[float, float] | None = None, window=None, title: str | None = None,
         colorbar: bool = True, cmap: str = "turbo", legend_loc: str = "upper right"):
    """Deformed mesh (grey per body, or cells coloured by ``cell_values``) with the slave
    surface drawn thick where it touches, coloured by contact pressure (colour scale 0..``p_max``,
    default ``pressure_scale``);
    slipping nodes marked with open circles, sticking ones with dots. ``window`` =
    (xmin, xmax, ymin, ymax). Returns the pressure colour mapping."""
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.colors import Normalize

    polys = snap.points[snap.cells]
    if cell_values is None:
        shades = np.array(["0.88", "0.72", "0.80", "0.65"])
        mesh = PolyCollection(polys, facecolors=shades[(snap.body - snap.body.min()) % 4],
                              edgecolors="0.35", linewidths=0.3)
    else:
        lo, hi = cell_limits or (float(np.min(cell_values)), float(np.max(cell_values)))
        mesh = PolyCollection(polys, array=cell_values, cmap="viridis", norm=Normalize(lo, hi),
                              edgecolors="0.35", linewidths=0.2)
    ax.add_collection(mesh)
    norm = Normalize(0.0, p_max if p_max is not None else pressure_scale([snap]))
    seg_p = snap.pressure[snap.segments].mean(axis=1)
    touching = seg_p > 0
    ax.add_collection(LineCollection(snap.surface[snap.segments[~touching]], colors="k",
                                     linewidths=1.0))
    line = LineCollection(snap.surface[snap.segments[touching]], array=seg_p[touching],
                          cmap=cmap, norm=norm, linewidths=4, capstyle="round")
    ax.add_collection(line)
    on = snap.pressure > 0
    stick, slip = on & (snap.status == 1), on & (snap.status == 2)
    if stick.any():
        ax.plot(*snap.surface[stick].T, "o", ms=2.5, color="tab:blue", label="stick")
    if slip.any():
        ax.plot(*snap.surface[slip].T, "o", ms=3.5, mfc="none", mec="tab:green", mew=0.7,
                label="slip")
    if stick.any() or slip.any():
        ax.legend(loc=legend_loc, fontsize=7, framealpha=0.8)
    if window is None:
        lo, hi = snap.points.min(axis=0), snap.points.max(axis=0)
        pad = 0.03 * (hi - lo).max()
        window = (lo[0] - pad, hi[0] + pad, lo[1] - pad, hi[1] + pad)
    ax.set_xlim(window[0], window[1])
    ax.set_ylim(window[2], window[3])
    ax.set_aspect("equal")
    ax.set_title(title if title is not None else f"t = {snap.time:.4g}", fontsize=9)
    if colorbar:
        fig = ax.figure
        fig.colorbar(line, ax=ax, label="contact pressure", shrink=0.8, extend=_extend(snap, norm))
        if cell_values is not None:
            fig.colorbar(mesh, ax=ax, shrink=0.8)
    plt.setp(ax.get_xticklabels() + ax.get_yticklabels(), fontsize=7)
    return line


def frames_png(path: str | Path, snaps: Sequence[Snapshot], *, ncols: int = 2,
               panel: tuple[float, float] = (5.0, 3.2), suptitle: str | None = None,
               label: Callable[[Snapshot], str] | None = None, **kw) -> Path:
    """Several steps side by side (common pressure scale), one PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    n = len(snaps)
    ncols = min(ncols, n)
    nrows = -(-n // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(panel[0] * ncols, panel[1] * nrows),
                             squeeze=False, constrained_layout=True)
    kw.setdefault("p_max", pressure_scale(snaps))
    for ax, s in zip(axes.flat, snaps):
        line = draw(ax, s, colorbar=False, title=label(s) if label else None, **kw)
    for ax in axes.flat[n:]:
        ax.axis("off")
    fig.colorbar(line, ax=axes, label="contact pressure", shrink=0.7,
                 extend=_extend(snaps, line.norm))
    if suptitle:
        fig.suptitle(suptitle, fontsize=10)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def animation_gif(path: str | Path, snaps: Sequence[Snapshot], *, fps: int = 6,
                  size: tuple[float, float] = (6.0, 4.0),
                  label: Callable[[Snapshot], str] | None = None,
                  **kw) -> Path:
    """The load path as a GIF (matplotlib animation, Pillow writer), common pressure scale
    and a fixed window enclosing every frame."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter
    kw.setdefault("p_max", pressure_scale(snaps))
    if kw.get("window") is None:
        lo = np.min([s.points.min(axis=0) for s in snaps], axis=0)
        hi = np.max([s.points.max(axis=0) for s in snaps], axis=0)
        pad = 0.03 * (hi - lo).max()
        kw["window"] = (lo[0] - pad, hi[0] + pad, lo[1] - pad, hi[1] + pad)
    fig, ax = plt.subplots(figsize=size, constrained_layout=True)
    line = draw(ax, snaps[0], colorbar=False, **kw)
    fig.colorbar(line, ax=ax, label="contact pressure", shrink=0.8,
                 extend=_extend(snaps, line.norm))

    def frame(i: int):
        ax.clear()
        draw(ax, snaps[i], colorbar=False, title=label(snaps[i]) if label else None, **kw)
        return []

    anim = FuncAnimation(fig, frame, frames=len(snaps), blit=False)
    anim.save(str(path), writer=PillowWriter(fps=fps), dpi=90)
    plt.close(fig)
    return Path(path)


def _extend(snaps, norm) -> str:
    snaps = [snaps] if isinstance(snaps, Snapshot) else snaps
    return "max" if max(float(s.pressure.max()) for s in snaps) > norm.vmax else "neither"
