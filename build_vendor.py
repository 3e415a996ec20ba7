"""Build hook: the wheel carries the browser files the service serves (three.js for the UI, Swagger UI and ReDoc
for ``/docs`` and ``/redoc``), copied from ``node_modules`` at the versions ``package-lock.json`` pins.

They are never committed: ``npm ci`` (``scripts/setup.sh`` runs ``npm install``) puts them into ``node_modules``,
and building a wheel (``pip wheel .``, ``python -m build``) copies the files below into
``curvefm/service/vendor/<package>/`` of the wheel. An editable install copies nothing: the service then serves
the checkout's ``node_modules`` (``curvefm.service.vendor``).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
VENDOR_PACKAGE_DIR = ("curvefm", "service", "vendor")
VENDOR_FILES = {
    "three": [
        "LICENSE",
        "package.json",
        "build/three.module.js",
        "build/three.core.js",
        "examples/jsm/controls/OrbitControls.js",
    ],
    "swagger-ui-dist": [
        "LICENSE",
        "NOTICE",
        "package.json",
        "swagger-ui-bundle.js",
        "swagger-ui.css",
        "favicon-32x32.png",
    ],
    "redoc": ["LICENSE", "package.json", "bundles/redoc.standalone.js"],
}
"""Per npm package, the files the pages load (and the licence they come under)."""


class VendorError(RuntimeError):
    pass


def locked_version(package: str, root: Path = ROOT) -> str:
    lock = json.loads((root / "package-lock.json").read_text())
    return lock["packages"][f"node_modules/{package}"]["version"]


def vendor_sources(root: Path = ROOT) -> dict[str, Path]:
    """Every vendored file by its path inside the vendor folder; refuses a missing or differently versioned
    package, naming the command that installs the locked one."""
    sources = {}
    for package, files in VENDOR_FILES.items():
        folder = root / "node_modules" / package
        wanted = locked_version(package, root)
        manifest = folder / "package.json"
        found = json.loads(manifest.read_text())["version"] if manifest.is_file() else None
        if found != wanted:
            raise VendorError(
                f"building curvefm needs the npm package {package} {wanted} (package-lock.json) in "
                f"{folder}, found {found or 'nothing'}: run 'npm ci --omit=dev' in {root} first"
            )
        for name in files:
            sources[f"{package}/{name}"] = folder / name
    return sources


class BuildPyWithVendor(build_py):
    """``build_py`` that also copies the vendored browser files into the built package (not in editable mode)."""

    def run(self) -> None:
        super().run()
        if not self.editable_mode:
            for target, source in self._vendor_targets().items():
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(source, target)

    def get_outputs(self, include_bytecode: bool = True) -> list[str]:
        vendored = [] if self.editable_mode else [str(target) for target in self._vendor_targets()]
        return super().get_outputs(include_bytecode) + vendored

    def _vendor_targets(self) -> dict[Path, Path]:
        base = Path(self.build_lib, *VENDOR_PACKAGE_DIR)
        return {base / name: source for name, source in vendor_sources().items()}
