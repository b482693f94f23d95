"""The roller of examples/roller_crowning.toml as a Gmsh 2.2 file: a quarter model of a roller of
radius R = 5 and length L = 20 (axis along x1 at x3 = R) standing on the plane x3 = 0; hexahedra.

    python examples/roller_crowning/make_mesh.py     # writes examples/roller_crowning/roller.msh

The body is the lower half of the cylinder, x1 in [0, L/2], x2 in [0, R], between its face
x3 = R - sqrt(R² - x2²) and the axial plane x3 = R. Its cross-section is mapped from a square by
transfinite interpolation (corners: the contact line (0, 0), the point of the face at 45°, (R, R) and
(0, R)); the mesh is graded towards the contact line x2 = 0, the face and the roller's end x1 = L/2.
Groups: ``mid`` (x1 = 0, the roller's mid-plane), ``sym`` (x2 = 0), ``top`` (x3 = R), ``contact``
(the strip x2 <= 1.2 of the face), ``roller`` (the volume).
"""

from pathlib import Path

import meshio
import numpy as np

R, L, STRIP = 5.0, 20.0, 1.2
N_STRIP, N_REST, N_UP, N_AX = 10, 6, 10, 30


def graded(n, ratio):
    """n + 1 points on [0, 1], each interval ``ratio`` times the previous one."""
    w = ratio ** np.arange(n)
    return np.r_[0.0, np.cumsum(w) / w.sum()]


def face(phi):
    """The point of the cylinder's face at angle phi from the bottom, in (x2, x3)."""
    return np.c_[R * np.sin(phi), R - R * np.cos(phi)]


def cross_section():
    """Nodes (nu, nv, 2) of the cross-section: u along the face, v from the face to the axis."""
    pc, pb = np.arcsin(STRIP / R), np.pi / 4
    phi = np.r_[pc * graded(N_STRIP, 1.08), pc + (pb - pc) * graded(N_REST, 1.25)[1:]]
    s = phi / pb                                  # the parameter u of each node along the face
    v = graded(N_UP, 1.15)
    bottom = face(phi)                                           # A -> B
    right = face(pb + (np.pi / 2 - pb) * v)                      # B -> C
    topl = np.c_[R * s, np.full_like(s, R)]                      # D -> C
    left = np.c_[np.zeros_like(v), R * v]                        # A -> D
    A, B, C, D = bottom[0], bottom[-1], topl[-1], topl[0]
    U, V = s[:, None, None], v[None, :, None]
    return ((1 - V) * bottom[:, None] + V * topl[:, None] + (1 - U) * left[None] + U * right[None]
            - ((1 - U) * (1 - V) * A + U * (1 - V) * B + U * V * C + (1 - U) * V * D))


def main(path=None):
    path = path or Path(__file__).with_name("roller.msh")
    xs = cross_section()
    nu, nv = xs.shape[:2]
    x1 = (L / 2) * (1.0 - graded(N_AX, 1.06)[::-1])           # finer towards the end x1 = L/2
    nx = x1.size
    pts = np.empty((nx, nu, nv, 3))
    pts[..., 0] = x1[:, None, None]
    pts[..., 1:] = xs[None]
    pts[:, 0, :, 1] = 0.0                                      # exact symmetry plane
    idx = np.arange(pts[..., 0].size).reshape(nx, nu, nv)
    a, b, c = (g.ravel() for g in np.meshgrid(np.arange(nx - 1), np.arange(nu - 1), np.arange(nv - 1),
                                             indexing="ij"))
    hexes = np.c_[idx[a, b, c], idx[a + 1, b, c], idx[a + 1, b + 1, c], idx[a, b + 1, c],
                  idx[a, b, c + 1], idx[a + 1, b, c + 1], idx[a + 1, b + 1, c + 1], idx[a, b + 1, c + 1]]

    def quads(q):
        return np.c_[q[:-1, :-1].ravel(), q[1:, :-1].ravel(), q[1:, 1:].ravel(), q[:-1, 1:].ravel()]
    groups = {"mid": quads(idx[0]), "sym": quads(idx[:, 0, :]), "top": quads(idx[:, :, -1]),
              "contact": quads(idx[:, :N_STRIP + 1, 0])}
    blocks, phys, fd = [], [], {}
    for tag, (name, q) in enumerate(groups.items(), start=1):
        blocks.append(("quad", q))
        phys.append(np.full(len(q), tag))
        fd[name] = np.array([tag, 2])
    blocks.append(("hexahedron", hexes))
    phys.append(np.full(len(hexes), 9))
    fd["roller"] = np.array([9, 3])
    meshio.write(path, meshio.Mesh(pts.reshape(-1, 3), blocks,
                                   cell_data={"gmsh:physical": phys, "gmsh:geometrical": phys},
                                   field_data=fd), file_format="gmsh22", binary=False)
    return path


if __name__ == "__main__":
    print(main())
