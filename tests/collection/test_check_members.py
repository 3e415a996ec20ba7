"""Check members' ground truth (curvefm.collection.checks) on small meshes whose answers are known: the file
formats read alike, a truth is checked against both meshes (vertices no face uses included), and an annotation is
scored away from the curve ends it gave."""

from __future__ import annotations

import io
import re

import numpy as np
import pytest
from support.shapes import ellipsoid

from curvefm.collection import Annotated, accuracy, accuracy_by_annotator, checked_truth, read_truth, truth_pairs
from curvefm.errors import InvalidInput
from curvefm.geometry import build_mesh, pair_geodesic_distances


def with_loose_vertex(mesh):
    """The mesh with one more file vertex, last, that no face uses."""
    return build_mesh(np.vstack([mesh.vertices, [[9.0, 9.0, 9.0]]]), mesh.faces)


def test_text_vts_and_npy_files_read_alike():
    ids = np.array([3, 0, -1, 2])
    npy = io.BytesIO()
    np.save(npy, ids.astype(np.int32))
    assert read_truth(b"3\n0\n-1\n2\n", "t.txt").tolist() == ids.tolist()
    assert read_truth(b"3 7\n0 7\n-1 7\n2 7\n", "t.txt").tolist() == ids.tolist()  # the first column
    assert read_truth(npy.getvalue(), "t.bin").tolist() == ids.tolist()  # .npy by its magic, whatever the name
    assert read_truth(b"4\n1\n3\n", "T.VTS").tolist() == [3, 0, 2]  # 1-based, as the shared data's
    with pytest.raises(InvalidInput, match="1-based"):
        read_truth(b"4\n0\n", "t.vts")


def test_a_truth_is_checked_against_both_meshes():
    template, member = with_loose_vertex(ellipsoid(6, 12)), with_loose_vertex(ellipsoid(6, 12, scale=2))
    rows, loose = template.n_file_vertices, member.n_file_vertices - 1
    identity = np.arange(rows)
    identity[-1] = -1  # the template's loose vertex has no partner
    assert checked_truth(identity, template, member) is identity
    for ids, words in (
        (identity[:-1], f"needs one per template vertex ({rows})"),
        (np.r_[identity[:-1], member.n_file_vertices], "out of range"),
        (np.r_[-2, identity[1:]], "row 0"),
        (np.r_[loose, identity[1:]], "belongs to no face"),
        (np.full(rows, -1), "no partner"),
    ):
        with pytest.raises(InvalidInput, match=re.escape(words)):
            checked_truth(ids, template, member)
    only_loose = np.full(rows, -1)
    only_loose[-1] = 0  # a partner for the template vertex no face uses: nothing to score
    with pytest.raises(InvalidInput, match="no partner"):
        checked_truth(only_loose, template, member)
    pairs = truth_pairs(identity, template, member)
    assert len(pairs) == rows - 1 and (pairs.ids_X == pairs.ids_Y).all()


def test_an_annotation_is_scored_away_from_its_curve_ends():
    template, member = ellipsoid(8, 16), ellipsoid(8, 16, scale=2)
    truth = truth_pairs(np.arange(template.n_vertices), template, member)
    rows = np.arange(0, template.n_vertices, 2)
    exact = Annotated("ann", "s1", rows.copy(), {"t1": (0, 40)})
    shifted = Annotated("abe", "s2", rows + 1, {"t1": (2, 40)})
    ends = {"t1": (0, 40), "t2": (10, 12)}  # t2 answered by no one: its ends are scored

    right = accuracy(exact, rows, truth, ends, member)
    assert right.error == 0 and right.scored == rows.size - 2  # vertices 0 and 40 are t1's ends
    off = accuracy(shifted, rows, truth, ends, member)
    kept = ~np.isin(rows, [0, 40, 2])  # abe's start is 2 on the member: its true partner, 2, is left out too
    expected = pair_geodesic_distances(member, rows[kept] + 1, rows[kept]).mean() / np.sqrt(member.area)
    assert np.isclose(off.error, expected) and off.scored == kept.sum() and off.unreachable == 0

    per = accuracy_by_annotator([("m1", right), ("m1", off), ("m2", off)])
    assert [(a.annotator, a.members) for a in per] == [("abe", 2), ("ann", 1)]
    assert np.isclose(per[0].error, off.error) and per[1].error == 0
