"""The session domain without HTTP: records on disk, the live cache, the edit operations."""

import contextlib
import json
import sqlite3
import threading
import time
from array import array

import numpy as np
import pytest
from pydantic import ValidationError
from support.shapes import basis_of, ellipsoid

from curvefm import registry
from curvefm.errors import Conflict, NotFound
from curvefm.geometry import check_edge_path
from curvefm.records.sessions import sessions_of
from curvefm.session import (
    CurveRecord,
    CurveSpec,
    LiveSessions,
    MissingBasis,
    SessionBusy,
    SessionCreate,
    SessionEditor,
    SessionRecord,
    UnknownSession,
    UnknownShape,
    build_solver,
    load_pair,
)
from curvefm.session.live import LOCK_STRIPES
from curvefm.store import Store, params_key

K = 20
ENDPOINTS = [(0, 600), (100, 900), (250, 1100), (40, 700)]


@pytest.fixture(scope="module")
def shapes():
    M, N = ellipsoid(), ellipsoid(radii=(1.1, 0.6, 0.55))
    return [(mesh, basis_of(mesh, K)) for mesh in (M, N)]


@pytest.fixture
def store(tmp_path, shapes):
    store = Store(tmp_path / "data")
    params = registry.get("basis", "laplace-beltrami").parse_params({}).model_dump()
    for mesh, basis in shapes:
        store.put_basis(store.put_mesh(mesh), basis, "laplace-beltrami", params)
    return store


def editor_on(store, size=32):
    records = sessions_of(store)
    return SessionEditor(records, LiveSessions(store, records, size))


def new_session(editor, store, **params):
    source, target = store.mesh_ids()
    return editor.create(SessionCreate(source=source, target=target, k=K, **params))


def curve(i):
    a, b = ENDPOINTS[i]
    return CurveSpec(source=[a, b], target=[a, b])


def test_every_edit_is_on_disk_with_the_next_revision_before_it_returns(store):
    editor = editor_on(store)
    session = new_session(editor, store)
    assert session.revision == 0 and editor.records.read(session.id) == session
    ids = [editor.add_curve(session.id, curve(i))[0].id for i in range(3)]
    editor.remove_curve(session.id, "c2")
    added, summary = editor.add_curve(session.id, curve(3))
    editor.replace_curve(session.id, "c1", curve(1).model_copy(update={"weight": 2.0}))
    stored = editor.records.read(session.id)
    assert ids == ["c1", "c2", "c3"] and added.id == "c4"  # removed ids are not handed out again
    assert (summary.revision, stored.revision) == (5, 6)
    assert [c.id for c in stored.curves] == ["c1", "c3", "c4"] and stored.curves[0].spec.weight == 2.0
    C_MN, C_NM, record = editor.maps(session.id)
    assert record == stored
    rebuilt = build_solver(stored, load_pair(store, stored))  # what a worker or a restarted API builds
    np.testing.assert_allclose(rebuilt.C_MN, C_MN, atol=1e-12)
    np.testing.assert_allclose(rebuilt.C_NM, C_NM, atol=1e-12)
    editor.live.close()

    restarted = editor_on(store)
    assert restarted.add_curve(session.id, curve(0))[0].id == "c5"
    assert restarted.records.read(session.id).revision == 7
    restarted.live.close()


@pytest.mark.parametrize("energy", ["curves", "combined"])
def test_the_map_an_edit_changes_is_solved_in_the_background_when_its_texture_is_being_read(store, energy):
    """A session whose texture is read between edits (as the web UI does) has the texture's map (C_MN) solved on a
    background thread after each edit, so the read finds it solved; the reverse map waits for a read that needs it.
    A session only edited (a script) leaves every solve to the reads, if any come."""
    editor = editor_on(store)
    session = new_session(editor, store, energy=energy)
    editor.add_curve(session.id, curve(3))
    editor.add_curve(session.id, curve(0))
    live = editor.live.peek(session.id)
    time.sleep(0.2)
    assert _pending(editor, session.id, live) == {"MN", "NM"}  # nobody has read it: nothing solved yet
    editor.transfer(session.id, "uv")  # the page shows the texture
    edits = [
        lambda: editor.add_curve(session.id, curve(1)),
        lambda: editor.replace_curve(session.id, "c2", curve(2)),
        lambda: editor.remove_curve(session.id, "c3"),
    ]
    for edit in edits:
        edit()
        live, deadline = editor.live.peek(session.id), time.monotonic() + 10
        while "MN" in (pending := _pending(editor, session.id, live)) and time.monotonic() < deadline:
            time.sleep(0.005)
        assert pending == {"NM"}
        assert editor.transfer(session.id, "uv").solve_ms == 0.0  # a prior lands a second after an edit at the soonest
    editor.live.close()


