"""The side of a curve (:func:`curvefm.geometry.curve_side`) on a real mesh: it changes sign in the mirror image,
does not depend on how the file winds its triangles, and puts a person's arms on opposite sides of a curve from
the head to a foot."""

from dataclasses import replace

import numpy as np
import pytest

from curvefm.geometry import curve_side, farthest_point_sampling, load_mesh, shortest_path


@pytest.fixture(scope="module")
def person(shared_data):
    mesh = load_mesh(shared_data / "faust/tr_reg_000.off")
    head, foot = farthest_point_sampling(mesh, 2)  # vertex 0 (the head) and the farthest from it (a foot)
    return mesh, shortest_path(mesh.edge_graph, int(head), int(foot))


def test_the_mirror_image_has_the_opposite_side(person):
    mesh, path = person
    flipped = mesh.vertices * np.array([-1.0, 1.0, 1.0])
    mirrored = replace(mesh, vertices=flipped, faces=mesh.faces[:, ::-1].copy())  # its normals still point out
    side = curve_side(mesh, path)
    np.testing.assert_allclose(curve_side(mirrored, path), -side, atol=1e-12)
    assert np.mean(side > 0) > 0.3 and np.mean(side < 0) > 0.3  # both sides hold much of the surface


def test_the_winding_of_the_file_does_not_matter(person):
    mesh, path = person
    np.testing.assert_allclose(
        curve_side(replace(mesh, faces=mesh.faces[:, ::-1].copy()), path), curve_side(mesh, path)
    )


def test_the_arms_lie_on_opposite_sides_of_a_curve_from_the_head_to_a_foot(person):
    mesh, path = person
    side = curve_side(mesh, path)
    x, y = mesh.vertices[:, 0], mesh.vertices[:, 1]
    hands = y < np.quantile(y, 0.5)  # FAUST 000 stands with its arms down: its hands are beside the hips
    left_hand = hands & (x > np.quantile(x, 0.97))
    right_hand = hands & (x < np.quantile(x, 0.03))
    assert left_hand.any() and right_hand.any()
    assert np.sign(np.median(side[left_hand])) == -np.sign(np.median(side[right_hand])) != 0
