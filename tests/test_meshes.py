"""Facts about the gmsh mesh generators in meshes/*.py (geometry, groups, cells, nodes)."""
from __future__ import annotations

import importlib
import math
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

gmsh = pytest.importorskip("gmsh")

REPO = Path(__file__).parents[1]
GMSH_TYPE = {"quadrilateral": 3, "triangle": 2}   # gmsh element types quad4, tri3
CELLS = tuple(GMSH_TYPE)


def load(name: str):
    """The generator module, as the project's loader imports it."""
    return importlib.import_module(f"fenicsx_mortar.meshes.{name}")


@contextmanager
def built(name: str, **params):
    """Build generator `name` into a fresh gmsh session; yields gmsh.model."""
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(name)
        load(name).build(gmsh.model, **params)
        yield gmsh.model
    finally:
        gmsh.finalize()


@dataclass
class Mesh:
    x: np.ndarray                     # (num_nodes, 2), row i = gmsh node tag i + 1
    cell_types: set                   # gmsh element types of all 2D elements
    all_cells: np.ndarray             # tags of all 2D elements
    bodies: dict                      # name -> (element tags, (n, k) node indices)
    facets: dict                      # name -> (m, 2) node indices


def extract(model) -> Mesh:
    tags, coords, _ = model.mesh.getNodes()
    # gmshio reads nodes densely by tag: they must be exactly 1..N.
    assert np.array_equal(np.sort(tags), np.arange(1, len(tags) + 1))
    x = np.empty((len(tags), 2))
    x[tags - 1] = coords.reshape(-1, 3)[:, :2]
    types, elem_tags, _ = model.mesh.getElements(2)
    bodies, facets = {}, {}
    for dim, tag in model.getPhysicalGroups():
        name = model.getPhysicalName(dim, tag)
        assert name and name not in bodies and name not in facets, f"bad/duplicate name {name!r}"
        etags, conns = [], []
        for entity in model.getEntitiesForPhysicalGroup(dim, tag):
            etypes, et, nodes = model.mesh.getElements(dim, entity)
            assert len(etypes) == 1
            nn = model.mesh.getElementProperties(etypes[0])[3]
            etags.append(et[0])
            conns.append(nodes[0].reshape(-1, nn).astype(np.int64) - 1)
        if dim == 2:
            bodies[name] = (np.concatenate(etags), np.concatenate(conns))
        else:
            assert dim == 1, f"unexpected physical group dimension {dim}"
            facets[name] = np.concatenate(conns)
    return Mesh(x, set(types), np.concatenate(elem_tags), bodies, facets)


