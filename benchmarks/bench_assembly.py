"""Stiffness assembly by element type on one node set: P1 and P2 tetrahedra against Q1 hexahedra.

    python benchmarks/bench_assembly.py [--n 48] [--reps 7] [--blocks]

The unit cube on an n³ grid of cubes (n = 48: 117 649 nodes), clamped on x3 = 0, as Q1
hexahedra, as the same grid split into six P1 tetrahedra per cube (Kuhn split), and as P2
tetrahedra on the n/2 grid (the same 117 649 nodes when n is even: the midside nodes of the
coarse grid are the nodes of the fine one). Each row times ``ElasticityAssembler.stiffness``
at new designs (the morph x3 + ϑ(x1, x2)(1 − x3) with a different ϑ per repetition), the
pattern built once beforehand, median over the repetitions. Ratios are to references measured
in the same run, because absolute times on a shared machine drift:

- ``/ matvec``: one product A @ x of SciPy's CSR with the same matrix;
- ``/ Q1``: the Q1 assembly of the same nodes.

``--blocks`` adds the P1 row assembled through the generic element-block path (12×12 element
matrices scattered onto the CSR by ``np.bincount``) instead of the node-pair path; it needs
several GB of memory at n = 48.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from contactopt.fem.elasticity import ElasticityAssembler
from contactopt.mesh.block import block_mesh
from contactopt.mesh.tetsplit import hex_to_tets, tet4_to_tet10

E, NU = 21.19, 0.277


def morph(points: np.ndarray, r: int) -> np.ndarray:
    """A design: the cube's bottom lifted by a smooth surface that changes with r."""
    X = points.copy()
    th = 0.02 * (1 + r % 5) * np.sin((2 + r) * X[:, 0]) * np.cos((1 + r) * X[:, 1])
    X[:, 2] += np.abs(th) * (1.0 - X[:, 2])
    return X


def meshes(n: int):
    ref = block_mesh(1.0, 1.0, 1.0, n, n, n)
    yield "Q1 hexahedra", ref.points, ref.cells, "hexahedron"
    yield "P1 tetrahedra", ref.points, hex_to_tets(ref.cells, ref.points), "tetra"
    coarse = block_mesh(1.0, 1.0, 1.0, n // 2, n // 2, n // 2)
    p10, c10 = tet4_to_tet10(coarse.points, hex_to_tets(coarse.cells, coarse.points))
    yield "P2 tetrahedra", p10, c10, "tetra10"


def time_stiffness(name, points, cells, kind, reps, blocks=False):
    fixed = (3 * np.flatnonzero(points[:, 2] < 1e-12)[:, None] + np.arange(3)).ravel()
    asm = ElasticityAssembler(cells, len(points), fixed, E, NU, element=kind)
    if blocks:
        asm._pairs = False                       # the generic path, for comparison
    t0 = time.perf_counter()
    A = asm.stiffness(morph(points, 0))          # builds the pattern
    setup = time.perf_counter() - t0
    ts = []
    for r in range(1, reps + 1):
        X = morph(points, r)
        t0 = time.perf_counter()
        A = asm.stiffness(X)
        ts.append(time.perf_counter() - t0)
    x = np.random.default_rng(0).standard_normal(A.shape[0])
    mv = []
    for _ in range(max(5, reps)):
        t0 = time.perf_counter()
        A @ x
        mv.append(time.perf_counter() - t0)
    return dict(name=name, elements=len(cells), nodes=len(points), dofs=A.shape[0], nnz=A.nnz,
                setup=setup, t=float(np.median(ts)), matvec=float(np.median(mv)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=48, help="cubes per edge of the Q1/P1 grid (even: P2 shares its nodes)")
    ap.add_argument("--reps", type=int, default=7)
    ap.add_argument("--blocks", action="store_true", help="also the P1 element-block path")
    args = ap.parse_args()
    rows = []
    for name, pts, cells, kind in meshes(args.n):
        rows.append(time_stiffness(name, pts, cells, kind, args.reps))
        if args.blocks and kind == "tetra":
            rows.append(time_stiffness("P1, element blocks", pts, cells, kind, args.reps, blocks=True))
    q1 = rows[0]["t"]
    print(f"{'mesh':<20} {'elements':>9} {'nodes':>8} {'free DOFs':>9} {'nnz(A)':>10} {'pattern s':>9} "
          f"{'A(α) ms':>8} {'/ matvec':>8} {'/ Q1':>6}")
    for r in rows:
        print(f"{r['name']:<20} {r['elements']:>9} {r['nodes']:>8} {r['dofs']:>9} {r['nnz']:>10} {r['setup']:>9.2f} "
              f"{1e3 * r['t']:>8.1f} {r['t'] / r['matvec']:>8.1f} {r['t'] / q1:>6.2f}")


if __name__ == "__main__":
    main()
