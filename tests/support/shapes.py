"""Small shapes generated in code for fast tests."""

import numpy as np

from curvefm.geometry import build_mesh


def ellipsoid(n_lat=24, n_lon=48, radii=(1.0, 0.7, 0.5), scale=1.0):
    """A closed triangulated ellipsoid (UV sphere with poles), ~n_lat * n_lon vertices."""
    theta = np.linspace(0, np.pi, n_lat + 2)[1:-1]
    phi = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.c_[np.sin(t).ravel() * np.cos(p).ravel(), np.sin(t).ravel() * np.sin(p).ravel(), np.cos(t).ravel()]
    vertices = np.vstack([ring, [[0, 0, 1], [0, 0, -1]]]) * np.asarray(radii) * scale
    north, south = len(ring), len(ring) + 1
    faces = []
    for i in range(n_lat - 1):
        for j in range(n_lon):
            a, b = i * n_lon + j, i * n_lon + (j + 1) % n_lon
            c, d = a + n_lon, b + n_lon
            faces += [[a, c, b], [b, c, d]]
    for j in range(n_lon):
        faces.append([north, j, (j + 1) % n_lon])
        last = (n_lat - 1) * n_lon
        faces.append([south, last + (j + 1) % n_lon, last + j])
    return build_mesh(vertices, np.array(faces), name="ellipsoid")


def basis_of(mesh, k=40):
    """The built-in ``laplace-beltrami`` basis of a small test mesh."""
    from curvefm import registry

    plugin = registry.get("basis", "laplace-beltrami")
    return plugin.run(mesh, k, plugin.parse_params({}))


def stretched_ellipsoid_pair(k=40):
    """``(M, basis_M, N, basis_N)``: an ellipsoid and a stretched copy, vertex i <-> vertex i."""
    M = ellipsoid()
    N = ellipsoid(radii=(1.1, 0.6, 0.55))
    return M, basis_of(M, k), N, basis_of(N, k)


def off_bytes(mesh) -> bytes:
    """The mesh as the text of an OFF file, for uploads."""
    lines = ["OFF", f"{len(mesh.vertices)} {len(mesh.faces)} 0"]
    lines += [" ".join(f"{x:.9g}" for x in vertex) for vertex in mesh.vertices]
    lines += ["3 " + " ".join(str(i) for i in face) for face in mesh.faces]
    return ("\n".join(lines) + "\n").encode()


def save_demo_shapes(folder) -> list:
    """The service's two demo shapes (which share their vertex ids) as OFF files in ``folder``, source first."""
    from curvefm.geometry import save_mesh
    from curvefm.service.demo import demo_shapes

    paths = []
    for mesh in demo_shapes():
        save_mesh(mesh, folder / f"{mesh.name}.off")
        paths.append(folder / f"{mesh.name}.off")
    return paths
