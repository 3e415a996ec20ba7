"""The wheel works alone: built from the checkout, installed in a fresh virtual environment and started from a
folder with no checkout, no npm and no CURVEFM_THREE_DIR, it serves the UI (three.js draws a session in Chromium)
and the API documentation (Swagger UI), from the files it carries (build_vendor.py)."""

from __future__ import annotations

import json
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest
from support.ci import unavailable
from support.paths import REPO
from support.processes import TEST_USER, Api, free_port, wait_until_healthy
from support.ui import PageWatch, open_session

sys.path.insert(0, str(REPO))
from build_vendor import VENDOR_FILES, VendorError, vendor_sources  # noqa: E402

K = 20


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    try:
        vendor_sources()
    except VendorError as exc:
        unavailable(str(exc))
    out = tmp_path_factory.mktemp("dist")
    # no build isolation: the test's own setuptools builds it, offline
    run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-w", str(out), str(REPO)])
    (built,) = out.glob("curvefm-*.whl")
    return built


def run(args: list, **kwargs) -> str:
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True, **kwargs)
    assert done.returncode == 0, f"{args}:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout


def test_the_wheel_carries_the_pinned_npm_files_and_nothing_of_node_modules(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    for package, files in VENDOR_FILES.items():
        for name in files:
            assert f"curvefm/service/vendor/{package}/{name}" in names
        shipped = json.loads(zipfile.ZipFile(wheel).read(f"curvefm/service/vendor/{package}/package.json"))
        locked = json.loads((REPO / "package-lock.json").read_text())["packages"][f"node_modules/{package}"]
        assert shipped["version"] == locked["version"]
    assert not [n for n in names if "node_modules" in n or n.startswith("build_vendor")]


def test_building_without_the_npm_packages_says_what_to_run(tmp_path):
    (tmp_path / "package-lock.json").write_text((REPO / "package-lock.json").read_text())
    with pytest.raises(VendorError, match="npm ci"):
        vendor_sources(tmp_path)


def fresh_venv(folder: Path, wheel: Path) -> Path:
    """A virtual environment with the wheel installed (``--no-deps``: its dependencies are this interpreter's,
    reached through a .pth file, so the test needs no network; the wheel's own files are what is tested)."""
    run([sys.executable, "-m", "venv", "--without-pip", folder])
    python = folder / "bin" / "python"
    site = Path(run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"]).strip())
    dependencies = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    dependencies |= {p for p in sys.path if p.endswith("site-packages")}
    (site / "dependencies-of-the-test.pth").write_text("\n".join(sorted(dependencies)) + "\n")
    run([sys.executable, "-m", "pip", "--python", python, "install", "--no-deps", "--no-index", wheel])
    return python


def test_the_installed_wheel_serves_its_ui_and_docs(wheel, tmp_path, processes, browser):
    python = fresh_venv(tmp_path / "venv", wheel)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {"CURVEFM_THREE_DIR": "", "PYTHONPATH": "", "CURVEFM_RATE_LIMIT": "0"}
    where = run(
        [python, "-c", "import curvefm.service.ui as ui; print(ui.vendor_dir('three'))"],
        cwd=elsewhere,
        env={"PATH": "/usr/bin:/bin"},
    )
    assert Path(where.strip()).is_relative_to(tmp_path / "venv"), where

    data, port = tmp_path / "data", free_port()
    token = processes.token(data, TEST_USER)
    args = [str(python), "-m", "curvefm.service", "--host", "127.0.0.1", "--port", str(port), "--data", str(data)]
    process = processes.start(args, "wheel-api", env, cwd=elsewhere)
    api = Api(process, f"http://127.0.0.1:{port}", tmp_path / "wheel-api.log", data, token)
    wait_until_healthy(api)
    _, session_id = api.demo_pair(tmp_path, K)

    context = browser.new_context()
    watch = PageWatch(context, api.url)
    page = context.new_page()
    open_session(page, api.url, session_id, token)  # waits until three.js drew the first texture
    page.goto(f"{api.url}/docs")
    page.wait_for_function("() => document.querySelectorAll('.opblock').length > 10", timeout=60_000)
    violations = watch.violations(page)
    context.close()
    assert not violations and not watch.elsewhere, (violations, watch.elsewhere)