def _pending(editor, session_id, live):
    with editor.live.locked(session_id):
        return live.solver.pending


def test_the_live_cache_is_bounded_and_rebuilds_evicted_sessions_from_disk(store):
    editor = editor_on(store, size=1)
    first, second = new_session(editor, store), new_session(editor, store)
    editor.add_curve(first.id, curve(0))
    editor.add_curve(second.id, curve(1))  # evicts the first
    assert editor.live.peek(first.id) is None
    _, summary = editor.add_curve(first.id, curve(2))
    assert (summary.n_curves, summary.revision) == (2, 2)
    carried = editor.transfer(first.id, "xyz")
    values, revision = carried.rows, carried.revision
    assert values.shape == (store.get_mesh(first.target).n_vertices, 3) and revision == 2
    editor.live.close()


def test_the_lock_table_does_not_grow_with_the_ids_asked_for(store):
    live = LiveSessions(store, sessions_of(store))
    locks = {id(live.lock(f"session-{i}")) for i in range(10_000)}
    assert len(locks) == LOCK_STRIPES
    assert live.lock("abc") is live.lock("abc")
    live.close()


def test_a_session_held_too_long_by_another_thread_is_busy_and_the_edit_changes_nothing(store):
    records = sessions_of(store, lock_timeout_s=0.2)
    editor = SessionEditor(records, LiveSessions(store, records))
    session = new_session(editor, store)
    with editor.live.lock(session.id):  # another request's edit that does not finish
        waiter = threading.Thread(target=lambda: outcome.append(_attempt(editor, session.id)))
        outcome: list = []
        waiter.start()
        waiter.join(timeout=10)
    assert isinstance(outcome[0], SessionBusy) and "CURVEFM_SESSION_LOCK_TIMEOUT" in outcome[0].message
    assert records.read(session.id).curves == []
    assert editor.add_curve(session.id, curve(0))[1].n_curves == 1  # released: editing goes on
    editor.live.close()


def _attempt(editor, session_id):
    try:
        return editor.add_curve(session_id, curve(0))
    except SessionBusy as busy:
        return busy


def test_missing_things_are_named_without_saying_how_to_get_them(store):
    editor = editor_on(store)
    source, target = store.mesh_ids()
    with pytest.raises(MissingBasis) as missing:
        editor.create(SessionCreate(source=source, target=target, k=K + 5))
    assert [need.role for need in missing.value.needs] == ["source", "target"]
    assert isinstance(missing.value, Conflict) and f"k >= {K + 5}" in missing.value.message
    with pytest.raises(UnknownShape, match="no target shape with id 'feed'"):
        editor.create(SessionCreate(source=source, target="feed", k=K))
    for session_id in ("nope", "../sessions/x"):
        with pytest.raises(UnknownSession, match="no session with id"):
            editor.add_curve(session_id, curve(0))
    for error in (missing.value, UnknownShape("feed"), UnknownSession("nope")):
        assert "POST" not in error.message and "GET" not in error.message
    editor.live.close()


def test_an_id_in_use_and_a_curve_that_is_not_there_are_refused(store):
    editor = editor_on(store)
    session = new_session(editor, store)
    with pytest.raises(Conflict, match="already exists"):
        editor.records.create(session)
    with pytest.raises(NotFound, match="no curve 'c7'.*none yet"):
        editor.remove_curve(session.id, "c7")
    editor.live.close()


@pytest.mark.parametrize(("field", "value"), [("k", 0), ("alpha", -1.0), ("alpha", float("inf")), ("samples", 1)])
def test_solver_parameters_are_validated_by_the_request_and_the_record(field, value):
    with pytest.raises(ValidationError, match=field):
        SessionCreate(source="a", target="b", **{field: value})
    fields = {
        "id": "s",
        "source": "a",
        "target": "b",
        "k": 10,
        "alpha": 1.0,
        "samples": 100,
        "tracer": "geodesic",
        "basis_plugin": "laplace-beltrami",
        "basis_params": {},
        "created_at": 0.0,
        "updated_at": 0.0,
    }
    with pytest.raises(ValidationError, match=field):
        SessionRecord(**(fields | {field: value}))


def test_stored_paths_are_int32_in_memory_in_the_database_and_lists_in_a_record_dump(store):
    editor = editor_on(store)
    session = new_session(editor, store)
    added, _ = editor.add_curve(session.id, curve(0))
    assert isinstance(added.path_source, array) and added.path_source.itemsize == 4
    with contextlib.closing(sqlite3.connect(store.root / "curvefm.db")) as conn:
        row = conn.execute("SELECT path_source FROM curves WHERE session_id = ?", (session.id,)).fetchone()
    assert row[0] == added.path_source.tobytes()  # int32, little-endian
    dumped = editor.record(session.id).model_dump_json(indent=1).encode()
    stored = json.loads(dumped)["curves"][0]
    assert stored["path_source"] == added.path_source.tolist() and all(type(v) is int for v in stored["path_target"])
    assert SessionRecord.model_validate_json(dumped).model_dump_json(indent=1).encode() == dumped
    with pytest.raises(ValidationError, match="vertex ids, 0 to"):
        CurveRecord(id="c9", spec=curve(0), tracer="geodesic", path_source=[0, 2**31], path_target=[0, 1])
    editor.live.close()


