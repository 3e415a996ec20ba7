"""The ``curvefm`` command line.

``serve`` and ``worker`` start the service and the queue workers; they import ``curvefm.service`` and
``curvefm.workers`` inside the command, so the library itself never depends on them.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import fields
from pathlib import Path

from curvefm.errors import CurvefmError, InternalError, InvalidInput
from curvefm.fmap import DEFAULT_K
from curvefm.runtime import limit_blas_threads
from curvefm.session import SessionLimits


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
        mesh_M, mesh_N, curves, k=args.k, alpha=args.alpha, tracer=args.tracer,
        converter=args.refine, converter_params=_json_option(args.refine_params, "--refine-params"),
        method=args.method, method_params=_json_option(args.method_params, "--method-params"),
        store=Store(args.data) if args.data else None, progress=progress_bar("match"),
    )
    for path in write_outputs(result, args.out):
        print(path)
    quality = Path(args.out) / "quality.json"
    quality.write_text(json.dumps(result.summary(), indent=2))
    print(quality)
    if result.kept != "converted":
        print(f"kept the {result.kept} maps: {result.reason}", file=sys.stderr)
    return 0


def cmd_basis(args) -> int:
    from curvefm.geometry import load_mesh
    from curvefm.store import Store

    mesh = load_mesh(args.mesh)
    store = Store(args.data) if args.data else Store()
    params = _json_option(args.params, "--params")
    basis = store.ensure_basis(mesh, args.k, params=params, progress=progress_bar("basis"))
    print(f"{mesh.name}: {basis.k} eigenpairs of {mesh.n_vertices} vertices stored in {store.root} "
          f"(shape {mesh.content_hash})")  # fmt: skip
    return 0


def _json_option(text: str, option: str) -> dict:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InvalidInput(f"{option} must be a JSON object: {exc}") from None
    if not isinstance(value, dict):
        raise InvalidInput(f"{option} must be a JSON object, got {text!r}")
    return value


def cmd_evaluate(args) -> int:
    from curvefm.evaluation import evaluate_pair
    from curvefm.store import Store

    report = evaluate_pair(
        args.source, args.target, n_curves=args.curves, k=args.k, alpha=args.alpha,
        store=Store(args.data) if args.data else None, progress=progress_bar("evaluate"),
        method=args.method, method_params=_json_option(args.method_params, "--method-params"),
    )
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(
        f"{report['source']} -> {report['target']}  ({report['ground_truth']}, {args.method}, {args.curves} curves, "
        f"k={args.k})"
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
        args.out, suite=args.suite, experiments=tuple(args.experiments), report=args.report,
        store=Store(args.data) if args.data else None, command=command, progress_for=progress_bar,
    )
    for claim in results["claims"]:
        print(f"{claim['verdict']:>14}: {claim['claim']}")
    print(f"report: {results['report']}")
    return 0


def cmd_serve(args) -> int:
    from curvefm.service.app import serve_main
    from curvefm.service.settings import LIMITS, parsed_setting

    settings = {name: getattr(args, name) for name in (*SERVE_SETTINGS, *LIMITS)}
    if args.allowed_hosts is not None:
        settings["allowed_hosts"] = parsed_setting("allowed_hosts", args.allowed_hosts, "--allowed-hosts")
    serve_main(args.host, args.port, args.log_level, data_dir=args.data, **settings)
    return 0


def cmd_worker(args) -> int:
    from curvefm.workers.worker import worker_main

    worker_main(args.redis_url, args.queues, name=args.name, burst=args.burst)
    return 0


def cmd_users_add(args) -> int:
    token = _users(args).add(args.name, admin=args.admin)
    _audit(args, "user.add", args.name, {"admin": args.admin})
    print(f"added {'admin' if args.admin else 'user'} {args.name}; the token is shown only this once")
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
    from curvefm.access import UserStore

    return UserStore(args.data)


def _audit(args, action: str, target: str, detail: dict | None = None) -> None:
    from curvefm.access import AuditLog

    AuditLog(args.data).record("cli", action, target, detail)


SERVE_SETTINGS = (
    "redis_url", "demo", "allowed_hosts", "quota_bytes", "quota_sessions", "quota_jobs", "rate_limit", "rate_burst",
    "job_ttl_s",
)
"""The ``serve`` options that are service settings besides the request limits (``None``: from the environment)."""


def add_limit_options(s: argparse.ArgumentParser) -> None:
    s.add_argument("--allowed-hosts", metavar="HOST[,HOST...]",
                   help="Host header values to answer, '*' for any (default $CURVEFM_ALLOWED_HOSTS, else the loopback "
                        "names, plus this machine's names and the bound address when --host is not a loopback one)")
    s.add_argument("--quota-bytes", type=int, help="per user: stored shapes and results (default $CURVEFM_QUOTA_BYTES "
                                                   "or 2 GiB; 0: no limit)")
    s.add_argument("--quota-sessions", type=int, help="per user (default $CURVEFM_QUOTA_SESSIONS or 100; 0: no limit)")
    s.add_argument("--quota-jobs", type=int, help="per user, queued or running at once (default $CURVEFM_QUOTA_JOBS "
                                                  "or 4; 0: no limit)")
    s.add_argument("--rate-limit", type=float, help="requests per second per token (default $CURVEFM_RATE_LIMIT or "
                                                    "20; 0: no limit)")
    s.add_argument("--rate-burst", type=int, help="requests at once per token (default $CURVEFM_RATE_BURST or 40)")
    s.add_argument("--job-ttl", dest="job_ttl_s", type=float, metavar="SECONDS",
                   help="delete ended jobs and their result files this long after they ended (default "
                        "$CURVEFM_JOB_TTL or 7 days)")


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

    b = sub.add_parser("basis", parents=[data], help="compute and store a mesh's eigenbasis (match and the service "
                                                     "find it)")  # fmt: skip
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
    e.add_argument("--json", action="store_true", help="print the full report as JSON")
    e.set_defaults(run=cmd_evaluate)

    r = sub.add_parser("reproduce", parents=[data], help="rerun the paper's evaluation on ../shared/data")
    r.add_argument("--out", default="reproduce-results", help="folder for JSON tables and plots (default %(default)s)")
    r.add_argument("--suite", default="full", help="'full' (about 15 min) or 'ci' (two pairs, about 1 min)")
    r.add_argument("--experiments", nargs="+", default=["accuracy", "timing"], help="accuracy and/or timing")
    r.add_argument("--report", help="Markdown report path (default OUT/results.md)")
    r.set_defaults(run=cmd_reproduce)

    s = sub.add_parser("serve", parents=[data], help="run the HTTP API and web UI (jobs in-process without Redis)")
    s.add_argument("--host", default="127.0.0.1")
    s.add_argument("--port", type=int, default=8000)
    s.add_argument("--redis-url", help="send jobs to RQ on this Redis (default $CURVEFM_REDIS_URL; none: in-process)")
    s.add_argument("--demo", action=argparse.BooleanOptionalAction, default=False,
                   help="add two generated shapes and a ready session 'demo'")
    s.add_argument("--max-upload-bytes", type=int, help="largest upload (default $CURVEFM_MAX_UPLOAD_BYTES or 200 MB)")
    s.add_argument("--max-body-bytes", type=int, help="largest other request (default $CURVEFM_MAX_BODY_BYTES or 4 MB)")
    for limit in fields(SessionLimits):
        s.add_argument(f"--{limit.name.replace('_', '-')}", type=int,
                       help=f"{limit.metadata['help']} (default $CURVEFM_{limit.name.upper()} or {limit.default})")
    add_limit_options(s)
    s.add_argument("--log-level", default="info")
    s.set_defaults(run=cmd_serve)

    w = sub.add_parser("worker", help="run an RQ worker on the project's queues")
    w.add_argument("--redis-url", help="Redis URL (default $CURVEFM_REDIS_URL)")
    w.add_argument("--queues", nargs="+", help="queue names (default: the project's queues)")
    w.add_argument("--name", help="worker name (default: chosen by RQ)")
    w.add_argument("--burst", action="store_true", help="exit once the queues are empty")
    w.set_defaults(run=cmd_worker)

    u = sub.add_parser("users", help="manage the service's users and their bearer tokens")
    users = u.add_subparsers(dest="users_command", required=True)
    ua = users.add_parser("add", parents=[data], help="create a user and print its token (last word of the output)")
    ua.add_argument("name", help="1 to 64 letters, digits, '_', '.' or '-'")
    ua.add_argument("--admin", action="store_true", help="may see and manage everything")
    ua.set_defaults(run=cmd_users_add)
    ul = users.add_parser("list", parents=[data], help="list users (name, admin, created)")
    ul.add_argument("--json", action="store_true")
    ul.set_defaults(run=cmd_users_list)
    ur = users.add_parser("remove", parents=[data], help="delete a user; its token stops working at once")
    ur.add_argument("name")
    ur.set_defaults(run=cmd_users_remove)
    ut = users.add_parser("token", parents=[data], help="replace a user's token (tokens cannot be shown again)")
    ut.add_argument("name")
    ut.add_argument("--rotate", action="store_true", help="make a new token and print it; the old one stops working")
    ut.set_defaults(run=cmd_users_token)

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


if __name__ == "__main__":
    sys.exit(main())
