"""The image's wheel is built from the whole source tree: the Dockerfile's wheel stage copies what .dockerignore lets
through (no hand-made list of package folders), and the wheel built from exactly that holds every package under
src/curvefm, its web UI and the vendored npm files.

The copy is made by the real container engine (podman, so .dockerignore has its real semantics): a throwaway
Containerfile ``FROM scratch`` with the wheel stage's own WORKDIR and COPY lines, parsed from the Dockerfile, built
into a private podman store in a temporary folder and written out with ``--output``. The stage's
``COPY --from=<npm stage> .../node_modules`` is played by linking the checkout's production npm packages (what
``npm ci --omit=dev`` installs, per package-lock.json); the wheel is then built on the host as the stage's
``RUN pip wheel`` would (``--no-deps --no-build-isolation``: offline, with this interpreter's setuptools).
tests/test_wheel.py tests what the checkout's own wheel does once installed; this test ties the image to it.

Self-contained (no conftest). Without podman it skips, or fails with the reason when CI is set.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path, PurePosixPath
from typing import NoReturn

import pytest

REPO = Path(__file__).resolve().parents[2]
WHEEL_STAGE = "wheel"
# no registry is reachable and nothing is run in a container, so no ulimits are needed (podman's defaults exceed
# the hard limits of some machines: "error setting rlimit")
CONTAINERS_CONF = "[containers]\ndefault_ulimits = []\n"
# what must never reach an image from a developer's checkout
NEVER_IN_THE_CONTEXT = {".git", ".venv", ".env", "node_modules", "__pycache__", "build", "dist"}


def unavailable(reason: str) -> NoReturn:
    if os.environ.get("CI", "").lower() not in ("", "0", "false"):
        pytest.fail(f"{reason} [CI is set: a missing requirement fails the test]", pytrace=False)
    pytest.skip(reason)


def instructions(dockerfile: str) -> list[tuple[str, str]]:
    """(INSTRUCTION, arguments) per instruction, continuation lines joined and comments dropped."""
    result, pending = [], ""
    for line in dockerfile.splitlines():
        if not pending and (not line.strip() or line.lstrip().startswith("#")):
            continue
        if pending and line.lstrip().startswith("#"):
            continue
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        whole = (pending + line).strip()
        pending = ""
        keyword, _, arguments = whole.partition(" ")
        result.append((keyword.upper(), arguments.strip()))
    return result


def stage(dockerfile: str, name: str) -> list[tuple[str, str]]:
    """The instructions of the stage ``FROM ... AS name`` (without its FROM)."""
    found, inside = None, False
    for keyword, arguments in instructions(dockerfile):
        if keyword == "FROM":
            inside = bool(re.search(rf"\bAS\s+{re.escape(name)}\s*$", arguments, re.IGNORECASE))
            if inside:
                found = []
            continue
        if inside:
            found.append((keyword, arguments))
    assert found is not None, f"the Dockerfile has no stage 'FROM ... AS {name}'"
    return found


def copy_arguments(arguments: str) -> tuple[dict[str, str], list[str]]:
    """A COPY's flags (``--from=...``) and its paths (sources then destination), shell or JSON form."""
    words = json.loads(arguments) if arguments.startswith("[") else shlex.split(arguments)
    flags = dict(w[2:].split("=", 1) for w in words if w.startswith("--"))
    return flags, [w for w in words if not w.startswith("--")]


def replayable(instructions_: list[tuple[str, str]]) -> tuple[str, list[tuple[str, str]], str]:
    """Splits the wheel stage into a Containerfile ``FROM scratch`` (its WORKDIR and context COPY lines), the
    copies from other stages [(source, destination)] and the folder its RUN builds in."""
    lines, other_stages, workdir, build_dir = ["FROM scratch"], [], "/", None
    for keyword, arguments in instructions_:
        if keyword == "WORKDIR":
            workdir = str(PurePosixPath(workdir, arguments))
            lines.append(f"WORKDIR {arguments}")
        elif keyword == "COPY":
            flags, paths = copy_arguments(arguments)
            if "from" in flags:
                destination = str(PurePosixPath(workdir, paths[-1]))
                other_stages += [(source, destination) for source in paths[:-1]]
            else:
                lines.append(f"COPY {arguments}")
        elif keyword == "RUN":
            assert "pip wheel" in arguments, f"the test knows only the stage's 'pip wheel' RUN, not: RUN {arguments}"
            build_dir = workdir
        elif keyword not in ("ENV", "ARG", "LABEL"):
            raise AssertionError(f"the test cannot replay '{keyword} {arguments}' of the wheel stage: teach it")
    assert build_dir, "the wheel stage has no 'RUN pip wheel'"
    return "\n".join(lines) + "\n", other_stages, build_dir


def production_npm_packages(into: Path) -> None:
    """What the npm stage's ``npm ci --omit=dev`` leaves in node_modules, linked from the checkout's."""
    lock = json.loads((REPO / "package-lock.json").read_text())["packages"]
    for key, entry in lock.items():
        if not key or entry.get("dev") or key.count("node_modules/") != 1:
            continue  # the root, a dev package, or one nested inside another (it comes with its parent)
        source = REPO / key
        if not source.is_dir():
            unavailable(f"{source} is missing: run 'npm ci' in {REPO} first (the npm stage's packages)")
        target = into / "node_modules" / key.removeprefix("node_modules/")
        target.parent.mkdir(parents=True, exist_ok=True)
        target.symlink_to(source, target_is_directory=True)


