"""curvefm: interactive curve-constrained functional maps between 3D shapes.

Concept packages: :mod:`curvefm.geometry`, :mod:`curvefm.spectral`, :mod:`curvefm.fmap`, :mod:`curvefm.pointwise`,
:mod:`curvefm.session`, :mod:`curvefm.evaluation`; :func:`curvefm.matching.match` runs the whole pipeline.
"""

__version__ = "0.1.0"
