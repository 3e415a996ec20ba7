"""Agreement between two annotators' answers on a member (curvefm.collection.agreement), on small meshes whose
distances are known: the same answer agrees exactly, answers on the two components of a member are counted
unreachable instead of giving an infinite mean."""

from __future__ import annotations

import numpy as np
from support.shapes import ellipsoid

from curvefm.collection import Annotated, agreement, by_annotator
from curvefm.geometry import build_mesh, pair_geodesic_distances


def test_the_same_answer_agrees_and_a_moved_one_measures_its_distance():
    member = ellipsoid(8, 16)
    p2p = np.arange(0, 100, 3)
    a = Annotated("ann", "s1", p2p, {"t1": (0, 60), "t2": (5, 7)})
    same = agreement(a, Annotated("abe", "s2", p2p.copy(), {"t1": (0, 60)}), member)
    assert same.map_distance == 0 and same.unreachable == 0
    assert [(c.template_curve, c.start, c.end) for c in same.curves] == [("t1", 0.0, 0.0)]  # t2: only ann's

    moved = agreement(a, Annotated("abe", "s2", p2p + 1, {"t1": (1, 60), "t2": (5, 9)}), member)
    scale = np.sqrt(member.area)
    expected = pair_geodesic_distances(member, p2p, p2p + 1).mean() / scale
    assert np.isclose(moved.map_distance, expected) and moved.map_distance > 0
    start = pair_geodesic_distances(member, [0], [1])[0] / scale
    assert np.isclose(moved.curves[0].start, start) and moved.curves[0].end == 0
    assert np.isclose(moved.endpoint_distance, np.mean([c for x in moved.curves for c in (x.start, x.end)]))


def test_images_on_different_components_are_counted_not_averaged():
    one = ellipsoid(6, 12)
    vertices, faces = one.vertices, one.faces
    twice = build_mesh(np.vstack([vertices, vertices + [5.0, 0, 0]]), np.vstack([faces, faces + len(vertices)]))
    a = Annotated("ann", "s1", np.array([0, 1, 2]), {"t1": (0, 1)})
    b = Annotated("abe", "s2", np.array([0, 1 + len(vertices), 3]), {"t1": (len(vertices), 1)})
    result = agreement(a, b, twice)
    assert result.unreachable == 1 and result.map_distance is not None and result.map_distance > 0
    assert result.curves[0].start is None and result.curves[0].end == 0
    assert result.endpoint_distance == 0


def test_the_annotator_who_disagrees_with_everyone_stands_out():
    member = ellipsoid(8, 16)
    p2p = np.arange(0, 100, 3)
    ann, abe = Annotated("ann", "s1", p2p, {}), Annotated("abe", "s2", p2p.copy(), {})
    odd, nobody = Annotated("odd", "s3", p2p + 5, {}), Annotated(None, "s4", p2p.copy(), {})
    pairs = [("m1", agreement(x, y, member)) for x, y in ((ann, abe), (ann, odd), (abe, odd))]
    pairs += [("m2", agreement(ann, odd, member)), ("m2", agreement(nobody, odd, member))]
    figures = {a.annotator: a for a in by_annotator(pairs)}
    assert list(figures) == ["abe", "ann", "odd"]  # by name; an unassigned annotation is no one's
    assert (figures["ann"].members, figures["abe"].members, figures["odd"].members) == (2, 1, 2)
    far = pairs[1][1].map_distance
    assert figures["odd"].map_distance == far and far > 0
    assert np.isclose(figures["ann"].map_distance, 2 * far / 3) and np.isclose(figures["abe"].map_distance, far / 2)
    assert figures["odd"].endpoint_distance is None  # no curves compared
