#!/usr/bin/env bash
# The static checks CI runs before the tests: lint, format, the import layers, types (mypy, configured in
# pyproject.toml: strict on the core library), the web UI's lint, the documentation site's strict build.
# .pre-commit-config.yaml runs the same checks on each commit once enabled with `.venv/bin/pre-commit install`
# (or on demand: `.venv/bin/pre-commit run --all-files`).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=.venv/bin
$bin/ruff check .
$bin/ruff format --check .
$bin/lint-imports
$bin/mypy
npx --no-install eslint --max-warnings 0 src/curvefm/service/static
# The documentation site (mkdocs.yml), built outside the tree: strict, so a warning (a broken link or anchor, a
# docstring mkdocstrings cannot read) fails the check.
site="$(mktemp -d)"
trap 'rm -rf "$site"' EXIT
NO_MKDOCS_2_WARNING=1 $bin/mkdocs build --strict --site-dir "$site"
