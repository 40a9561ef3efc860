"""Which faces of a mesh meet (raymitsuba/geometry/topology.py), and the neighbours the
tessellations declare (raymitsuba/geometry/tessellation.py): checked against the meshes'
own construction -- faces that share an edge share its two corners' positions."""

import numpy as np
import pytest

from raymitsuba.geometry import tessellation, topology
from raymitsuba.geometry.topology import NONE, face_neighbours

# a unit square of two triangles, (0 1 2) and (0 2 3): they share the diagonal 0-2
SQUARE = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
SQUARE_FACES = np.array([[0, 1, 2], [0, 2, 3]])


def test_two_triangles_of_a_square_meet_along_its_diagonal():
    # edge 2 of face 0 runs 2 -> 0, edge 0 of face 1 runs 0 -> 2; the others are the border
    assert face_neighbours(SQUARE_FACES, SQUARE).tolist() == [[NONE, NONE, 1], [0, NONE, NONE]]


def test_faces_meet_by_their_corners_positions_not_their_vertex_indices():
    # every face its own three vertices (as the tessellations have them), -0.0 against 0.0
    positions = SQUARE[SQUARE_FACES].reshape(-1, 3)
    positions[3] = [-0.0, 0.0, -0.0]
    faces = np.arange(6).reshape(2, 3)
    assert face_neighbours(faces, positions).tolist() == [[NONE, NONE, 1], [0, NONE, NONE]]


def test_an_edge_of_three_faces_has_no_neighbour():
    # a third triangle on the diagonal, standing up out of the square's plane
    positions = np.vstack([SQUARE, [[0.5, 0.5, 1.0]]])
    faces = np.vstack([SQUARE_FACES, [[2, 0, 4]]])
    assert face_neighbours(faces, positions).tolist() == [[NONE] * 3] * 3


def shared_corners(mesh, face, edge, other):
    """The corners of ``face``'s edge ``edge`` and the nearest corners of face ``other``."""
    corners = mesh.positions[mesh.faces]
    ends = corners[face, [edge, (edge + 1) % 3]]
    gap = np.linalg.norm(ends[:, None, :] - corners[other][None, :, :], axis=-1)
    return gap.min(axis=1)


@pytest.mark.parametrize("kind", ["sphere", "cylinder", "cone"])
@pytest.mark.parametrize("segments", [8, 31, 48])
def test_a_templates_faces_meet_all_round_as_a_closed_surface(kind, segments):
    """Every edge of a closed primitive has one neighbour, the relation is symmetric, and
    the neighbour has the edge's two corners (up to the faces' growth against cracks,
    OVERLAP of their size: the template's faces are grown apart after they are matched)."""
    mesh = tessellation.template(kind, segments)
    across = mesh.neighbours
    assert across.shape == mesh.faces.shape and (across != NONE).all()
    faces = np.repeat(np.arange(len(across)), 3)
    assert (across[across.ravel()] == faces[:, None]).any(axis=1).all()
    size = np.ptp(mesh.positions, axis=0).max()
    for face in range(0, len(across), max(len(across) // 40, 1)):
        for edge in range(3):
            gap = shared_corners(mesh, face, edge, across[face, edge])
            assert gap.max() < 4 * tessellation.OVERLAP * size


def test_placed_copies_keep_their_neighbours_mirrored_or_not():
    """Two copies of a cylinder, the second mirrored (its winding reversed, so its edges run
    the other way round): each face's neighbour across each edge is in its own copy and has
    that edge's corners."""
    template = tessellation.template("cylinder", 12)
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0])
    mirror[0, 3] = 5.0
    mesh = tessellation.merged([(template, np.stack([np.eye(4), mirror]))])
    count = len(template.faces)
    across = mesh.neighbours
    assert (across[:count] < count).all() and (across[count:] >= count).all()
    for face in (3, count + 3, count + len(template.faces) - 1):
        for edge in range(3):
            assert shared_corners(mesh, face, edge, across[face, edge]).max() < 1e-3
