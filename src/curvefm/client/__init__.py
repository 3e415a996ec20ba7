"""A Python client of the curvefm HTTP API, for notebooks and scripts (``pip install curvefm[client]``).

.. code-block:: python

    from curvefm.client import Client
    c = Client("http://127.0.0.1:8000")                      # token: CURVEFM_TOKEN unless given
    src, tgt = c.upload("a.off"), c.upload("b.off")          # shape ids
    c.basis(src, k=120).wait(); c.basis(tgt, k=120).wait()  # jobs: .wait() shows progress; .state, .cancel()
    s = c.session(src, tgt, k=120)
    s.add_curve(source=[i, j], target=[p, q])                # file vertex ids, as in CURVES.json
    C = s.map()                                              # C source -> target (numpy, k x k)
    r = s.refine("zoomout").wait()                           # r.map_target_to_source[j]: source vertex of target j

Error answers raise the project's own exceptions (:mod:`curvefm.errors`: ``Conflict``, ``NotFound``,
``Unauthenticated``, ...) with the server's message, and ``status`` and ``body`` (the JSON error body) set; a job
that ends without result raises :class:`JobFailed`.
"""

from curvefm.client.api import Client, Collection, Curve, Job, JobFailed, RefineJob, Refinement, Session

__all__ = ["Client", "Collection", "Curve", "Job", "JobFailed", "RefineJob", "Refinement", "Session"]
