"""Triangle meshes and what is computed on their surface alone: the :class:`Mesh` type (internal and file
vertex ids), validation, one reader/writer per file format, Laplace-Beltrami operators, graph paths,
geodesic distances, the side of a curve a point lies on, farthest-point sampling, decimation, display copies
of big meshes and texture coordinates.
"""

from curvefm.geometry.curve_side import curve_side
from curvefm.geometry.decimation import closest_point_weights, decimate, fast_decimate
from curvefm.geometry.display import DisplayMesh, display_graph, display_mesh
from curvefm.geometry.geodesics import (
    checked_ids,
    geodesic_diameter,
    geodesic_distances,
    pair_geodesic_distances,
)
from curvefm.geometry.graph_paths import check_edge_path, shortest_path
from curvefm.geometry.laplacian import cotangent_laplacian, robust_laplacian
from curvefm.geometry.mesh import Mesh, MeshReport, edge_weight_graph
from curvefm.geometry.mesh_io import (
    GLTF_FORMATS,
    OPEN3D_FORMATS,
    SUPPORTED_FORMATS,
    load_mesh,
    save_mesh,
    save_textured,
    save_textured_zip,
    zip_files,
)
from curvefm.geometry.sampling import farthest_point_sampling
from curvefm.geometry.texture import checkerboard_image, cylindrical_uv, texture_coordinates
from curvefm.geometry.validation import build_mesh, per_vertex_uv

__all__ = [
    "DisplayMesh",
    "GLTF_FORMATS",
    "Mesh",
    "MeshReport",
    "OPEN3D_FORMATS",
    "SUPPORTED_FORMATS",
    "build_mesh",
    "check_edge_path",
    "checkerboard_image",
    "checked_ids",
    "closest_point_weights",
    "curve_side",
    "cotangent_laplacian",
    "decimate",
    "fast_decimate",
    "display_graph",
    "display_mesh",
    "cylindrical_uv",
    "edge_weight_graph",
    "farthest_point_sampling",
    "geodesic_diameter",
    "geodesic_distances",
    "load_mesh",
    "pair_geodesic_distances",
    "per_vertex_uv",
    "robust_laplacian",
    "save_mesh",
    "save_textured",
    "save_textured_zip",
    "shortest_path",
    "texture_coordinates",
    "zip_files",
]
