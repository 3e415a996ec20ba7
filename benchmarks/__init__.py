"""Product benchmarks: each prints one JSON object. Run from the repository root: ``python -m benchmarks.bench_NAME``
(see docs/performance.md)."""