def signed_areas(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    p, q = x[cells], x[np.roll(cells, -1, axis=1)]
    return 0.5 * np.sum(p[..., 0] * q[..., 1] - q[..., 0] * p[..., 1], axis=1)


def corner_crosses(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """z-component of (next - p) x (prev - p) at every corner; one sign <=> convex cell."""
    p = x[cells]
    a = x[np.roll(cells, -1, axis=1)] - p
    b = x[np.roll(cells, 1, axis=1)] - p
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


# ---- expected facts per generator -------------------------------------------------------
# Arc: (facet group, centre, radius, total angle, +1 if the body lies inside the circle).
SPECS = {
    "block": dict(
        facets={"bottom": "block", "right": "block", "top": "block", "left": "block"},
        area={"block": 1.0}, arcs={}, points=[],
        quads={"block": 16}, edges={"bottom": 4, "right": 4, "top": 4, "left": 4}),
    "patch_test": dict(
        facets={**{f"lower_{s}": "lower" for s in (
            "bottom", "right", "left", "top_left", "top_middle", "top_right")},
            **{f"upper_{s}": "upper" for s in ("bottom", "right", "top", "left")}},
        area={"lower": 8.0, "upper": 2.0}, arcs={},
        points=[((2, 0), "lower"), ((1, 2), "lower"), ((3, 2), "lower"), ((2, 3), "upper")],
        quads={"lower": 128, "upper": 80},
        edges={"lower_bottom": 16, "lower_top_left": 4, "lower_top_middle": 8,
               "lower_top_right": 4, "lower_left": 8, "upper_bottom": 20, "upper_top": 20,
               "upper_left": 4}),
    "hertz": dict(
        facets={"disk_arc": "disk", "disk_top": "disk", "block_top": "block",
                "block_bottom": "block", "block_left": "block", "block_right": "block"},
        area={"disk": math.pi / 2, "block": 2.0},
        arcs={"disk": [("disk_arc", (0.0, 1.0), 1.0, math.pi, +1)]},
        points=[((0, 1), "disk"), ((0, 0.5), "disk"), ((0, 0), "disk"), ((0, 0), "block"),
                ((0, -1), "block")],
        quads=None, edges=None),
    "half_rings": dict(
        facets={"fixed_inner": "fixed_ring", "fixed_outer": "fixed_ring",
                "fixed_ends": "fixed_ring", "moving_outer": "moving_ring",
                "moving_inner": "moving_ring", "moving_ends": "moving_ring"},
        area={"fixed_ring": math.pi / 2 * (12**2 - 10**2),
              "moving_ring": math.pi / 2 * (10**2 - 8**2)},
        arcs={"fixed_ring": [("fixed_outer", (0, 0), 12.0, math.pi, +1),
                             ("fixed_inner", (0, 0), 10.0, math.pi, -1)],
              "moving_ring": [("moving_outer", (0, 0), 10.0, math.pi, +1),
                              ("moving_inner", (0, 0), 8.0, math.pi, -1)]},
        points=[((-12, 0), "fixed_ring"), ((10, 0), "fixed_ring"), ((-10, 0), "moving_ring"),
                ((0, -10), "fixed_ring"), ((0, -10), "moving_ring")],
        quads={"fixed_ring": 128, "moving_ring": 240},
        edges={"fixed_inner": 32, "fixed_outer": 32, "fixed_ends": 8, "moving_outer": 60,
               "moving_inner": 60, "moving_ends": 8}),
    "ironing": dict(
        facets={"substrate_top": "substrate", "substrate_bottom": "substrate",
                "substrate_left": "substrate", "substrate_right": "substrate",
                "tool_arc": "tool", "tool_sides": "tool", "tool_top": "tool"},
        area={"substrate": 48.0, "tool": 2.0 + math.pi / 2},
        arcs={"tool": [("tool_arc", (1.2, 5.02), 1.0, math.pi, +1)]},
        points=[((1.2, 4.02), "tool"), ((0.2, 6.02), "tool"), ((12, 4), "substrate")],
        # tool: 2 side patches 4x4, bottom patch and inner rectangle 10x4, top 18x9
        quads={"substrate": 700, "tool": 2 * 16 + 2 * 40 + 162},
        edges={"substrate_top": 70, "substrate_left": 10, "tool_arc": 18, "tool_top": 18,
               "tool_sides": 18}),
    "block_on_slab": dict(
        facets={**{f"block_{s}": "block" for s in ("bottom", "right", "top", "left")},
                **{f"slab_{s}": "slab" for s in ("bottom", "right", "top", "left")}},
        area={"block": 0.5, "slab": 3.0}, arcs={},
        points=[((0, 1), "block"), ((0, 1), "slab"), ((2, 1), "slab")],
        quads={"block": 50, "slab": 192},
        edges={"block_bottom": 10, "block_left": 5, "slab_top": 24, "slab_left": 8}),
}


def has_node(mesh: Mesh, body: str, point) -> bool:
    nodes = np.unique(mesh.bodies[body][1])
    return bool(np.any(np.all(np.abs(mesh.x[nodes] - point) < 1e-12, axis=1)))


def chord_segments(mesh: Mesh, group: str, centre, radius: float):
    """Angles alpha of the chords on an arc group, after checking nodes lie on the circle."""
    edges = mesh.facets[group]
    r = np.linalg.norm(mesh.x[np.unique(edges)] - centre, axis=1)
    assert np.allclose(r, radius, rtol=0, atol=1e-12 * radius), f"{group}: node off the arc"
    chord = np.linalg.norm(mesh.x[edges[:, 0]] - mesh.x[edges[:, 1]], axis=1)
    return 2.0 * np.arcsin(chord / (2.0 * radius))


@pytest.mark.parametrize("cell", CELLS)
@pytest.mark.parametrize("name", list(SPECS))
def test_generator_facts(name: str, cell: str):
    spec = SPECS[name]
    with built(name, cell=cell) as model:
        mesh = extract(model)
        for etype in mesh.cell_types:
            assert model.mesh.getElementProperties(etype)[2] == 1, "not linear"
    # Cell type, and every cell in exactly one body group.
    assert mesh.cell_types == {GMSH_TYPE[cell]}
    assert set(mesh.bodies) == set(spec["area"])
    in_bodies = np.concatenate([tags for tags, _ in mesh.bodies.values()])
    assert len(in_bodies) == len(np.unique(in_bodies)) == len(mesh.all_cells)
    assert set(in_bodies) == set(mesh.all_cells)
    # Bodies share no node, and every node belongs to a cell (gmshio keeps all nodes).
    node_sets = [set(np.unique(conn)) for _, conn in mesh.bodies.values()]
    assert sum(map(len, node_sets)) == len(set().union(*node_sets)) == len(mesh.x)
    # Named facet groups: exactly the documented ones, disjoint, boundary edges of the
    # right body (each edge lies in exactly one cell of that body).
    assert set(mesh.facets) == set(spec["facets"])
    seen = set()
    for group, body in spec["facets"].items():
        cell_edges = {}
        conn = mesh.bodies[body][1]
        for k in range(conn.shape[1]):
            for e in map(frozenset, np.stack([conn[:, k], np.roll(conn, -1, 1)[:, k]], 1)):
                cell_edges[e] = cell_edges.get(e, 0) + 1
        group_edges = [frozenset(e) for e in mesh.facets[group]]
        assert all(cell_edges.get(e) == 1 for e in group_edges), f"{group}: not boundary"
        assert seen.isdisjoint(group_edges), f"{group} overlaps another group"
        seen.update(group_edges)
    for body, (_, conn) in mesh.bodies.items():
        # Valid cells: one orientation, convex (no inverted or degenerate corner).
        crosses = corner_crosses(mesh.x, conn)
        assert np.all(crosses > 0) or np.all(crosses < 0), f"{body}: bad cell"
        area_h = np.abs(signed_areas(mesh.x, conn)).sum()
        area = spec["area"][body]
        arcs = spec["arcs"].get(body, [])
        if not arcs:
            assert abs(area_h - area) < 1e-12 * max(1.0, area)
            continue
        # A chord of angle alpha cuts a segment R^2 (alpha - sin alpha)/2 off the circle:
        # the polygon loses them on convex arcs and gains them on concave ones (exact), and
        # summed over an arc of angle Theta they are <= R^2 Theta alpha_max^2 / 12
        # (= Theta h^2 / 12 to leading order, h = longest chord).
        exact_gap, bound = 0.0, 0.0
        for group, centre, radius, theta, side in arcs:
            alpha = chord_segments(mesh, group, np.asarray(centre), radius)
            assert abs(alpha.sum() - theta) < 1e-9
            exact_gap += side * 0.5 * radius**2 * np.sum(alpha - np.sin(alpha))
            bound += radius**2 * theta * alpha.max() ** 2 / 12.0
        assert abs(area_h - (area - exact_gap)) < 1e-9 * area
        assert 0 < abs(area_h - area) <= bound
    for point, body in spec["points"]:
        assert has_node(mesh, body, np.asarray(point, float)), f"no node at {point} in {body}"
    per_quad = 1 if cell == "quadrilateral" else 2
    for body, n in (spec["quads"] or {}).items():
        assert len(mesh.bodies[body][0]) == per_quad * n
    for group, n in (spec["edges"] or {}).items():
        assert len(mesh.facets[group]) == n


def test_curved_area_error_decreases_with_refinement():
    def area_errors(name, **params):
        with built(name, **params) as model:
            mesh = extract(model)
        return {b: abs(np.abs(signed_areas(mesh.x, c)).sum() - SPECS[name]["area"][b])
                for b, (_, c) in mesh.bodies.items() if SPECS[name]["arcs"].get(b)}

    coarse = area_errors("half_rings", fixed_nc=16, moving_nc=30)
    fine = area_errors("half_rings", fixed_nc=32, moving_nc=60)
    for body in coarse:   # O(h^2): halving h divides the error by ~4
        assert 3.5 < coarse[body] / fine[body] < 4.5
    coarse = area_errors("ironing", n_arc=12)["tool"]
    fine = area_errors("ironing", n_arc=24)["tool"]
    assert 3.5 < coarse / fine < 4.5
    coarse = area_errors("hertz", h_contact=0.05, h_far=0.2)["disk"]
    fine = area_errors("hertz", h_contact=0.025, h_far=0.1)["disk"]
    assert coarse / fine > 2.5


@pytest.mark.parametrize("cell", CELLS)
def test_hertz_sizes_near_contact(cell: str):
    h_c, h_far = 0.01, 0.1
    with built("hertz", cell=cell, h_contact=h_c, h_far=h_far) as model:
        mesh = extract(model)
    for group in ("disk_arc", "block_top"):
        edges = mesh.facets[group]
        mid_x = mesh.x[edges].mean(axis=1)[:, 0]
        length = np.linalg.norm(mesh.x[edges[:, 0]] - mesh.x[edges[:, 1]], axis=1)
        near = np.abs(mid_x) <= 0.15
        assert near.sum() >= 0.3 / (1.15 * h_c)
        assert np.all(length[near] <= 1.15 * h_c) and np.all(length[near] >= 0.5 * h_c)
        assert length.max() <= 1.15 * h_far


def test_parameters_change_geometry_and_divisions():
    with built("block", cell="triangle", x0=-1.0, y0=2.0, width=3.0, height=0.5,
               nx=3, ny=5) as model:
        mesh = extract(model)
    conn = mesh.bodies["block"][1]
    assert len(conn) == 2 * 15
    assert abs(np.abs(signed_areas(mesh.x, conn)).sum() - 1.5) < 1e-12
    assert np.allclose(mesh.x.min(axis=0), [-1.0, 2.0])
    assert np.allclose(mesh.x.max(axis=0), [2.0, 2.5])
    assert len(mesh.facets["bottom"]) == 3 and len(mesh.facets["left"]) == 5
    with built("patch_test", lower_nx=8, lower_ny=2, upper_nx=6, upper_ny=3) as model:
        mesh = extract(model)
    assert len(mesh.bodies["lower"][0]) == 16 and len(mesh.bodies["upper"][0]) == 18
    assert [len(mesh.facets[g]) for g in ("lower_top_left", "lower_top_middle",
                                          "lower_top_right")] == [2, 4, 2]
    assert has_node(mesh, "upper", np.array([2.0, 3.0]))
    with built("half_rings", fixed_nr=2, fixed_nc=7, moving_nr=3, moving_nc=9) as model:
        mesh = extract(model)
    assert len(mesh.bodies["fixed_ring"][0]) == 14 and len(mesh.bodies["moving_ring"][0]) == 27
    assert len(mesh.facets["moving_outer"]) == 9 and len(mesh.facets["fixed_ends"]) == 4


@pytest.mark.parametrize("name, params, match", [
    ("block", dict(cell="hexahedron"), "hexahedron"),
    ("hertz", dict(cell="quad"), "quad"),
    ("block", dict(nx=0), "nx"),
    ("block", dict(width=-1.0), "width"),
    ("patch_test", dict(lower_nx=18), "lower_nx"),
    ("patch_test", dict(upper_nx=21), "upper_nx"),
    ("half_rings", dict(moving_nc=1), "moving_nc"),
    ("ironing", dict(n_arc=3), "n_arc"),
    ("ironing", dict(nx=2.5), "nx"),
    ("hertz", dict(h_contact=0.2, h_far=0.1), "h_far"),
    ("block_on_slab", dict(slab_ny=0), "slab_ny"),
])
def test_invalid_parameters_raise_value_error(name, params, match):
    with pytest.raises(ValueError, match=match):
        with built(name, **params):
            pass


@pytest.mark.parametrize("name", list(SPECS))
def test_unknown_parameter_raises(name):
    with pytest.raises(TypeError, match="no_such_option"):
        with built(name, no_such_option=1):
            pass


@pytest.mark.parametrize("cell", CELLS)
def test_patch_test_through_dolfinx_gmshio(cell: str):
    from mpi4py import MPI

    from fenicsx_mortar import _dolfinx as dx

    expected_facets = {"lower_bottom": 16, "lower_right": 8, "lower_top_right": 4,
                       "lower_top_middle": 8, "lower_top_left": 4, "lower_left": 8,
                       "upper_bottom": 20, "upper_right": 4, "upper_top": 20,
                       "upper_left": 4}
    per_quad = 1 if cell == "quadrilateral" else 2
    with built("patch_test", cell=cell) as model:
        tags = {model.getPhysicalName(d, t): t for d, t in model.getPhysicalGroups()}
        mesh, ct, ft = dx.model_to_mesh(model, MPI.COMM_WORLD, 0)
    assert mesh.topology.cell_type.name == cell
    assert dx.num_owned_cells(mesh) == per_quad * (128 + 80)
    assert len(ct.find(tags["lower"])) == per_quad * 128
    assert len(ct.find(tags["upper"])) == per_quad * 80
    for group, n in expected_facets.items():
        assert len(ft.find(tags[group])) == n, group
    # The tagged slave facets are the 20 equal pieces of y = 2, x in [1, 3].
    mid = dx.midpoints(mesh, 1, ft.find(tags["upper_bottom"]))
    assert np.allclose(mid[:, 1], 2.0)
    assert np.allclose(np.sort(mid[:, 0]), np.linspace(1.05, 2.95, 20))


@pytest.mark.parametrize("cell", CELLS)
@pytest.mark.parametrize("name", list(SPECS))
def test_every_generator_converts_with_gmshio(name: str, cell: str):
    """Every body cell and group facet survives gmshio with its tag (one tag per facet)."""
    from mpi4py import MPI

    from fenicsx_mortar import _dolfinx as dx

    with built(name, cell=cell) as model:
        tags = {model.getPhysicalName(d, t): t for d, t in model.getPhysicalGroups()}
        ref = extract(model)
        mesh, ct, ft = dx.model_to_mesh(model, MPI.COMM_WORLD, 0)
    assert dx.num_owned_cells(mesh) == len(ref.all_cells)
    for body, (cells, _) in ref.bodies.items():
        assert len(ct.find(tags[body])) == len(cells)
    for group, edges in ref.facets.items():
        assert len(ft.find(tags[group])) == len(edges), group
