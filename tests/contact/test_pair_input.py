"""What a DOLFINx user can hand to ContactPair and ContactProblem wrongly: each refused
with a ValueError naming the argument, before anything is solved (hostile sweep 4: a
P2 space or cell tags gave a numpy broadcast error, a pair on another mesh converged to a
wrong answer, ε < 0 carried forces across open gaps, μ < 0 pushed)."""
import pytest

from conftest import ROOT
from fenicsx_mortar import _dolfinx as dx
from fenicsx_mortar import load_scene
from fenicsx_mortar.contact.pair import ContactPair
from fenicsx_mortar.scene.meshing import build_domain
from fenicsx_mortar.problem import ContactProblem


@pytest.fixture(scope="module")
def block_on_slab():
    dom = build_domain(load_scene(ROOT / "tests/bad_input/_base.toml"))
    tags = (dom.facet_groups["block_bottom"], dom.facet_groups["slab_top"])
    return dom, dx.vector_space(dom.mesh), tags


def pair(setup, V=None, facet_tags=None, **kw):
    dom, V0, (slave, master) = setup
    return ContactPair(V or V0, dom.facet_tags if facet_tags is None else facet_tags,
                       slave, master, **({"E": 1000.0} | kw))


@pytest.mark.parametrize("element", [("Lagrange", 2, (2,)), ("Lagrange", 1)])
def test_the_space_must_be_p1_vectors(block_on_slab, element):
    V = dx.api.functionspace(block_on_slab[0].mesh, element)
    with pytest.raises(ValueError, match="P1 vector space"):
        pair(block_on_slab, V=V)


def test_facet_tags_must_be_facets(block_on_slab):
    with pytest.raises(ValueError, match="facet_tags are meshtags of dimension 2"):
        pair(block_on_slab, facet_tags=block_on_slab[0].cell_tags)


@pytest.mark.parametrize("kw, key", [
    ({"enforcement": "penalty", "epsilon": -1e4}, "epsilon"),
    ({"enforcement": "penalty", "epsilon": 0.0}, "epsilon"),
    ({"epsilon": float("nan")}, "epsilon"),
    ({"friction": "coulomb", "mu": -0.3}, "mu"),
    ({"n_gauss": 0}, "n_gauss"),
    ({"n_gauss": float("inf")}, "n_gauss"),
    ({"enforcement": "penalty", "epsilon": "stiff"}, "epsilon"),
    ({"search_radius": -1.0}, "search_radius"),
    ({"tolerance": -1.0}, "tolerance"),
    ({"E": 0.0}, "E"),
    ({"E": float("nan")}, "E"),
    ({"E": {1: 1000.0, 2: 1000.0}}, "cell_tags"),
])
def test_numbers_out_of_range_are_refused_by_name(block_on_slab, kw, key):
    with pytest.raises(ValueError, match=key):
        pair(block_on_slab, **kw)


def test_a_mapping_of_E_must_cover_both_bodies(block_on_slab):
    dom = block_on_slab[0]
    with pytest.raises(ValueError, match="no value for the cell tag"):
        pair(block_on_slab, E={99: 1000.0}, cell_tags=dom.cell_tags)


def test_the_problem_refuses_a_pair_twice_and_a_pair_of_another_mesh(block_on_slab):
    import ufl
    dom, V, _ = block_on_slab
    u = dx.Function(V)
    F = ufl.inner(ufl.grad(u), ufl.grad(ufl.TestFunction(V))) * ufl.dx
    p = pair(block_on_slab)
    with pytest.raises(ValueError, match="given twice"):
        ContactProblem(F, u, [], [p, p])
    other = build_domain(load_scene(ROOT / "tests/bad_input/_base.toml"))
    V2 = dx.vector_space(other.mesh)
    tags = (other.facet_groups["block_bottom"], other.facet_groups["slab_top"])
    q = ContactPair(V2, other.facet_tags, *tags, E=1000.0)
    with pytest.raises(ValueError, match="another mesh"):
        ContactProblem(F, u, [], [q])


def test_the_problem_refuses_a_displacement_of_another_space(block_on_slab):
    import ufl
    dom, _, _ = block_on_slab
    V2 = dx.api.functionspace(dom.mesh, ("Lagrange", 2, (2,)))
    u = dx.Function(V2)
    F = ufl.inner(ufl.grad(u), ufl.grad(ufl.TestFunction(V2))) * ufl.dx
    with pytest.raises(ValueError, match="u: contact needs the displacement in the P1"):
        ContactProblem(F, u, [], [pair(block_on_slab)])
