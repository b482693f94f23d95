"""The blade root and the slot of examples/dovetail.toml, hexahedra, as Gmsh files:

    python examples/dovetail/make_mesh.py      # writes blade.msh and slot.msh here

A dovetail joint in the x1–x3 plane, extruded along x2 (0 ≤ x2 ≤ 0.5): the blade's root is the
trapezoid of half-width 1 at x3 = 0 and 0.5 at x3 = 0.5, its flanks x1 = ±(1 − x3) at 45°, under a neck
of half-width 0.5 up to x3 = 1; the slot is the block [−2, 2] × [0, 0.5] × [−1, 0.5] less the
trapezoid continued down to its floor x3 = −0.25 (a clearance under the blade). Both meshes are
mirror-symmetric about x1 = 0, and the flanks' nodes coincide (point partners node to node).
Groups: blade — flank_left, flank_right, top; slot — flank_left, flank_right (x3 ≥ 0, the part the
blade's flanks meet), bottom.
"""

import sys
from pathlib import Path

import meshio
import numpy as np

HERE = Path(__file__).resolve().parent
WB, WT, H, NECK, LENGTH = 1.0, 0.5, 0.5, 1.0, 0.5       # root half-widths, root height, neck top, x2 length
WIDTH, DEPTH, CLEAR = 2.0, 1.0, 0.25                    # the slot block's half-width and depth, the clearance


def half_width(x3):
    """The flank's half-width at height x3 (continued below the root into the clearance)."""
    return np.where(x3 <= H, WB - (WB - WT) * x3 / H, WT)


def _grid(x1, x3, ny):
    """Points (i, j, k) → x of a mapped grid: x1 (n1, n3) per (i, k), x3 (n3,), x2 uniform; and its hexahedra."""
    n1, n3 = x1.shape
    x2 = np.linspace(0.0, LENGTH, ny + 1)
    i, j, k = np.meshgrid(np.arange(n1), np.arange(ny + 1), np.arange(n3), indexing="ij")
    pts = np.column_stack([x1[i, k].ravel(), x2[j].ravel(), x3[k].ravel()])
    idx = np.arange(pts.shape[0]).reshape(n1, ny + 1, n3)
    a = idx[:-1, :-1, :-1], idx[1:, :-1, :-1], idx[1:, 1:, :-1], idx[:-1, 1:, :-1]
    b = idx[:-1, :-1, 1:], idx[1:, :-1, 1:], idx[1:, 1:, 1:], idx[:-1, 1:, 1:]
    return pts, np.column_stack([c.ravel() for c in a + b]), idx


def _merge(blocks):
    """One mesh of several grids: their coinciding nodes merged."""
    pts = np.vstack([p for p, _ in blocks])
    offs = np.cumsum([0] + [p.shape[0] for p, _ in blocks])
    cells = np.vstack([c + o for (_, c), o in zip(blocks, offs)])
    _, first, inverse = np.unique(np.round(pts, 9), axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)                      # the merged nodes in the order they first occur
    rank = np.empty(first.size, int)
    rank[order] = np.arange(first.size)
    new = rank[inverse.ravel()]
    return pts[first[order]], new[cells]


def _faces(cells, pts, select):
    """The boundary quads of the hexahedra whose four nodes all satisfy ``select(x)``."""
    local = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    quads = np.vstack([cells[:, f] for f in local])
    key = np.sort(quads, axis=1)
    _, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    boundary = quads[count[inv.ravel()] == 1]
    ok = np.all(select(pts[boundary]), axis=1)
    return boundary[ok]


def _write(path, pts, cells, groups, name):
    blocks = [("quad", f) for f in groups.values()] + [("hexahedron", cells)]
    phys = [np.full(len(b[1]), t) for t, b in enumerate(blocks, start=1)]
    fd = {n: np.array([t, 2]) for t, n in enumerate(groups, start=1)} | {name: np.array([len(blocks), 3])}
    meshio.write(path, meshio.Mesh(pts, blocks, cell_data={"gmsh:physical": phys}, field_data=fd),
                 file_format="gmsh22", binary=False)
    return path


def blade(nx=8, nz=8, nneck=4, ny=2):
    x3 = np.r_[np.linspace(0.0, H, nz + 1), np.linspace(H, NECK, nneck + 1)[1:]]
    s = np.linspace(-1.0, 1.0, nx + 1)
    pts, cells, _ = _grid(s[:, None] * half_width(x3)[None, :], x3, ny)
    tol = 1e-9
    groups = {
        "flank_left": _faces(cells, pts, lambda x: (np.abs(x[..., 0] + half_width(x[..., 2])) < tol) & (x[..., 2] <= H + tol)),
        "flank_right": _faces(cells, pts, lambda x: (np.abs(x[..., 0] - half_width(x[..., 2])) < tol) & (x[..., 2] <= H + tol)),
        "top": _faces(cells, pts, lambda x: np.abs(x[..., 2] - NECK) < tol),
    }
    return pts, cells, groups


def slot(nside=6, nz=8, nclear=2, nopen=8, ndepth=3, ny=2):
    x3 = np.r_[np.linspace(-CLEAR, 0.0, nclear + 1), np.linspace(0.0, H, nz + 1)[1:]]
    u = np.linspace(0.0, 1.0, nside + 1)
    hw = half_width(x3)
    right = hw[None, :] + (WIDTH - hw[None, :]) * u[:, None]
    grids = [_grid(right, x3, ny)[:2], _grid(-right[::-1], x3, ny)[:2]]
    b = right[:, 0]
    x1 = np.r_[-b[::-1], np.linspace(-b[0], b[0], nopen + 1)[1:-1], b]
    z = np.linspace(-DEPTH, -CLEAR, ndepth + 1)
    grids.append(_grid(np.repeat(x1[:, None], z.size, axis=1), z, ny)[:2])
    pts, cells = _merge(grids)
    tol = 1e-9
    groups = {
        "flank_left": _faces(cells, pts, lambda x: (np.abs(x[..., 0] + half_width(x[..., 2])) < tol) & (x[..., 2] >= -tol)),
        "flank_right": _faces(cells, pts, lambda x: (np.abs(x[..., 0] - half_width(x[..., 2])) < tol) & (x[..., 2] >= -tol)),
        "bottom": _faces(cells, pts, lambda x: np.abs(x[..., 2] + DEPTH) < tol),
    }
    return pts, cells, groups


def main(out=HERE):
    out = Path(out)
    return [_write(out / "blade.msh", *blade(), "blade"), _write(out / "slot.msh", *slot(), "slot")]


if __name__ == "__main__":
    for p in main(*sys.argv[1:2]):
        print("wrote", p)
