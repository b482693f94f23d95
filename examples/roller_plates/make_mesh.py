"""The meshes of examples/roller_plates.toml: a roller between two plates, a half model in plane strain.

    python examples/roller_plates/make_mesh.py     # writes roller.msh, lower.msh, upper.msh here

The roller (radius R, axis along x2 through (0, ·, R)) is the half x1 ≥ 0 of its cross-section, one
element long in x2 (u2 = 0 on both ends: plane strain), meshed as two quarters of the cross-section
of examples/roller_rigid/make_mesh.py, mirrored about the axial plane x3 = R. The plates are boxes
x1 in [0, W], graded towards the contact lines: ``lower`` below x3 = 0, ``upper`` above x3 = 2R.
Groups of the roller: ``lower`` and ``upper`` (the strips |x1| ≤ STRIP of its face at the bottom and
the top), ``face`` (both), ``sym`` (x1 = 0), ``ends`` (x2 = 0 and x2 = LEN), ``roller`` (the volume).
Groups of a plate: ``top``, ``bottom``, ``sym``, ``ends``, ``plate``.
"""

import importlib.util
import sys
from pathlib import Path

import meshio
import numpy as np

HERE = Path(__file__).parent
R, LEN, W, H = 10.0, 0.25, 12.0, 12.0


def _quarter(n_strip):
    """The cross-section of a quarter (x1, x3 − R ≤ 0 in the file's (x2, x3)) of a roller of radius R."""
    spec = importlib.util.spec_from_file_location("roller_quarter", HERE.parent / "roller_rigid" / "make_mesh.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    mod.R, mod.STRIP, mod.N_STRIP, mod.SQUARE = R, 1.5, n_strip, 0.45 * R
    graded = mod.graded
    mod.graded = lambda n, ratio: np.linspace(0.0, 1.0, n + 1) if n == n_strip else graded(n, ratio)
    return mod.cross_section()                 # the strip's elements of equal size


def graded(fine_h, fine, length, growth=1.2):
    x = list(np.arange(0.0, fine + 0.5 * fine_h, fine_h))
    step = fine_h
    while x[-1] < length:
        step *= growth
        x.append(min(x[-1] + step, length))
    if length - x[-2] < 0.5 * step:
        x.pop(-2)
    return np.array(x)


def extrude(xz, quads):
    """Hexahedra one element long in x2 over the cross-section (x1, x3) points and quadrilaterals."""
    m = len(xz)
    pts = np.vstack([np.c_[xz[:, 0], np.full(m, y), xz[:, 1]] for y in (0.0, LEN)])
    q = quads
    # the quadrilateral (x1, x3) oriented counter-clockwise seen from −x2 gives positive hexahedra
    hexes = np.c_[q[:, [0, 3, 2, 1]], q[:, [0, 3, 2, 1]] + m]
    vol = _volumes(pts, hexes)
    hexes[vol < 0] = np.c_[q[vol < 0], q[vol < 0] + m]
    return pts, hexes


def _volumes(pts, hexes):
    c = pts[hexes]
    return np.einsum("ij,ij->i", c[:, 1] - c[:, 0], np.cross(c[:, 3] - c[:, 0], c[:, 4] - c[:, 0]))


def boundary(hexes):
    local = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])
    faces = hexes[:, local].reshape(-1, 4)
    _, first, count = np.unique(np.sort(faces, axis=1), axis=0, return_index=True, return_counts=True)
    return faces[first[count == 1]]


def write(path, pts, hexes, groups, volume):
    blocks, phys, fd = [], [], {}
    for tag, (name, q) in enumerate(groups.items(), start=1):
        blocks.append(("quad", q))
        phys.append(np.full(len(q), tag))
        fd[name] = np.array([tag, 2])
    blocks.append(("hexahedron", hexes))
    phys.append(np.full(len(hexes), 99))
    fd[volume] = np.array([99, 3])
    meshio.write(path, meshio.Mesh(pts, blocks, cell_data={"gmsh:physical": phys, "gmsh:geometrical": phys},
                                   field_data=fd), file_format="gmsh22", binary=False)


def roller(n_strip, strip):
    yz, quads = _quarter(n_strip)               # (x2, x3) of the quarter below the axis: our (x1, x3)
    up = np.c_[yz[:, 0], 2 * R - yz[:, 1]]
    xz = np.vstack([yz, up])
    q = np.vstack([quads, quads[:, ::-1] + len(yz)])
    key = np.round(xz / R, 9)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    xz, q = xz[first], inverse.reshape(-1)[q]
    pts, hexes = extrude(xz, q)
    bnd = boundary(hexes)
    c = pts[bnd]
    tol = 1e-9 * R
    on_face = np.all(np.abs(np.hypot(c[..., 0], c[..., 2] - R) - R) < 1e-6 * R, axis=1)
    near = np.all(c[..., 0] < strip + tol, axis=1)
    low, high = on_face & near & np.all(c[..., 2] < R, axis=1), on_face & near & np.all(c[..., 2] > R, axis=1)
    groups = {"lower": bnd[low], "upper": bnd[high], "face": bnd[low | high],
              "sym": bnd[np.all(c[..., 0] < tol, axis=1)],
              "ends": bnd[np.all((c[..., 1] < tol) | (c[..., 1] > LEN - tol), axis=1)]}
    return pts, hexes, groups


def plate(h, below: bool):
    x1 = graded(h, 1.5, W)
    x3 = graded(h, 0.5, H)
    z = -x3[::-1] if below else 2 * R + x3
    X1, X3 = np.meshgrid(x1, z, indexing="ij")
    xz = np.c_[X1.ravel(), X3.ravel()]
    n1, n3 = x1.size, z.size
    i = np.arange(n1 * n3).reshape(n1, n3)
    q = np.c_[i[:-1, :-1].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel(), i[:-1, 1:].ravel()]
    pts, hexes = extrude(xz, q)
    bnd = boundary(hexes)
    c = pts[bnd]
    tol = 1e-9 * W
    groups = {"top": bnd[np.all(np.abs(c[..., 2] - z.max()) < tol, axis=1)],
              "bottom": bnd[np.all(np.abs(c[..., 2] - z.min()) < tol, axis=1)],
              "sym": bnd[np.all(c[..., 0] < tol, axis=1)],
              "ends": bnd[np.all((c[..., 1] < tol) | (c[..., 1] > LEN - tol), axis=1)]}
    return pts, hexes, groups


def main(out=HERE, n_strip=20, h=0.075, strip=1.5):
    """Writes the three meshes into ``out``: ``n_strip`` elements on the roller's contact strips, ``h``
    the plates' element size near the contact lines."""
    out = Path(out)
    write(out / "roller.msh", *roller(n_strip, strip), "roller")
    write(out / "lower.msh", *plate(h, True), "plate")
    write(out / "upper.msh", *plate(h, False), "plate")
    return out


if __name__ == "__main__":
    print(main(*sys.argv[1:2]))
