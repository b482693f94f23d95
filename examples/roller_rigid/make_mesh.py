"""The roller of examples/roller_rigid.toml as a Gmsh 2.2 file: a quarter model of a roller of
radius R = 5 and length L = 20 (axis along x1 at x3 = R) standing on the plane x3 = 0; hexahedra.

    python examples/roller_rigid/make_mesh.py     # writes examples/roller_rigid/roller.msh

The body is the lower half of the cylinder, x1 in [0, L/2], x2 in [0, R], between its face
x3 = R - sqrt(R² - x2²) and the axial plane x3 = R. Its cross-section is made of three patches mapped
by transfinite interpolation (see cross_section), extruded along x1; the mesh is graded towards the
contact line x2 = 0, the face and the roller's end x1 = L/2.
Groups: ``mid`` (x1 = 0, the roller's mid-plane), ``sym`` (x2 = 0), ``top`` (x3 = R), ``contact``
(the strip x2 <= 1.2 of the face), ``roller`` (the volume).
"""

from pathlib import Path

import meshio
import numpy as np

R, L, STRIP = 5.0, 20.0, 1.2
N_STRIP, N_REST, N_SIDE, N_UP, N_AX = 10, 4, 6, 7, 24
SQUARE = 0.45 * R      # the square [0, SQUARE] x [R - SQUARE, R] around the axis


def graded(n, ratio):
    """n + 1 points on [0, 1], each interval ``ratio`` times the previous one."""
    w = ratio ** np.arange(n)
    return np.r_[0.0, np.cumsum(w) / w.sum()]


def face(phi):
    """The point of the cylinder's face at angle phi from the bottom, in (x2, x3)."""
    return np.c_[R * np.sin(phi), R - R * np.cos(phi)]


def segment(p, q, t):
    return p + (q - p) * t[:, None]


def tfi(bottom, top, left, right):
    """Transfinite interpolation of a four-sided patch: (nu, nv, 2) from its sides (bottom, top
    along u; left, right along v, all oriented with increasing u and v)."""
    nu, nv = len(bottom), len(left)
    U, V = np.linspace(0, 1, nu)[:, None, None], np.linspace(0, 1, nv)[None, :, None]
    if nu > 1:     # arc-length parameters of the sides keep the grading
        lb = np.r_[0, np.cumsum(np.hypot(*np.diff(bottom, axis=0).T))]
        U = (lb / lb[-1])[:, None, None]
    ll = np.r_[0, np.cumsum(np.hypot(*np.diff(left, axis=0).T))]
    V = (ll / ll[-1])[None, :, None]
    A, B, C, D = bottom[0], bottom[-1], top[-1], top[0]
    return ((1 - V) * bottom[:, None] + V * top[:, None] + (1 - U) * left[None] + U * right[None]
            - ((1 - U) * (1 - V) * A + U * (1 - V) * B + U * V * C + (1 - U) * V * D))


def cross_section():
    """Points (m, 2) and quadrilaterals (k, 4) of the cross-section in (x2, x3).

    Three patches: a square around the axis, and between it and the face a lower patch (the face
    from the contact line to 45°, graded towards the contact line, with the strip's edge x2 = STRIP
    a node line) and a side patch (the face from 45° to the axial plane)."""
    pc, pb = np.arcsin(STRIP / R), np.pi / 4
    phi1 = np.r_[pc * graded(N_STRIP, 1.08), pc + (pb - pc) * graded(N_REST, 1.15)[1:]]
    phi2 = pb + (np.pi / 2 - pb) * np.linspace(0, 1, N_SIDE + 1)
    v = graded(N_UP, 1.15)
    s = SQUARE
    P, Q, T, D = np.array([0, R - s]), np.array([s, R - s]), np.array([s, R]), np.array([0, R])
    u1 = phi1 / pb                                  # the square's edges follow the face's grading
    u2 = (phi2 - pb) / (np.pi / 2 - pb)
    lower = tfi(face(phi1), segment(P, Q, u1), segment(face(phi1[:1])[0], P, v), segment(face(phi1[-1:])[0], Q, v))
    side = tfi(face(phi2), segment(Q, T, u2), segment(face(phi2[:1])[0], Q, v), segment(face(phi2[-1:])[0], T, v))
    square = tfi(segment(P, Q, u1), segment(D, T, u1), segment(P, D, u2), segment(Q, T, u2))
    pts, quads = [], []
    for g in (lower, side, square):
        base = sum(len(p) for p in pts)
        nu, nv = g.shape[:2]
        i = base + np.arange(nu * nv).reshape(nu, nv)
        pts.append(g.reshape(-1, 2))
        quads.append(np.c_[i[:-1, :-1].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel(), i[:-1, 1:].ravel()])
    pts, quads = np.vstack(pts), np.vstack(quads)
    key = np.round(pts / R, 9)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return pts[first], inverse.reshape(-1)[quads]


def main(path=None):
    path = path or Path(__file__).with_name("roller.msh")
    xy, quads = cross_section()
    m = len(xy)
    x1 = (L / 2) * (1.0 - graded(N_AX, 1.06)[::-1])           # finer towards the end x1 = L/2
    pts = np.c_[np.repeat(x1, m), np.tile(xy, (x1.size, 1))]
    layer = (np.arange(N_AX) * m)[:, None, None]
    hexes = np.concatenate([layer + quads, layer + m + quads], axis=2).reshape(-1, 8)
    # boundary faces: the hexahedra's faces that occur once, named by where they lie
    local = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])
    faces = hexes[:, local].reshape(-1, 4)
    _, first, count = np.unique(np.sort(faces, axis=1), axis=0, return_index=True, return_counts=True)
    bnd = faces[first[count == 1]]
    c = pts[bnd]                                               # (k, 4, 3)
    tol = 1e-9 * R
    on_face = np.all(np.abs(np.hypot(c[..., 1], c[..., 2] - R) - R) < 1e-6 * R, axis=1)
    groups = {"mid": bnd[np.all(c[..., 0] < tol, axis=1)],
              "sym": bnd[np.all(c[..., 1] < tol, axis=1)],
              "top": bnd[np.all(c[..., 2] > R - tol, axis=1)],
              "contact": bnd[on_face & np.all(c[..., 1] < STRIP + tol, axis=1)]}
    blocks, phys, fd = [], [], {}
    for tag, (name, q) in enumerate(groups.items(), start=1):
        blocks.append(("quad", q))
        phys.append(np.full(len(q), tag))
        fd[name] = np.array([tag, 2])
    blocks.append(("hexahedron", hexes))
    phys.append(np.full(len(hexes), 9))
    fd["roller"] = np.array([9, 3])
    meshio.write(path, meshio.Mesh(pts, blocks, cell_data={"gmsh:physical": phys, "gmsh:geometrical": phys},
                                   field_data=fd), file_format="gmsh22", binary=False)
    return path


if __name__ == "__main__":
    print(main())
