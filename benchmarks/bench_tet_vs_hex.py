"""Tetrahedra against hexahedra on the paper's block: λ under refinement.

    python benchmarks/bench_tet_vs_hex.py [--levels 3]

The block [0,2]×[0,1]×[0,1] of Example 1 (its loads, material, friction and α0) on structured
grids nx×ny×nz = (8,4,4)·2^k, k = 0..levels−1, once as Q1 hexahedra and once as the same grid
split into six linear tetrahedra per cube (P1). Both meshes have the same
contact nodes, so their normal contact forces λ compare node by node. The table gives the
total normal force, the relative difference ‖λ_tet − λ_hex‖/‖λ_hex‖ and the contact stresses'
largest difference; both discretisations converge to the same λ, so the differences fall with
h (linear tetrahedra are stiffer, and the gap closes at first order).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import meshio
import numpy as np

from contactopt.config import load_config
from contactopt.mesh.block import block_mesh
from contactopt.mesh.tetsplit import hex_to_tets, quads_to_triangles
from contactopt.problem import ShapeProblem

FACES = ("clamped", "top", "right", "contact")


def block_file(path: Path, nx, ny, nz, cell):
    """The block as a Gmsh 2.2 file of hexahedra or tetrahedra with the named face groups."""
    ref = block_mesh(2.0, 1.0, 1.0, nx, ny, nz)
    pts, cells, kind = ref.points, ref.cells, "hexahedron"
    if cell == "tetra":
        cells, kind = hex_to_tets(ref.cells), "tetra"
    blocks, tags, fd = [], [], {}
    for t, name in enumerate(FACES, start=1):
        blocks.append(("quad", ref.parts[name].faces))
        tags.append(np.full(len(ref.parts[name].faces), t))
        fd[name] = np.array([t, 2])
    if kind != "hexahedron":           # face groups as the boundary triangles of the split
        blocks = [("triangle", quads_to_triangles(q, cells)) for _, q in blocks]
        tags = [np.concatenate([t, t]) for t in tags]
    blocks.append((kind, cells))
    tags.append(np.full(len(cells), 9))
    fd["body"] = np.array([9, 3])
    meshio.write(path, meshio.Mesh(pts, blocks, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                                   field_data=fd), file_format="gmsh22", binary=True)


def solve(tmp: Path, nx, ny, nz, cell):
    block_file(tmp / f"{cell}.msh", nx, ny, nz, cell)
    base = load_config("example1").data
    data = {k: v for k, v in base.items() if k not in ("geometry", "mesh")}
    data["body"] = {**base["body"], "mesh": str(tmp / f"{cell}.msh")}
    data["loads"] = {"body_force": [0.0, 0.0, 0.0],
                     "traction": [{"on": "top", "value": base["loads"]["top_traction"]},
                                  {"on": "right", "value": base["loads"]["right_traction"]}]}
    pr = ShapeProblem(load_config(data))
    t0 = time.perf_counter()
    st = pr.solve_state(pr.model.initial_design())
    xy = pr.model.mesh.contact_points()
    order = np.lexsort(xy.T[::-1])
    return st.lam[order], pr.model.contact_areas()[order], pr.model.mesh.n_nodes, time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--levels", type=int, default=3)
    args = ap.parse_args()
    print(f"{'grid':>10} {'nodes':>7} {'Σλ hex':>10} {'Σλ tet':>10} {'‖Δλ‖/‖λ‖':>10} {'max Δσ/max σ':>12}")
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.levels):
            n = (8 * 2 ** k, 4 * 2 ** k, 4 * 2 ** k)
            lh, ah, nn, _ = solve(Path(tmp), *n, "hexahedron")
            lt, at, _, _ = solve(Path(tmp), *n, "tetra")
            sh, stt = lh / ah, lt / at
            print(f"{'×'.join(map(str, n)):>10} {nn:>7} {lh.sum():>10.5g} {lt.sum():>10.5g} "
                  f"{np.linalg.norm(lt - lh) / np.linalg.norm(lh):>10.3e} "
                  f"{np.abs(stt - sh).max() / np.abs(sh).max():>12.3e}")


if __name__ == "__main__":
    main()
