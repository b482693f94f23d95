"""The roller and the race of examples/roller_crowning.toml as Gmsh 2.2 files (hexahedra):

    python examples/roller/make_mesh.py   # writes examples/roller/roller.msh, roller_touch.msh and race.msh

A quarter model of a roller of radius R = 1 and length 4 on a race of the same material: the
roller's end region, x1 ∈ [0, 2] (x1 = 0 its middle, x1 = 2 its free end), x2 ∈ [0, 0.6] (x2 = 0
the plane through its axis), its underside the cylinder x3 = R − √(R² − x2²) − δ, its top
x3 = 0.6 held (the roller's core): roller.msh lowered by the interference δ = 0.002 into the race
(examples/roller_crowning_interference.toml), roller_touch.msh touching it along the line x2 = 0
(δ = 0: the race pressed by a force, examples/roller_crowning.toml). The race
x1 ∈ [0, 3] × x2 ∈ [0, 1.5] × x3 ∈ [−1, 0], its top on x3 = 0; the two meshes match under the
roller. Groups: roller: contact (underside), top, volume; race: top, bottom, volume. Both bodies
are fine near x2 = 0 and near the roller's end, where its pressure peaks.
"""

from pathlib import Path

import meshio
import numpy as np

R, DELTA, TOP = 1.0, 0.002, 0.6


def axis_nodes(parts):
    """Concatenated linspace pieces [(start, stop, cells), …] without repeated joints."""
    out = [parts[0][0]]
    for a, b, n in parts:
        out += list(np.linspace(a, b, n + 1)[1:])
    return np.asarray(out)


X1_ROLLER = axis_nodes([(0.0, 1.5, 6), (1.5, 1.9, 4), (1.9, 2.0, 4)])
X1_RACE = np.r_[X1_ROLLER, axis_nodes([(2.0, 2.1, 2), (2.1, 3.0, 3)])[1:]]
X2_ROLLER = axis_nodes([(0.0, 0.12, 6), (0.12, 0.6, 4)])
X2_RACE = np.r_[X2_ROLLER, axis_nodes([(0.6, 1.5, 3)])[1:]]
X3_ROLLER = axis_nodes([(0.0, 1.0, 4)])          # a parameter from the underside to the top
X3_RACE = axis_nodes([(-1.0, -0.2, 3), (-0.2, 0.0, 3)])


def hexes(n1, n2, n3):
    idx = np.arange(n1 * n2 * n3).reshape(n1, n2, n3)
    c = idx[:-1, :-1, :-1].ravel()
    d1, d2, d3 = n2 * n3, n3, 1
    return np.stack([c, c + d1, c + d1 + d2, c + d2, c + d3, c + d1 + d3, c + d1 + d2 + d3, c + d2 + d3], axis=1), idx


def faces_at(idx, k):
    """The quads of the layer x3-index k (outward orientation is taken from the cells by the reader)."""
    q = idx[:, :, k]
    return np.stack([q[:-1, :-1].ravel(), q[1:, :-1].ravel(), q[1:, 1:].ravel(), q[:-1, 1:].ravel()], axis=1)


def write(path, pts, cells, groups):
    blocks = [("quad", f) for f in groups.values()] + [("hexahedron", cells)]
    tags = [np.full(len(b[1]), t) for t, b in enumerate(blocks, start=1)]
    fd = {name: np.array([t, 2]) for t, name in enumerate(groups, start=1)}
    fd["volume"] = np.array([len(blocks), 3])
    meshio.write(path, meshio.Mesh(pts, blocks, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                                   field_data=fd), file_format="gmsh22", binary=False)


def main(directory=None):
    directory = Path(directory or Path(__file__).parent)
    x1, x2, s = np.meshgrid(X1_ROLLER, X2_ROLLER, X3_ROLLER, indexing="ij")
    cells, idx = hexes(X1_ROLLER.size, X2_ROLLER.size, X3_ROLLER.size)
    for name, delta in (("roller.msh", DELTA), ("roller_touch.msh", 0.0)):
        under = R - np.sqrt(R ** 2 - x2 ** 2) - delta
        pts = np.c_[x1.ravel(), x2.ravel(), (under + s * (TOP - under)).ravel()]
        write(directory / name, pts, cells, {"contact": faces_at(idx, 0), "top": faces_at(idx, -1)})
    x1, x2, x3 = np.meshgrid(X1_RACE, X2_RACE, X3_RACE, indexing="ij")
    pts = np.c_[x1.ravel(), x2.ravel(), x3.ravel()]
    cells, idx = hexes(X1_RACE.size, X2_RACE.size, X3_RACE.size)
    write(directory / "race.msh", pts, cells, {"top": faces_at(idx, -1), "bottom": faces_at(idx, 0)})


if __name__ == "__main__":
    main()
