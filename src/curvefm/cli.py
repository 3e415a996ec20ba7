"""The ``curvefm`` command line.

``serve`` and ``worker`` start the service and the queue workers; they, and ``collection export`` (for the
service's agreement report), import ``curvefm.service`` and ``curvefm.workers`` inside the command, so the library
itself never depends on them.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from dataclasses import fields
from pathlib import Path

from curvefm.errors import CurvefmError, InternalError, InvalidInput, disk_full_error
from curvefm.limits import SessionLimits
from curvefm.runtime import limit_blas_threads
from curvefm.spectral import DEFAULT_K


def progress_bar(description: str):
    """A progress callback drawing a tqdm bar on stderr."""
    from tqdm import tqdm

    bar = tqdm(total=1000, desc=description, unit="", bar_format="{desc}: {percentage:3.0f}%|{bar}| {postfix}")

    def report(fraction: float, message: str) -> None:
        bar.n = int(1000 * min(max(fraction, 0.0), 1.0))
        bar.set_postfix_str(message, refresh=True)
        if fraction >= 1.0:
            bar.close()

    return report


def cmd_match(args) -> int:
    from curvefm.geometry import load_mesh
    from curvefm.matching import match, write_outputs
    from curvefm.session import read_curves
    from curvefm.store import Store

    mesh_M, mesh_N = load_mesh(args.source), load_mesh(args.target)
    curves = read_curves(args.curves)
    result = match(
        mesh_M,
        mesh_N,
        curves,
        k=args.k,
        alpha=args.alpha,
        tracer=args.tracer,
        converter=args.refine,
        converter_params=_json_option(args.refine_params, "--refine-params"),
        method=args.method,
        method_params=_json_option(args.method_params, "--method-params"),
        store=Store(args.data) if args.data else None,
        progress=progress_bar("match"),
    )
    for path in write_outputs(result, args.out):
        print(path)
    quality = Path(args.out) / "quality.json"
    quality.write_text(json.dumps(result.summary(), indent=2))
    print(quality)
    if result.kept != "converted":
        print(f"refinement: {result.reason}", file=sys.stderr)
    return 0


def cmd_basis(args) -> int:
    from curvefm.geometry import load_mesh
    from curvefm.store import Store

    mesh = load_mesh(args.mesh)
    store = Store(args.data) if args.data else Store()
    params = _json_option(args.params, "--params")
    basis = store.ensure_basis(mesh, args.k, params=params, progress=progress_bar("basis"))
    print(
        f"{mesh.name}: {basis.k} eigenpairs of {mesh.n_vertices} vertices stored in {store.root} "
        f"(shape {mesh.content_hash})"
    )
    return 0


def _json_option(text: str, option: str) -> dict:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InvalidInput(f"{option} must be a JSON object: {exc}") from None
    if not isinstance(value, dict):
        raise InvalidInput(f"{option} must be a JSON object, got {text!r}")
    return value


class _Collections:
    """What the ``collection`` commands work with on a data directory: the stores, and jobs run in this process
    with durable records (so a service on the same directory shows them; no queue is opened, which would declare
    the service's running jobs lost)."""

    def __init__(self, data: str | None):
        from curvefm.collection import CollectionEditor
        from curvefm.records.collections import Collections
        from curvefm.records.sessions import sessions_of
        from curvefm.session import LiveSessions, SessionEditor
        from curvefm.store import Store
        from curvefm.workers.job_rows import DbJobRecords

        self.store = Store(data) if data else Store()
        records = sessions_of(self.store)
        self.sessions = SessionEditor(records, LiveSessions(self.store, records))
        self.collections = CollectionEditor(Collections(records.db, records), self.sessions)
        self.jobs = DbJobRecords(self.store.root)

    def shape(self, mesh_or_id: str, k: int) -> str:
        """A stored shape id for a mesh file (stored now) or an id, with its basis computed here if missing."""
        from curvefm.geometry import load_mesh

        mesh = self.store.get_mesh(mesh_or_id) if self.store.has_mesh(mesh_or_id) else load_mesh(mesh_or_id)
        self.store.put_mesh(mesh)
        self.store.ensure_basis(mesh, k, progress=progress_bar(f"basis {mesh.name}"))
        return mesh.content_hash

    def job_view(self, job_id: str):
        from curvefm.collection import JobView

        stored = self.jobs.load(job_id)
        if stored is None:
            return JobView("lost", message="no record of the job")
        info = stored.info
        return JobView(info.state, info.progress, info.message, info.error.message if info.error else None, info.result)

    def refine(self, session, converter: str, params: dict) -> str:
        """Run a refinement job here, recorded as the service records its jobs; returns its id."""
        import time
        import uuid

        from curvefm.workers.context import JobContext, embedded_job
        from curvefm.workers.interface import JobFailure, JobInfo
        from curvefm.workers.job_rows import StoredJob
        from curvefm.workers.jobs import refine

        job_id = uuid.uuid4().hex
        kwargs = {
            "data_dir": str(self.store.root),
            "session": session.model_dump(mode="json"),
            "converter": converter,
            "params": params,
        }
        info = JobInfo(job_id, "refine", "started", message="started", created_at=time.time(), owner=session.owner)
        self.jobs.create(StoredJob(info, kwargs, runner="cli"))
        self.sessions.records.add_job(session.id, job_id)
        try:
            with embedded_job(JobContext(job_id, progress_bar(f"refine {session.target[:12]}"))):
                result = refine(**kwargs)
        except CurvefmError as exc:
            self.jobs.update(job_id, state="failed", error=JobFailure.of(exc), ended_at=time.time())
            return job_id
        finished = {"state": "finished", "progress": 1.0, "message": "finished", "ended_at": time.time()}
        self.jobs.update(job_id, result=result, **finished)
        return job_id


def _status_lines(manage: _Collections, collection_id: str) -> list[str]:
    from curvefm.collection import member_status

    record = manage.collections.record(collection_id)
    counts = f"{len(record.curves)} template curves, {len(record.members)} members, {len(record.runs)} runs"
    lines = [f"collection {record.id} '{record.name}': template {record.template}, k={record.k}, {counts}"]
    for member in record.members:
        status = member_status(record, member, manage.sessions.record(member.session), "", manage.job_view)
        run = f", {status.last_run.state} in the newest run" if status.last_run else ""
        lines.append(
            f"  {member.id} {member.shape[:12]} session {member.session}: {status.curves_done}/"
            f"{status.curves_total} template curves, {status.extra_curves} extra{run}"
        )
    return lines


def cmd_collection_create(args) -> int:
    from curvefm.collection import CollectionCreate, TemplateCurveSpec

    manage = _Collections(args.data)
    curves = json.loads(Path(args.curves).read_text())["curves"] if args.curves else []
    request = CollectionCreate(
        name=args.name,
        template=manage.shape(args.template, args.k),
        from_session=args.from_session,
        k=args.k,
        curves=[TemplateCurveSpec.model_validate(c) for c in curves],
        sharing=args.sharing,
    )
    record = manage.collections.create(request, owner=args.owner)
    print("\n".join(_status_lines(manage, record.id)))
    return 0


def cmd_collection_add(args) -> int:
    manage = _Collections(args.data)
    k = manage.collections.record(args.collection).k
    members = manage.collections.add_members(args.collection, [manage.shape(mesh, k) for mesh in args.meshes])
    answers = json.loads(Path(args.curves).read_text())["curves"] if args.curves else []
    for member in members:
        for answer in answers:
            manage.collections.answer(args.collection, member.id, **answer)
    print("\n".join(_status_lines(manage, args.collection)))
    return 0


def cmd_collection_roles(args) -> int:
    from curvefm.errors import NotFound

    manage = _Collections(args.data)
    records, record = manage.collections.records, manage.collections.record(args.collection)
    if args.grant:
        name, role = args.grant
        user = _users(args).require(name)
        previous = records.grant(record.id, user.id, role, None)
        _audit(
            args, "collection.grant", record.id, {"user": name, "user_id": user.id, "role": role, "previous": previous}
        )
    if args.revoke:
        user = _users(args).require(args.revoke)
        previous = records.revoke(record.id, user.id)
        if previous is None:
            raise NotFound(f"user '{args.revoke}' holds no role in collection {record.id}")
        _audit(args, "collection.revoke", record.id, {"user": args.revoke, "user_id": user.id, "role": previous})
    print(f"{record.owner or '(none)':24s} owner      (made it)")
    for grant in records.grants(record.id):
        print(f"{grant.user:24s} {grant.role:10s} (granted by {grant.granted_by or 'the command line'})")
    return 0


def cmd_collection_status(args) -> int:
    print("\n".join(_status_lines(_Collections(args.data), args.collection)))
    return 0


def cmd_collection_export(args) -> int:
    from curvefm import registry
    from curvefm.collection import archive_summary, run_maps, write_npz, write_zip
    from curvefm.service.agreement import archive_agreement
    from curvefm.service.settings import Settings

    settings = Settings.from_env(data_dir=args.data)
    manage = _Collections(args.data)
    _, parsed = registry.load("converter", args.converter, _json_option(args.params, "--params"))
    params = parsed.model_dump()
    run = manage.collections.start_run(
        args.collection,
        args.converter,
        params,
        lambda session: manage.refine(session, args.converter, params),
        args.members,
        args.only_ready,
    )
    record = manage.collections.record(args.collection)
    maps = run_maps(record, run, manage.job_view, manage.store.root / "results")
    # the operator's authority on the data directory: the check members' accuracy too, as for a manager
    agreement = archive_agreement(
        manage.collections, record, settings.agreement_points, settings.agreement_threshold, checks=True
    )
    summary = archive_summary(record, run, maps, agreement)
    (write_zip if args.out.endswith(".zip") else write_npz)(args.out, maps, summary)
    print(f"run {run.id}: {len(maps)} members written to {args.out}")
    return 0


FORMAT_FILES = {
    "mrk": ("source.mrk.json", "target.mrk.json"),
    "fcsv": ("source.fcsv", "target.fcsv"),
    "tps": ("landmarks.tps", "curveslide.csv"),
    "morphologika": ("morphologika.txt", "curveslide.csv"),
}


def _session_editor(data: str | None):
    from curvefm.records.sessions import sessions_of
    from curvefm.session import LiveSessions, SessionEditor
    from curvefm.store import Store

    store = Store(data) if data else Store()
    records = sessions_of(store)
    return SessionEditor(records, LiveSessions(store, records))


def cmd_export(args) -> int:
    from curvefm.morphometrics import live_configuration, write_export

    editor = _session_editor(args.data)
    if args.refinement:
        configuration = _refined_configuration(editor, args)
    else:
        configuration = live_configuration(editor, args.session, args.semilandmarks, args.pseudo)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in dict.fromkeys(n for f in args.format for n in FORMAT_FILES[f]):
        print(write_export(name, configuration, out))
    return 0


def _refined_configuration(editor, args):
    """The landmarks of a finished refinement job of the session, run by the service or ``collection export``."""
    import numpy as np

    from curvefm.morphometrics import refined_configuration
    from curvefm.session import SessionRecord
    from curvefm.store import Store
    from curvefm.workers.job_rows import DbJobRecords

    store = Store(args.data) if args.data else Store()
    stored = DbJobRecords(store.root).load(args.refinement)
    p2p = store.root / "results" / args.refinement / "p2p_source_to_target.npy"
    finished = stored is not None and stored.info.state == "finished" and p2p.is_file()
    if stored is None or not finished or stored.kwargs.get("session", {}).get("id") != args.session:
        raise InvalidInput(f"job {args.refinement} is not a finished refinement of session {args.session}")
    record = SessionRecord.model_validate(stored.kwargs["session"])
    meshes = (editor.live.mesh(record.source, "source"), editor.live.mesh(record.target, "target"))
    return refined_configuration(record, meshes, np.load(p2p), args.semilandmarks, args.pseudo)


def cmd_import_markups(args) -> int:
    from curvefm.morphometrics import Tolerance, check_limits, pair_markups, read_markups, seed_curves

    editor = _session_editor(args.data)
    record = editor.record(args.session)
    meshes = (editor.live.mesh(record.source, "source"), editor.live.mesh(record.target, "target"))
    pairs = pair_markups(
        *(read_markups(Path(path).read_bytes(), Path(path).name) for path in (args.source, args.target))
    )
    seeding = seed_curves(pairs, meshes, Tolerance(args.tolerance, "--tolerance"), args.join_landmarks)
    check_limits(seeding, editor.limits, len(record.curves))
    for point in seeding.points:
        print(
            f"{point.side} {point.markup} '{point.label}': vertex {point.vertex}, {point.distance:.6g} away "
            f"({point.relative_distance:.3g} sqrt(area))"
        )
    for seeded in seeding.curves:
        curve, summary = editor.add_curve(args.session, seeded.spec)
        print(f"curve {curve.id} '{seeded.name}': {len(curve.path_source)} -> {len(curve.path_target)} vertices")
    for what in seeding.unpaired:
        print(f"left out: {what} (in one file only)", file=sys.stderr)
    return 0


def cmd_evaluate(args) -> int:
    from curvefm.evaluation import evaluate_pair
    from curvefm.store import Store

    report = evaluate_pair(
        args.source,
        args.target,
        n_curves=args.curves,
        k=args.k,
        alpha=args.alpha,
        store=Store(args.data) if args.data else None,
        progress=progress_bar("evaluate"),
        method=args.method,
        method_params=_json_option(args.method_params, "--method-params"),
        endpoints_on=args.endpoints_on,
    )
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(
        f"{report['source']} -> {report['target']}  ({report['ground_truth']}, {args.method}, {args.curves} curves, "
        f"k={args.k}; endpoints on the {args.endpoints_on}; scored at {report['scored_at']})"
    )
    for direction, e in report["errors"].items():
        print(
            f"  {direction:17s} mean error {e['mean']:.4f} (by geodesic diameter)  {e['mean_area']:.4f} "
            f"(by sqrt(area))  median {e['median']:.4f}  AUC@0.25 {e['auc']:.3f}  n={e['count']}"
        )
    return 0


def cmd_plugins(args) -> int:
    from curvefm.registry import describe_all

    plugins = describe_all()
    if args.json:
        print(json.dumps(plugins, indent=2))
        return 0
    plural = {"tracer": "tracers", "basis": "bases", "converter": "converters", "method": "map methods"}
    print("Parameters are JSON fields: a curve's tracer_params, match --refine-params, the API's params.")
    for kind, entries in plugins.items():
        print(f"{plural[kind]}:")
        for entry in entries:
            print(f"  {entry['name']}: {entry['description']}")
            for field, schema in entry["parameters"].get("properties", {}).items():
                default = f" (default {schema['default']!r})" if "default" in schema else ""
                print(f"      {field}{default}: {schema.get('description', '')}")
    return 0


def cmd_reproduce(args) -> int:
    from curvefm.evaluation.reproduce import reproduce
    from curvefm.store import Store

    command = "curvefm " + " ".join(sys.argv[1:]) if sys.argv[1:2] == ["reproduce"] else "curvefm reproduce"
    results = reproduce(
        args.out,
        suite=args.suite,
        experiments=tuple(args.experiments),
        report=args.report,
        store=Store(args.data) if args.data else None,
        command=command,
        seeds=args.seeds,
        progress_for=progress_bar,
    )
    for claim in results["claims"]:
        print(f"{claim['verdict']:>14}: {claim['claim']}")
    print(f"report: {results['report']}")
    return 0


def cmd_serve(args) -> int:
    from curvefm.service.app import serve_main
    from curvefm.service.settings import LIMITS

    settings = {name: getattr(args, name) for name in (*SERVE_SETTINGS, *LIMITS)}
    serve_main(args.host, args.port, args.log_level, data_dir=args.data, **settings)
    return 0


def cmd_worker(args) -> int:
    from curvefm.workers.worker import worker_main

    if args.database_url:  # the jobs (in forked work horses) open the records' database by the variable
        os.environ["CURVEFM_DATABASE_URL"] = args.database_url
    if args.memory:
        os.environ["CURVEFM_WORKER_MEMORY"] = args.memory
    worker_main(args.redis_url, args.queues, name=args.name, burst=args.burst)
    return 0


def cmd_users_add(args) -> int:
    from curvefm.store import default_data_dir

    token = _users(args).add(args.name, admin=args.admin)
    _audit(args, "user.add", args.name, {"admin": args.admin})
    folder = Path(args.data or default_data_dir()).resolve()
    if not args.data and not os.environ.get("CURVEFM_DATA"):
        print(
            f"warning: neither --data nor $CURVEFM_DATA is set, so the user went to the default data directory "
            f"{folder}: a server started with another --data or $CURVEFM_DATA does not know it",
            file=sys.stderr,
        )
    role = "admin" if args.admin else "user"
    print(f"added {role} {args.name} to the data directory {folder}; the token is shown only this once")
    print(f"login URL: {args.url.rstrip('/')}/?token={token}")
    print(f"token for {args.name}: {token}")
    return 0


def cmd_users_list(args) -> int:
    users = _users(args).list()
    if args.json:
        print(json.dumps([vars(user) for user in users], indent=2))
        return 0
    if not users:
        print("no users; 'curvefm users add NAME' makes one")
    for user in users:
        print(f"{user.name:24s} {'admin' if user.admin else 'user':5s}  created {user.created_at}")
    return 0


def cmd_users_remove(args) -> int:
    _users(args).remove(args.name)
    _audit(args, "user.remove", args.name)
    print(f"removed user {args.name}; its token no longer works")
    return 0


def cmd_users_admin(args) -> int:
    admin = not args.revoke
    was = _users(args).set_admin(args.name, admin)
    _audit(args, "user.admin", args.name, {"admin": admin, "was": was})
    now = "is an admin" if admin else "is no admin"
    print(f"{args.name} {now} now{' (unchanged)' if was == admin else ''}; it takes effect at their next request")
    return 0


def cmd_users_token(args) -> int:
    if not args.rotate:
        raise InvalidInput(
            "tokens are stored hashed and cannot be shown again; 'curvefm users token NAME --rotate' makes a new "
            "one (the old one stops working)"
        )
    token = _users(args).rotate(args.name)
    _audit(args, "user.rotate", args.name)
    print(f"new token for {args.name}; the old one no longer works")
    print(f"token for {args.name}: {token}")
    return 0


def _users(args):
    from curvefm.access import users_of

    return users_of(args.data)


def _audit(args, action: str, target: str, detail: dict | None = None) -> None:
    from curvefm.access import audit_of

    audit_of(args.data).record("cli", action, target, detail)


def _database(args, upgrade: bool = True):
    from curvefm.records import open_database

    return open_database(args.data, url=args.url, upgrade=upgrade)


def cmd_db_upgrade(args) -> int:
    from curvefm.records import migrate

    database = _database(args, upgrade=False)
    before = migrate.current(database)
    migrate.upgrade(database, args.revision)
    print(f"{database!r}: revision {before or 'none'} -> {migrate.current(database)}")
    return 0


def cmd_db_current(args) -> int:
    from curvefm.records import migrate

    database = _database(args, upgrade=False)
    current, head = migrate.current(database), migrate.head()
    state = "up to date" if current == head else f"behind {head}: run 'curvefm db upgrade'"
    print(f"{database!r}: revision {current or 'none'} ({state})")
    return 0


def cmd_db_import(args) -> int:
    from curvefm.records.legacy_import import import_directory

    database = _database(argparse.Namespace(data=args.data or args.dir, url=args.url))
    report = import_directory(database, args.dir)
    for line in report.lines():
        print(line)
    return 0


def cmd_db_backup(args) -> int:
    from curvefm.records.backup import backup

    database = _database(args)
    print(f"backed up {database!r} to {backup(database, args.file)}")
    return 0


def cmd_db_restore(args) -> int:
    from curvefm.records.backup import restore

    database = _database(args, upgrade=False)
    restore(database, args.file)
    print(f"restored {database!r} from {args.file}; 'curvefm db upgrade' if it is of an older version")
    return 0


DATABASE_URL_HELP = (
    "the records' database, e.g. postgresql+psycopg://user@host/curvefm (default $CURVEFM_DATABASE_URL, else "
    "SQLite in the data directory)"
)
SERVE_SETTINGS = (
    "redis_url",
    "database_url",
    "demo",
    "allowed_hosts",
    "quota_bytes",
    "quota_sessions",
    "quota_jobs",
    "rate_limit",
    "rate_burst",
    "job_ttl_s",
)
"""The ``serve`` options that are service settings besides the request limits (``None``: from the environment)."""


def add_limit_options(s: argparse.ArgumentParser) -> None:
    s.add_argument(
        "--allowed-hosts",
        metavar="HOST[,HOST...]",
        help="Host header values to answer, '*' for any (default $CURVEFM_ALLOWED_HOSTS, else the loopback "
        "names, plus this machine's names and the bound address when --host is not a loopback one)",
    )
    s.add_argument(
        "--quota-bytes",
        type=int,
        help="per user: stored shapes, results and sessions' curves (default $CURVEFM_QUOTA_BYTES or 2 GiB; "
        "0: no limit)",
    )
    s.add_argument("--quota-sessions", type=int, help="per user (default $CURVEFM_QUOTA_SESSIONS or 100; 0: no limit)")
    s.add_argument(
        "--quota-jobs",
        type=int,
        help="per user, queued or running at once (default $CURVEFM_QUOTA_JOBS or 4; 0: no limit)",
    )
    s.add_argument(
        "--rate-limit",
        type=float,
        help="requests per second per token (default $CURVEFM_RATE_LIMIT or 20; 0: no limit)",
    )
    s.add_argument("--rate-burst", type=int, help="requests at once per token (default $CURVEFM_RATE_BURST or 40)")
    s.add_argument(
        "--job-ttl",
        dest="job_ttl_s",
        type=float,
        metavar="SECONDS",
        help="delete ended jobs and their result files this long after they ended (default $CURVEFM_JOB_TTL or 7 days)",
    )


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="curvefm", description=__doc__)
    data = argparse.ArgumentParser(add_help=False)
    data.add_argument("--data", help="data directory for meshes, bases and sessions (default $CURVEFM_DATA)")
    sub = p.add_subparsers(dest="command", required=True)

    m = sub.add_parser("match", parents=[data], help="compute maps between two meshes from corresponding curves")
    m.add_argument("source")
    m.add_argument("target")
    m.add_argument("--curves", required=True, help='JSON: {"curves": [{"source": [i, j], "target": [p, q]}]}')
    m.add_argument("--out", required=True, help="output folder")
    m.add_argument("--k", type=int, default=DEFAULT_K, help="basis size (default %(default)s)")
    m.add_argument("--alpha", type=float, help="commutativity weight (default: the method's own)")
    m.add_argument("--tracer", default="geodesic", help="default curve tracer plugin (default %(default)s)")
    m.add_argument("--refine", default="nearest-neighbor", help="converter plugin for the pointwise maps")
    m.add_argument("--refine-params", default="{}", help="converter parameters as JSON")
    m.add_argument("--method", default="combined", help="map method plugin: combined, curves, obcs12, no17, ...")
    m.add_argument("--method-params", default="{}", help="map method parameters as JSON")
    m.set_defaults(run=cmd_match)

    b = sub.add_parser(
        "basis", parents=[data], help="compute and store a mesh's eigenbasis (match and the service find it)"
    )
    b.add_argument("mesh")
    b.add_argument("--k", type=int, default=DEFAULT_K, help="basis size (default %(default)s)")
    b.add_argument("--params", default="{}", help='laplace-beltrami parameters as JSON, e.g. \'{"method": "exact"}\'')
    b.set_defaults(run=cmd_basis)

    e = sub.add_parser("evaluate", parents=[data], help="score a pair with known ground truth (../shared/data)")
    e.add_argument("source")
    e.add_argument("target")
    e.add_argument("--curves", type=int, default=10, help="number of curves from the ground truth")
    e.add_argument("--k", type=int, default=DEFAULT_K)
    e.add_argument("--alpha", type=float, help="commutativity weight (default: the method's own)")
    e.add_argument("--method", default="combined", help="map method plugin: combined, curves, obcs12, no17, ...")
    e.add_argument("--method-params", default="{}", help="map method parameters as JSON")
    e.add_argument(
        "--endpoints-on",
        choices=("source", "target"),
        default="source",
        help="the shape the curves' endpoints are chosen on (farthest points); their partners come from the truth",
    )
    e.add_argument("--json", action="store_true", help="print the full report as JSON")
    e.set_defaults(run=cmd_evaluate)

    r = sub.add_parser("reproduce", parents=[data], help="rerun the paper's evaluation on ../shared/data")
    r.add_argument("--out", default="reproduce-results", help="folder for JSON tables and plots (default %(default)s)")
    r.add_argument(
        "--suite",
        default="full",
        help="'full' (12 pairs: about 2,400 conversions to the handed-out pointwise maps, hours) or 'ci' (two pairs, "
        "168 conversions: 30-50 min on a loaded 2-core machine, estimated)",
    )
    r.add_argument(
        "--seeds",
        type=int,
        help="seeded curve draws per pair and count (default the suite's: 3 full, 2 ci); fewer is faster",
    )
    r.add_argument("--experiments", nargs="+", default=["accuracy", "timing"], help="accuracy and/or timing")
    r.add_argument("--report", help="Markdown report path (default OUT/results.md)")
    r.set_defaults(run=cmd_reproduce)

    s = sub.add_parser("serve", parents=[data], help="run the HTTP API and web UI (jobs in-process without Redis)")
    s.add_argument("--host", default="127.0.0.1")
    s.add_argument("--port", type=int, default=8000)
    s.add_argument("--redis-url", help="send jobs to RQ on this Redis (default $CURVEFM_REDIS_URL; none: in-process)")
    s.add_argument("--database-url", help=DATABASE_URL_HELP)
    s.add_argument(
        "--demo",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="add two generated shapes and a ready session 'demo'",
    )
    s.add_argument("--max-upload-bytes", type=int, help="largest upload (default $CURVEFM_MAX_UPLOAD_BYTES or 200 MB)")
    s.add_argument("--max-body-bytes", type=int, help="largest other request (default $CURVEFM_MAX_BODY_BYTES or 4 MB)")
    s.add_argument(
        "--max-json-depth", type=int, help="deepest nesting in a JSON body (default $CURVEFM_MAX_JSON_DEPTH or 32)"
    )
    s.add_argument(
        "--max-session-bytes",
        type=int,
        help="most a session's curves may store (default $CURVEFM_MAX_SESSION_BYTES or 4 MiB)",
    )
    for limit in fields(SessionLimits):
        s.add_argument(
            f"--{limit.name.replace('_', '-')}",
            type=int,
            help=f"{limit.metadata['help']} (default $CURVEFM_{limit.name.upper()} or {limit.default})",
        )
    s.add_argument("--max-webhooks", type=int, help="webhooks per collection (default $CURVEFM_MAX_WEBHOOKS or 10)")
    s.add_argument(
        "--max-pseudo-landmarks",
        type=int,
        help="pseudo-landmarks a collection export may ask for (default $CURVEFM_MAX_PSEUDO_LANDMARKS or 10000)",
    )
    s.add_argument(
        "--max-review-comments",
        type=int,
        help="review comments per collection member (default $CURVEFM_MAX_REVIEW_COMMENTS or 200)",
    )
    s.add_argument(
        "--max-comment-chars", type=int, help="longest review comment (default $CURVEFM_MAX_COMMENT_CHARS or 2000)"
    )
    add_limit_options(s)
    s.add_argument("--log-level", default="info")
    s.set_defaults(run=cmd_serve)

    w = sub.add_parser("worker", help="run an RQ worker on the project's queues")
    w.add_argument("--redis-url", help="Redis URL (default $CURVEFM_REDIS_URL)")
    w.add_argument("--database-url", help=DATABASE_URL_HELP)
    w.add_argument("--queues", nargs="+", help="queue names (default: the project's queues)")
    w.add_argument("--name", help="worker name (default: chosen by RQ)")
    w.add_argument(
        "--memory",
        help="memory budget, e.g. 8G: jobs that state more fail as too_large instead of being killed "
        "(default $CURVEFM_WORKER_MEMORY or the memory available at the start)",
    )
    w.add_argument("--burst", action="store_true", help="exit once the queues are empty")
    w.set_defaults(run=cmd_worker)

    u = sub.add_parser("users", help="manage the service's users and their bearer tokens")
    users = u.add_subparsers(dest="users_command", required=True)
    ua = users.add_parser("add", parents=[data], help="create a user and print its token (last word of the output)")
    ua.add_argument("name", help="1 to 64 letters, digits, '_', '.' or '-'")
    ua.add_argument("--admin", action="store_true", help="may see and manage everything")
    ua.add_argument(
        "--url",
        default="http://127.0.0.1:8000",
        help="the service's address, for the login URL printed (default: curvefm serve's, http://127.0.0.1:8000)",
    )
    ua.set_defaults(run=cmd_users_add)
    ul = users.add_parser("list", parents=[data], help="list users (name, admin, created)")
    ul.add_argument("--json", action="store_true")
    ul.set_defaults(run=cmd_users_list)
    ur = users.add_parser("remove", parents=[data], help="delete a user; its token stops working at once")
    ur.add_argument("name")
    ur.set_defaults(run=cmd_users_remove)
    um = users.add_parser(
        "admin", parents=[data], help="make an existing user an admin (one made at a single sign-on too), or not"
    )
    um.add_argument("name")
    um.add_argument("--revoke", action="store_true", help="take the admin role away instead")
    um.set_defaults(run=cmd_users_admin)
    ut = users.add_parser("token", parents=[data], help="replace a user's token (tokens cannot be shown again)")
    ut.add_argument("name")
    ut.add_argument("--rotate", action="store_true", help="make a new token and print it; the old one stops working")
    ut.set_defaults(run=cmd_users_token)

    c = sub.add_parser("collection", help="a template with curves and many member shapes, on the data directory")
    collection = c.add_subparsers(dest="collection_command", required=True)
    cc = collection.add_parser("create", parents=[data], help="a collection on a template (mesh file or shape id)")
    cc.add_argument("template")
    cc.add_argument("--from-session", help="a session on the template whose curves become the template curves")
    cc.add_argument("--curves", help='JSON: {"curves": [{"waypoints": [i, j], "name": "..."}]} on the template')
    cc.add_argument("--name", default="")
    cc.add_argument("--k", type=int, default=DEFAULT_K, help="basis size (default %(default)s)")
    cc.add_argument("--owner", default="", help="the user who owns it (default none: admins only)")
    cc.add_argument("--sharing", default="private", choices=["private", "read", "edit"])
    cc.set_defaults(run=cmd_collection_create)
    ca = collection.add_parser("add", parents=[data], help="add member shapes (mesh files or shape ids)")
    ca.add_argument("collection")
    ca.add_argument("meshes", nargs="+")
    ca.add_argument("--curves", help='JSON: {"curves": [{"template_curve": "t1", "target": [i, j]}]} for each one')
    ca.set_defaults(run=cmd_collection_add)
    cs = collection.add_parser("status", parents=[data], help="members, curves answered, newest run")
    cs.add_argument("collection")
    cs.set_defaults(run=cmd_collection_status)
    cr = collection.add_parser("roles", parents=[data], help="who holds which role; grant one or take one away")
    cr.add_argument("collection")
    cr.add_argument("--grant", nargs=2, metavar=("USER", "ROLE"), help="owner, manager, annotator, reviewer or viewer")
    cr.add_argument("--revoke", metavar="USER", help="take the user's role away")
    cr.set_defaults(run=cmd_collection_roles)
    ce = collection.add_parser("export", parents=[data], help="refine every member here and write the archive")
    ce.add_argument("collection")
    ce.add_argument("--out", required=True, help="archive path: .npz, or .zip for text files")
    ce.add_argument("--converter", default="nearest-neighbor")
    ce.add_argument("--params", default="{}", help="converter parameters as JSON")
    ce.add_argument("--members", nargs="+", help="members to run (default all)")
    ce.add_argument("--only-ready", action="store_true", help="run only those of them that have curves")
    ce.set_defaults(run=cmd_collection_export)

    x = sub.add_parser("export", parents=[data], help="a session's landmarks for morphometrics (Slicer, TPS, ...)")
    x.add_argument("session", help="session id")
    x.add_argument("--format", nargs="+", choices=sorted(FORMAT_FILES), default=["mrk"], help="default mrk")
    x.add_argument("--out", required=True, help="folder for the files (made if missing)")
    x.add_argument("--semilandmarks", type=int, default=20, help="per curve, between its ends (default 20)")
    x.add_argument("--pseudo", type=int, default=0, help="pseudo-landmarks carried by the live map (default 0)")
    x.add_argument("--refinement", metavar="JOB", help="a finished refinement job: its curves and pointwise map")
    x.set_defaults(run=cmd_export)
    im = sub.add_parser("import-markups", parents=[data], help="add a session's curves from Slicer markups")
    im.add_argument("session", help="session id")
    im.add_argument("source", help=".mrk.json or .fcsv on the source shape")
    im.add_argument("target", help=".mrk.json or .fcsv on the target shape")
    im.add_argument("--tolerance", type=float, default=0.05, help="farthest snap, units of sqrt(area) (0.05)")
    im.add_argument("--join-landmarks", action="store_true", help="join consecutive paired landmarks by curves")
    im.set_defaults(run=cmd_import_markups)

    d = sub.add_parser("db", help="the records' database: migrations, import of the old files, backups")
    db = d.add_subparsers(dest="db_command", required=True)
    database = argparse.ArgumentParser(add_help=False, parents=[data])
    database.add_argument(
        "--url", help="database URL (default $CURVEFM_DATABASE_URL, else SQLite in the data directory)"
    )
    du = db.add_parser("upgrade", parents=[database], help="migrate the database to the newest schema")
    du.add_argument("revision", nargs="?", default="head")
    du.set_defaults(run=cmd_db_upgrade)
    db.add_parser("current", parents=[database], help="the schema revision").set_defaults(run=cmd_db_current)
    di = db.add_parser("import", parents=[database], help="import a data directory in the old JSON-file layout")
    di.add_argument("dir", help="the data directory (its files stay as they are)")
    di.set_defaults(run=cmd_db_import)
    dbk = db.add_parser("backup", parents=[database], help="copy a SQLite database to FILE (PostgreSQL: pg_dump)")
    dbk.add_argument("file")
    dbk.set_defaults(run=cmd_db_backup)
    dr = db.add_parser("restore", parents=[database], help="replace a SQLite database by a backup (stop the service)")
    dr.add_argument("file")
    dr.set_defaults(run=cmd_db_restore)

    pl = sub.add_parser("plugins", help="list installed plugins with their parameters")
    pl.add_argument("--json", action="store_true")
    pl.set_defaults(run=cmd_plugins)
    return p


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    limit_blas_threads()
    try:
        return args.run(args)
    except InternalError as exc:
        print(f"curvefm: internal error: {exc.message}", file=sys.stderr)
        return 1
    except CurvefmError as exc:
        print(f"curvefm: error: {exc.message}", file=sys.stderr)
        return 2
    except Exception as exc:
        full = disk_full_error(exc)  # the filesystem's or the database's error: one line, not a traceback
        if full is None:
            raise
        print(f"curvefm: error: {full.message}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
