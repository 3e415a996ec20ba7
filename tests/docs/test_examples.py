"""Every fenced code block in README.md and docs/**/*.md runs, and a block that fails fails with its file and line.

The convention, by the fence's info string: its language, then flags as classes in the attribute-list form that
MkDocs' superfences renders (```` ```{.bash .notest} ````; a plain ```` ```bash notest ```` would break the page):

* ```` ```python ```` blocks run with this interpreter; ```` ```bash ```` (or ``sh``, ``shell``) blocks with
  ``bash -euo pipefail``. ``curvefm`` on their PATH is this checkout's command line.
* ```` ```{.bash .notest} ```` (or ``{.python .notest}``): shown, never run: blocks that install system packages, start
  docker-compose or a service for good, build a wheel, or run for minutes.
* ```` ```{.python .server} ```` / ```` ```{.bash .server} ````: a curvefm service is started for them (once per test
  session, on a free port, rate limit off); ``http://127.0.0.1:8000`` in the block is replaced by its address and
  ``$CURVEFM_TOKEN`` holds an admin's token.
* Any other language (``text``, ``console``, ``json``, ``mermaid``, ...) or none: not code to run.

The blocks of one Markdown file run in order in one working folder, so a later block may use a file an earlier one
wrote. ``../shared/data`` resolves from that folder to the shared data (``$CURVEFM_SHARED_DATA``, else the checkout's
``../shared/data``), as it does from the repository root; ``CURVEFM_DATA`` is a temporary data directory shared by
every block, so bases are computed once. Keep examples small (k = 30, a few curves): the whole test should take a
minute or two.

Self-contained on purpose: paths come from ``__file__``, nothing is imported from a conftest.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC_URL = "http://127.0.0.1:8000"
RUNNABLE = {"python": "python", "py": "python", "bash": "bash", "sh": "bash", "shell": "bash"}
FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})(?P<info>[^`\n]*)$")
TIMEOUT_S = 300


@dataclass(frozen=True)
class Block:
    path: Path  # the Markdown file
    line: int  # the line of its opening fence, 1-based
    language: str  # "python" or "bash"
    flags: frozenset[str]
    code: str

    @property
    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def blocks_of(path: Path) -> list[Block]:
    """The fenced blocks of a Markdown file that are code to run (indented fences included, e.g. in lists)."""
    found, lines, i = [], path.read_text(encoding="utf-8").splitlines(), 0
    while i < len(lines):
        opening = FENCE.match(lines[i])
        if not opening or not opening["info"].strip():
            i += 1
            continue
        words = [word.lstrip(".") for word in opening["info"].strip().strip("{}").split()]
        closing = re.compile(rf"^[ \t]*{re.escape(opening['fence'][0])}{{{len(opening['fence'])},}}[ \t]*$")
        j = i + 1
        while j < len(lines) and not closing.match(lines[j]):
            j += 1
        indent = len(opening["indent"])
        body = "\n".join(line[indent:] if line[:indent].strip() == "" else line for line in lines[i + 1 : j])
        language = RUNNABLE.get(words[0].lower())
        if language:
            found.append(Block(path, i + 1, language, frozenset(words[1:]), body + "\n"))
        i = j + 1
    return found


def markdown_files() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


BLOCKS = [block for path in markdown_files() for block in blocks_of(path)]
RUN = [block for block in BLOCKS if "notest" not in block.flags]


def shared_data() -> Path | None:
    for candidate in (os.environ.get("CURVEFM_SHARED_DATA"), ROOT.parent / "shared" / "data", "/work/shared/data"):
        if candidate and (Path(candidate) / "faust").is_dir():
            return Path(candidate).resolve()
    return None


@pytest.fixture(scope="module")
def sandbox(tmp_path_factory):
    """A folder with ``shared/data`` (a link to the real data), ``data`` (CURVEFM_DATA), ``bin/curvefm`` (this
    checkout's command line) and one working folder per Markdown file beside them (``work-README.md``, ...), so
    that ``../shared/data`` resolves from it."""
    root = tmp_path_factory.mktemp("docs-examples")
    data = shared_data()
    if data:
        (root / "shared").mkdir()
        (root / "shared" / "data").symlink_to(data)
    (root / "data").mkdir()
    (root / "bin").mkdir()
    shim = root / "bin" / "curvefm"
    shim.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m curvefm.cli "$@"\n')
    shim.chmod(0o755)
    env = dict(os.environ)
    env.update(
        PYTHONPATH=os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")]).rstrip(os.pathsep),
        CURVEFM_DATA=str(root / "data"),
        PATH=os.pathsep.join([str(root / "bin"), str(Path(sys.executable).parent), env.get("PATH", "")]),
        MPLBACKEND="Agg",
        OMP_NUM_THREADS="1",
    )
    env.pop("CURVEFM_TOKEN", None)
    return {"root": root, "env": env, "data": data}


@pytest.fixture(scope="module")
def server(sandbox):
    """A curvefm service on a free port, on the sandbox's data directory, with an admin's token; started on first
    use and stopped at the end of the module."""
    state: dict = {}

    def start() -> tuple[str, str]:
        if state:
            return state["url"], state["token"]
        env = dict(sandbox["env"], CURVEFM_RATE_LIMIT="0")
        data = str(sandbox["root"] / "data")
        made = subprocess.run(
            ["curvefm", "users", "add", "docs-examples", "--admin", "--data", data],
            env=env,
            capture_output=True,
            text=True,
            check=True,
            timeout=120,
        )
        token = made.stdout.strip().splitlines()[-1].split()[-1]
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
        log = open(sandbox["root"] / "server.log", "w")
        process = subprocess.Popen(
            [sys.executable, "-m", "curvefm.service", "--host", "127.0.0.1", "--port", str(port), "--data", data],
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        url = f"http://127.0.0.1:{port}"
        deadline = time.monotonic() + 120
        while True:
            try:
                with urllib.request.urlopen(f"{url}/health", timeout=2) as answer:
                    if answer.status == 200:
                        break
            except OSError:
                pass
            if process.poll() is not None or time.monotonic() > deadline:
                process.kill()
                pytest.fail(f"the service did not start: {(sandbox['root'] / 'server.log').read_text()[-2000:]}")
            time.sleep(0.3)
        state.update(url=url, token=token, process=process, log=log)
        return url, token

    yield start
    if state:
        os.killpg(state["process"].pid, signal.SIGTERM)
        try:
            state["process"].wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(state["process"].pid, signal.SIGKILL)
        state["log"].close()


def test_the_convention_finds_the_examples():
    """The extraction itself: the README's and the CLI page's examples are found, and some are marked not to run."""
    where = {block.where.split(":")[0] for block in RUN}
    assert "README.md" in where and "docs/cli.md" in where and "docs/client.md" in where
    assert any("notest" in block.flags for block in BLOCKS)


def test_the_readme_stays_short():
    """The README is the front door (what it is, two commands, a tour, where to read more); the rest is in docs/."""
    lines = len((ROOT / "README.md").read_text(encoding="utf-8").splitlines())
    assert lines <= 200, f"README.md has {lines} lines: move the detail into docs/"


@pytest.mark.parametrize("block", RUN, ids=[block.where for block in RUN])
def test_example_runs(block: Block, sandbox, server):
    if "shared/data" in block.code and sandbox["data"] is None:
        pytest.skip("no shared data (../shared/data or $CURVEFM_SHARED_DATA)")
    if block.language == "bash" and re.search(r"^\s*curl\b", block.code, re.M) and not shutil.which("curl"):
        pytest.skip("no curl on this machine")
    env = dict(sandbox["env"])
    code = block.code
    if "server" in block.flags:
        url, token = server()
        code = code.replace(DOC_URL, url)
        env["CURVEFM_TOKEN"] = token
    work = sandbox["root"] / ("work-" + str(block.path.relative_to(ROOT)).replace("/", "_"))
    work.mkdir(parents=True, exist_ok=True)
    if block.language == "python":
        command = [sys.executable, "-c", code]
    else:
        command = [shutil.which("bash") or "/bin/bash", "-euo", "pipefail", "-c", code]
    try:
        done = subprocess.run(command, cwd=work, env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{block.where}: the {block.language} example ran past {TIMEOUT_S} s")
    if done.returncode != 0:
        pytest.fail(
            f"{block.where}: the {block.language} example failed (exit {done.returncode})\n"
            f"--- code\n{block.code}--- stdout\n{done.stdout[-3000:]}\n--- stderr\n{done.stderr[-3000:]}",
            pytrace=False,
        )
