"""Only the build hook lives here (everything else is in pyproject.toml): the wheel carries the npm files the pages
load (three.js, Swagger UI, ReDoc), which build_vendor.py copies from node_modules (`npm ci` first) at the versions
package-lock.json pins. The hook sits beside this file, outside src/, because it is not part of the package."""

import sys
from pathlib import Path

from setuptools import setup

sys.path.insert(0, str(Path(__file__).resolve().parent))
from build_vendor import BuildPyWithVendor  # noqa: E402

setup(cmdclass={"build_py": BuildPyWithVendor})