def test_two_editors_on_one_data_directory_see_each_others_edits(store):
    """Two editors stand for two API processes: each edit starts from the record on disk, a live solver that
    another editor left behind is brought up to date, and curve ids come from the fresh record."""
    first, second = editor_on(store), editor_on(store)
    session = new_session(first, store)
    assert first.add_curve(session.id, curve(0))[0].id == "c1"
    assert second.add_curve(session.id, curve(1))[0].id == "c2"
    C_MN, _, record = first.maps(session.id)  # the first editor's solver still held one curve
    assert [c.id for c in record.curves] == ["c1", "c2"] and record.revision == 2
    rebuilt = build_solver(record, load_pair(store, record))
    np.testing.assert_allclose(C_MN, rebuilt.C_MN, atol=1e-10)
    second.replace_curve(session.id, "c1", curve(2))
    first.remove_curve(session.id, "c2")
    assert first.add_curve(session.id, curve(3))[0].id == "c3"
    C_MN, C_NM, record = second.maps(session.id)
    assert [c.id for c in record.curves] == ["c1", "c3"] and record.revision == 5
    assert record.curves[0].spec == curve(2)
    rebuilt = build_solver(record, load_pair(store, record))
    np.testing.assert_allclose(C_MN, rebuilt.C_MN, atol=1e-10)
    np.testing.assert_allclose(C_NM, rebuilt.C_NM, atol=1e-10)
    first.live.close()
    second.live.close()


def test_concurrent_adds_through_two_editors_are_all_kept(store):
    editors = [editor_on(store), editor_on(store)]
    session = new_session(editors[0], store)
    acknowledged = []

    def add(worker: int) -> None:
        for i in range(6):
            added, summary = editors[(worker + i) % 2].add_curve(session.id, curve((worker + i) % len(ENDPOINTS)))
            acknowledged.append((added.id, summary.revision))

    threads = [threading.Thread(target=add, args=(worker,)) for worker in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    stored = editors[0].records.read(session.id)
    ids = [c.id for c in stored.curves]
    assert sorted(ids) == sorted(curve_id for curve_id, _ in acknowledged) and len(set(ids)) == 24
    assert sorted(revision for _, revision in acknowledged) == list(range(1, 25)) and stored.revision == 24
    for editor in editors:
        editor.live.close()


def test_bases_stored_before_the_method_parameter_are_found_and_explicit_methods_are_filed_apart(tmp_path, shapes):
    store = Store(tmp_path / "data")
    (mesh, basis), _ = shapes
    mesh_hash = store.put_mesh(mesh)
    legacy = store.root / "bases" / mesh_hash / f"laplace-beltrami-k{K}-{params_key({'laplacian': 'cotangent'})}.npz"
    legacy.parent.mkdir(parents=True)
    legacy.write_bytes(basis.to_bytes())  # as an earlier version filed it
    assert store.has_basis(mesh_hash, K) and store.has_basis(mesh_hash, K, params={"method": "auto"})
    np.testing.assert_array_equal(store.find_basis(mesh_hash, K).evals, basis.evals)
    assert not store.has_basis(mesh_hash, K, params={"method": "exact"})  # asked for by name: computed as asked
    store.put_basis(mesh_hash, basis, "laplace-beltrami", {"method": "exact"})
    assert store.has_basis(mesh_hash, K, params={"method": "exact"})
    assert not store.has_basis(mesh_hash, K, params={"method": "multires"})


def test_an_edit_on_shapes_with_stored_display_copies_traces_near_them_a_path_of_the_whole_mesh(store, shapes):
    records = sessions_of(store)
    editor = SessionEditor(records, LiveSessions(store, records, display_vertices=400, guided_trace_vertices=0))
    for mesh, _ in shapes:
        store.ensure_display(mesh, 400)
    session = new_session(editor, store)
    added, _ = editor.add_curve(session.id, curve(1))
    with editor.live.using(session.id) as live:
        assert editor.live.guide(session.source) is not None and editor.live.guide(session.target) is not None
        for mesh, path in ((live.pair.mesh_M, added.path_source), (live.pair.mesh_N, added.path_target)):
            internal = mesh.internal_ids(path)
            assert list(internal[[0, -1]]) == list(mesh.internal_ids(ENDPOINTS[1]))
            check_edge_path(mesh.edge_graph, internal)
