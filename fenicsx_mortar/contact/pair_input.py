"""The checks of a :class:`~.pair.ContactPair`'s arguments, at the Python API's input: names
among the registries' choices, numbers in their ranges (settings.RANGES, shared with the
scenes), surfaces that face each other; warnings for a deep initial overlap and for a
stiff, fine slave on a soft master.
"""
from __future__ import annotations

import warnings
from typing import Mapping

import numpy as np
from scipy.spatial import cKDTree

from ..settings import check_number
from . import crossing
from .registry import ENFORCEMENTS, FRICTION_LAWS, METHODS, SMOOTHINGS
from .surface import Surface


def check_arguments(name, *, slave, master, method, smoothing, enforcement, friction,
                     basis, slave_smoothing) -> None:
    """Names among the registries' choices and distinct surfaces, each refused by name."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"name = {name!r}: a non-empty string")
    for key, value, registry in (("method", method, METHODS),
                                 ("smoothing", smoothing, SMOOTHINGS),
                                 ("enforcement", enforcement, ENFORCEMENTS),
                                 ("friction", friction, FRICTION_LAWS)):
        if not isinstance(value, str) or value not in registry:
            raise ValueError(f"contact {name}: {key} = {value!r}: must be one of "
                             f"{', '.join(map(repr, registry.names()))}")
    kind = METHODS[method]
    if basis is not None and basis not in kind.bases:
        raise ValueError(f"contact {name}: basis = {basis!r}: method {method!r} offers "
                         f"{', '.join(map(repr, kind.bases))}")
    if slave_smoothing != "none" and (slave_smoothing not in SMOOTHINGS
                                      or not kind.two_sided):
        raise ValueError(f"contact {name}: slave_smoothing = {slave_smoothing!r}: only the "
                         "mortar method smooths the slave, with a local curve ('hermite')")
    both = set(np.atleast_1d(slave).tolist()) & set(np.atleast_1d(master).tolist())
    if both:
        raise ValueError(f"contact {name}: slave and master share the tag(s) {sorted(both)}: "
                         "they must be two different boundaries")


def check_numbers(name: str, *, epsilon, tolerance, mu, E, n_gauss, search_radius,
                   cell_tags) -> None:
    """The pair's numbers in their ranges (settings.RANGES, shared with the scenes), each
    refused by name (an ε ≤ 0 or a μ < 0 made a converged answer with forces across open
    gaps, or friction that pushes)."""
    key = f"contact {name}: "
    for arg, value in (("epsilon", epsilon), ("search_radius", search_radius),
                       ("tolerance", tolerance), ("mu", mu), ("n_gauss", n_gauss)):
        if value is not None:
            check_number(arg, value, key + arg)
    if isinstance(E, Mapping):
        if cell_tags is None:
            raise ValueError(f"{key}E = {dict(E)!r}: a mapping cell tag -> E needs cell_tags "
                             "(which body is which)")
        for tag, value in E.items():
            check_number("E", value, f"{key}E[{tag}]")
    elif E is not None:
        check_number("E", E, key + "E")


def check_facing(name: str, slave: Surface, master: Surface) -> None:
    """Some slave segment must face its nearest master segment (outward normals within 60°
    of opposite): a pair that never faces is a mistake in the set-up, not a contact."""
    def mids_normals(s: Surface):
        a, b = s.X[s.seg[:, 0]], s.X[s.seg[:, 1]]
        t = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
        return 0.5 * (a + b), np.column_stack([-t[:, 1], t[:, 0]])
    ms, ns = mids_normals(slave)
    mm, nm = mids_normals(master)
    _, j = cKDTree(mm).query(ms)
    if not np.any(np.einsum("ij,ij->i", ns, nm[j]) < -0.5):
        raise ValueError(f"contact {name}: the slave and master surfaces do not face each "
                         "other (their outward normals never oppose): check the tags")


def check_overlap(name: str, slave: Surface, master: Surface) -> None:
    """Warn when slave nodes start inside the master deeper than their element size
    (:func:`.crossing.initial_overlap`): the first step then often fails."""
    nodes, depth, size = crossing.initial_overlap(slave.X, slave.seg, master.X, master.seg)
    if nodes.size:
        j = int(np.argmax(depth))
        x = slave.X[nodes[j]]
        warnings.warn(f"contact {name}: {nodes.size} slave node(s) start inside the master, up "
                      f"to {depth[j]:.3g} deep at ({x[0]:.4g}, {x[1]:.4g}), more than their "
                      f"element size ({size[j]:.3g}): the first step must resolve all of it, "
                      "which then often fails (move the bodies apart, or mesh them coarser "
                      "than the overlap)", stacklevel=3)


def check_roles(name: str, slave: Surface, master: Surface, E_s: float, E_m: float) -> None:
    """Warn when the slave is the stiffer body with the finer segments. The multipliers live
    on the slave nodes; the soft master must then meet more weighted-gap conditions than it
    has nodes in the contact zone, and the pressure dips or zig-zags (docs/stability.md,
    cases 1 and 5: a 60 % dip at the centre of a Hertz-like zone)."""
    h_s, h_m = slave.mean_length(), master.mean_length()
    if E_s >= 2.0 * E_m and h_s < h_m:
        warnings.warn(f"contact {name}: the slave body is {E_s / E_m:.3g} x stiffer than the "
                      f"master's and its segments are finer ({h_s:.3g} < {h_m:.3g}): the "
                      "master cannot follow the slave's multipliers and the pressure may "
                      "oscillate; make the softer body the slave, or refine the master",
                      stacklevel=3)
