"""What the tests share that is not a fixture (the fixtures live in the conftest.py files).

``tests/`` is on ``sys.path`` (``pythonpath`` in pyproject.toml's pytest section), so a test imports these as
``from support.processes import Api``:

- :mod:`support.paths`: the repository, the shared data folder, where test artifacts go
- :mod:`support.ci`: :func:`~support.ci.unavailable`, a skip on a laptop and a failure under ``CI``
- :mod:`support.processes`: API and worker processes, their clients and users, free ports
- :mod:`support.redis_servers`: the shared Redis of the tests and a private ``redis-server`` of one test
- :mod:`support.errors`: checks of the API's error bodies and of an unchanged data directory
- :mod:`support.display`: a server drawing FAUST coarse, and the binary mesh payload's decoder
- :mod:`support.ui`: Chromium (Playwright) and driving the web UI in it (shared with benchmarks/bench_ui_latency.py)
- :mod:`support.shapes`: small shapes made in code; :mod:`support.mesh_corpus`: the malformed-mesh corpus
- :mod:`support.lab`: one API with callers of every kind, for the access tests
"""
