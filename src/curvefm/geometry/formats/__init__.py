"""One module per mesh file format; :mod:`curvefm.geometry.mesh_io` picks one by suffix."""
