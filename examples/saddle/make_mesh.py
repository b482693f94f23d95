"""The saddle of examples/saddle.toml as a Gmsh 2.2 file: a block 2 × 1 whose underside conforms
to a pipe of radius R = 1.5 (axis along x2 through x1 = 1), flat on top; hexahedra.

    python examples/saddle/make_mesh.py          # writes examples/saddle/saddle.msh

The underside is x3 = z(x1) = √(R² − (x1 − 1)²) − √(R² − 1) (0 at the ends, 0.382 in the middle),
the top flat at x3 = 0.882 (0.5 above the crest); groups: top, bottom (the contact face), ends (x1 = 0 and x1 = 2), saddle.
"""

from pathlib import Path

import meshio
import numpy as np

R, A, B = 1.5, 2.0, 1.0
NX, NY, NZ = 24, 4, 4


def underside(x1):
    return np.sqrt(R ** 2 - (x1 - 1.0) ** 2) - np.sqrt(R ** 2 - 1.0)


def main(path=None):
    path = path or Path(__file__).with_name("saddle.msh")
    top = underside(1.0) + 0.5
    i, j, k = np.meshgrid(np.arange(NX + 1), np.arange(NY + 1), np.arange(NZ + 1), indexing="ij")
    x1, x2, t = A * i / NX, B * j / NY, k / NZ
    z = underside(x1)
    pts = np.c_[x1.ravel(), x2.ravel(), (z + t * (top - z)).ravel()]
    idx = np.arange(pts.shape[0]).reshape(NX + 1, NY + 1, NZ + 1)
    a, b, c = np.meshgrid(np.arange(NX), np.arange(NY), np.arange(NZ), indexing="ij")
    a, b, c = a.ravel(), b.ravel(), c.ravel()
    hexes = np.c_[idx[a, b, c], idx[a + 1, b, c], idx[a + 1, b + 1, c], idx[a, b + 1, c],
                  idx[a, b, c + 1], idx[a + 1, b, c + 1], idx[a + 1, b + 1, c + 1], idx[a, b + 1, c + 1]]

    def quads(sl):
        q = idx[sl]
        return np.c_[q[:-1, :-1].ravel(), q[1:, :-1].ravel(), q[1:, 1:].ravel(), q[:-1, 1:].ravel()]
    groups = {"top": quads(np.s_[:, :, NZ]), "bottom": quads(np.s_[:, :, 0]),
              "ends": np.r_[quads(np.s_[0, :, :]), quads(np.s_[NX, :, :])]}
    blocks, phys, fd = [], [], {}
    for tag, (name, q) in enumerate(groups.items(), start=1):
        blocks.append(("quad", q))
        phys.append(np.full(len(q), tag))
        fd[name] = np.array([tag, 2])
    blocks.append(("hexahedron", hexes))
    phys.append(np.full(len(hexes), 9))
    fd["saddle"] = np.array([9, 3])
    meshio.write(path, meshio.Mesh(pts, blocks, cell_data={"gmsh:physical": phys, "gmsh:geometrical": phys},
                                   field_data=fd), file_format="gmsh22", binary=False)
    return path


if __name__ == "__main__":
    print(main())
