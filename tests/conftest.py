"""Fixtures shared by the whole suite (the folders' conftest.py add their own). Everything that is not a fixture
(process, Redis and browser management, shapes, paths) lives in the ``support`` package."""

import os
import shutil
import uuid
from pathlib import Path

import pytest
from support import records as support_records
from support.ci import unavailable
from support.paths import shared_data_path
from support.processes import Processes
from support.records import Databases
from support.redis_servers import REDIS_URL, delete_prefix

from curvefm.runtime import limit_blas_threads
from curvefm.store import default_data_dir

limit_blas_threads()  # as the CLI does: the solver threads, not BLAS, use the cores


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The real meshes with ground truth (../shared/data or $CURVEFM_SHARED_DATA)."""
    path = shared_data_path()
    if not path.is_dir():
        unavailable(f"shared data folder {path} is absent (set CURVEFM_SHARED_DATA)")
    return path


# ----------------------------------------------------------------------------------------------------------
# Service tests: real Redis, real `python -m curvefm.service` / `python -m curvefm.workers` processes.


@pytest.fixture(scope="session")
def node() -> str:
    """Node.js, for the tests that run the web UI's modules outside a browser."""
    path = shutil.which("node")
    if path is None:
        unavailable("Node.js is not installed (scripts/setup.sh needs it for the UI's packages)")
    return path


@pytest.fixture(scope="session")
def redis_url() -> str:
    import redis

    try:
        redis.Redis.from_url(REDIS_URL, socket_connect_timeout=2).ping()
    except redis.RedisError as exc:
        unavailable(f"no Redis at {REDIS_URL} ({exc}); scripts/test.sh starts one")
    return REDIS_URL


@pytest.fixture
def redis_prefix(redis_url: str):
    """A queue-name prefix of this test only; afterwards every Redis key of it (queues, registries, jobs,
    workers, our own keys) is deleted, and nothing else is touched."""
    prefix = f"cfmtest-{uuid.uuid4().hex[:10]}-"
    yield prefix
    delete_prefix(redis_url, prefix)


@pytest.fixture
def processes(tmp_path: Path):
    runner = Processes(tmp_path)
    yield runner
    runner.stop_all()


@pytest.fixture(scope="module")
def module_processes(tmp_path_factory):
    """Like ``processes``, shared by the tests of one module (one server for many quick requests)."""
    runner = Processes(tmp_path_factory.mktemp("processes"))
    yield runner
    runner.stop_all()


@pytest.fixture(scope="module")
def browser():
    """Headless Chromium (Playwright), one per test module."""
    from support.ui import CHROMIUM, launch

    if not CHROMIUM.is_file():
        unavailable(
            f"browser tests need Chromium at {CHROMIUM} (scripts/setup.sh installs Debian's 'chromium'; "
            "CURVEFM_CHROMIUM points elsewhere)"
        )
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = launch(playwright)
        yield browser
        browser.close()


# ----------------------------------------------------------------------------------------------------------
# The records' database: SQLite in each data directory by default. With CURVEFM_TEST_DATABASE=postgresql the
# service and queue tests run on PostgreSQL (the server is CURVEFM_TEST_POSTGRES, default postgres@127.0.0.1:5432):
# each data directory a module uses gets a database of its own, made on first use and dropped after the module.
# The test process finds it by the data directory (curvefm.records.engine.database_url is patched); the API and
# worker processes of a data directory get its CURVEFM_DATABASE_URL (support.processes), so replicas and workers of
# one deployment share its database and two deployments never do.
ON_DATABASE = ("service", "queue")
DATABASE_ENGINE = "CURVEFM_TEST_DATABASE"


@pytest.fixture(scope="module", autouse=True)
def module_database(request):
    """The engine of this module's records (``sqlite``, or ``postgresql`` as :data:`DATABASE_ENGINE` says for
    the folders :data:`ON_DATABASE`)."""
    engine = os.environ.get(DATABASE_ENGINE, "sqlite")
    folder = Path(str(request.node.path)).parent.name
    if engine == "sqlite" or folder not in ON_DATABASE:
        yield "sqlite"
        return
    if engine != "postgresql":
        pytest.fail(f"{DATABASE_ENGINE}={engine}: sqlite or postgresql", pytrace=False)
    from curvefm.records import engine as records_engine

    databases = support_records.current = Databases.connect()

    def per_data_dir(data_dir=None, url=None) -> str:
        chosen = url or os.environ.get(records_engine.URL_VARIABLE)
        return chosen or databases.url(data_dir if data_dir is not None else default_data_dir())

    try:
        with pytest.MonkeyPatch.context() as patch:
            patch.delenv(records_engine.URL_VARIABLE, raising=False)
            patch.setattr(records_engine, "database_url", per_data_dir)
            yield engine
    finally:
        support_records.current = None
        databases.drop_all()