def run(args: list, **kwargs) -> str:
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=180, **kwargs)
    assert done.returncode == 0, f"{shlex.join(map(str, args))}:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout


@pytest.fixture(scope="module")
def image_sources(tmp_path_factory) -> Path:
    """The wheel stage's file system after its COPY lines: the folder its ``pip wheel`` builds in."""
    podman = shutil.which("podman")
    if podman is None:
        unavailable("podman is not installed (Debian: apt-get install podman): it makes the image's build context")
    containerfile, other_stages, build_dir = replayable(stage((REPO / "Dockerfile").read_text(), WHEEL_STAGE))
    tmp = tmp_path_factory.mktemp("image")
    (tmp / "containers.conf").write_text(CONTAINERS_CONF)
    (tmp / "Containerfile").write_text(containerfile)
    env = {**os.environ, "CONTAINERS_CONF": str(tmp / "containers.conf")}
    # a private store (vfs: nothing stays mounted), removed afterwards: the machine's images are not touched
    state = tmp / "podman"
    store = ["--root", state / "root", "--runroot", state / "run", "--tmpdir", state / "tmp"]
    store += ["--storage-driver", "vfs", "--events-backend", "file"]
    try:
        build = [podman, *store, "build", "--quiet", "--pull=never", "--network=none", "--layers=false"]
        build += ["-f", tmp / "Containerfile", "--output", f"type=local,dest={tmp / 'fs'}", REPO]
        done = subprocess.run([str(a) for a in build], capture_output=True, text=True, timeout=180, env=env)
        hint = ""
        if "remount /" in done.stderr:  # podman applies a layer in a chroot of its own, which needs / to be a mount
            hint = "\n(in a chroot, bind-mount its root onto itself: unshare -m sh -c 'mount --rbind R R; chroot R')"
        assert done.returncode == 0, f"{shlex.join(map(str, build))}:\n{done.stderr[-3000:]}{hint}"
    finally:
        shutil.rmtree(state, ignore_errors=True)
    root = tmp / "fs"
    context = {p.name for p in root.rglob("*")} | {p.suffix for p in root.rglob("*")}
    leaked = sorted((NEVER_IN_THE_CONTEXT | {".egg-info", ".pyc"}) & context)
    assert not leaked, f"the image's build context carries {leaked}: exclude them in .dockerignore"
    for source, destination in other_stages:
        assert PurePosixPath(source).name == "node_modules", f"the test does not know the stage output {source}"
        production_npm_packages(root / PurePosixPath(destination).parent.relative_to("/"))
    return root / build_dir.lstrip("/")


@pytest.fixture(scope="module")
def image_wheel(image_sources, tmp_path_factory) -> zipfile.ZipFile:
    out = tmp_path_factory.mktemp("dist")
    run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", out, image_sources])
    (built,) = out.glob("curvefm-*.whl")
    return zipfile.ZipFile(built)


def source_files() -> list[str]:
    """Every file of the package in the checkout (tracked by git where there is one), relative to src/."""
    if (REPO / ".git").exists() and shutil.which("git"):
        tracked = run(["git", "-C", REPO, "ls-files", "-z", "--", "src/curvefm"]).split("\0")
        return [name.removeprefix("src/") for name in tracked if name]
    return [str(p.relative_to(REPO / "src")) for p in (REPO / "src/curvefm").rglob("*.py")]


def test_the_wheel_stage_copies_the_source_tree_not_a_list_of_folders():
    copies = [copy_arguments(a) for k, a in stage((REPO / "Dockerfile").read_text(), WHEEL_STAGE) if k == "COPY"]
    from_the_context = [paths for flags, paths in copies if "from" not in flags]
    assert from_the_context and all(paths[:-1] == ["."] for paths in from_the_context), (
        f"the wheel stage should copy the source tree ('COPY . .') and leave the choice to .dockerignore, "
        f"not list what to copy: {from_the_context}"
    )


def test_the_image_wheel_holds_every_package_and_its_files(image_wheel):
    names = set(image_wheel.namelist())
    expected = [name for name in source_files() if "__pycache__" not in name]
    packages = sorted({str(PurePosixPath(n).parent) for n in expected if n.endswith("/__init__.py")})
    assert len(packages) > 10 and "curvefm/client" in packages, packages
    missing = sorted(set(expected) - names)
    assert not missing, f"the image's wheel lacks {missing}: does .dockerignore exclude them?"


def test_the_image_wheel_carries_the_pinned_npm_files_and_nothing_of_node_modules(image_wheel):
    sys.path.insert(0, str(REPO))
    from build_vendor import VENDOR_FILES, locked_version

    names = set(image_wheel.namelist())
    for package, files in VENDOR_FILES.items():
        missing = [name for name in files if f"curvefm/service/vendor/{package}/{name}" not in names]
        assert not missing, f"the image's wheel lacks {package}'s {missing}"
        shipped = json.loads(image_wheel.read(f"curvefm/service/vendor/{package}/package.json"))
        assert shipped["version"] == locked_version(package, REPO)
    assert not [n for n in names if "node_modules" in n or n.startswith("build_vendor")]


def test_the_image_wheel_registers_the_built_in_plugins(image_wheel):
    groups = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["entry-points"]
    (entry_points,) = [n for n in image_wheel.namelist() if n.endswith(".dist-info/entry_points.txt")]
    text = image_wheel.read(entry_points).decode()
    for group, entries in groups.items():
        for name, target in entries.items():
            assert re.search(rf"^{re.escape(name)} = {re.escape(target)}$", text, re.MULTILINE), (group, name)
