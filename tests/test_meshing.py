"""The checks of a mesh file's cells and names (fenicsx_mortar.scene.meshing)."""
import numpy as np
import pytest

from fenicsx_mortar.scene.meshing import _check_areas, _check_names
from fenicsx_mortar.scene import SceneError

SQUARE = np.array([[0, 1, 2, 3]])


def _x(*corners):
    return np.array(corners, dtype=float)


@pytest.mark.parametrize("corners", [
    ((0, 0), (1, 0), (1, 1), (0, 1)),              # anticlockwise
    ((0, 0), (0, 1), (1, 1), (1, 0)),              # clockwise
    ((0, 0), (1, 0), (2, 0), (0, 1)),              # a straight corner (180°)
    ((0, 0), (1, 0), (1, 1e-9), (0, 1e-9)),        # thin
])
def test_valid_quadrilaterals_pass(corners):
    _check_areas(_x(*corners), SQUARE, "m")


@pytest.mark.parametrize("corners", [
    ((0, 0), (2, 0), (0.4, 0.4), (0, 2)),          # reentrant at (0.4, 0.4), area > 0
    ((0, 0), (0, 2), (0.4, 0.4), (2, 0)),          # the same, clockwise
])
def test_a_folded_quadrilateral_is_refused_at_its_corner(corners):
    with pytest.raises(SceneError, match=r"folded cell.*\(0.4, 0.4\)"):
        _check_areas(_x(*corners), SQUARE, "m")


def _msh(tmp_path, names):
    body = "\n".join(names)
    path = tmp_path / "m.msh"
    path.write_text(f"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n{len(names)}\n"
                    f"{body}\n$EndPhysicalNames\n$Nodes\n0\n$EndNodes\n")
    return path


def test_one_name_on_two_curve_groups_is_refused(tmp_path):
    path = _msh(tmp_path, ['1 2 "bottom"', '1 7 "bottom"', '2 1 "block"'])
    with pytest.raises(SceneError, match=r"'bottom' is on two curve groups \(tags 2 and 7\)"):
        _check_names(path.read_bytes(), path)


@pytest.mark.parametrize("names", [
    ['0 1 "corner"', '0 2 "corner"', '2 1 "block"'],     # points: not used by scenes
    ['1 2 "a b"', '1 3 "a \\"b\\""', '2 1 "a b"'],      # spaces, quotes, one per dimension
    ['1 2 "caf\xe9"', '1 3 "caf\xe8"', '2 1 "b"'],       # names that differ in one byte
])
def test_names_that_gmsh_keeps_pass(tmp_path, names):
    path = _msh(tmp_path, names)
    _check_names(path.read_bytes(), path)
