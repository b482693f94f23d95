"""The morph weight w (docs/theory.md): a discrete harmonic extension on the reference mesh.

    −Δw = 0 in Ω_ref,   w = 1 on the contact face,   w = 0 on the parts fixed in shape,
    ∂w/∂n = 0 elsewhere,

discretised with the body's own elements (the scalar Laplacian ∫∇φ_a·∇φ_b with the element's
shape functions and quadrature) and solved once: by a sparse direct solve up to
``DIRECT_MAX_NODES`` free nodes, above by conjugate gradients with a smoothed-aggregation AMG
preconditioner (pyamg) to a relative residual of 1e-12 — a direct solve of a 3-D Laplacian grows
much faster than the mesh without MKL PARDISO (SciPy's SuperLU: 97 s at 125k nodes, where the
full-space path itself needs no factorization). A function that is
linear in x3 is discretely harmonic, so on the block (w = 1 on x3 = 0, w = 0 on x3 = c, natural
conditions on the sides) w = 1 − x3/c exactly: the paper's vertical map. Round-off (and, on
meshes without a discrete maximum principle, overshoot) is clipped to [0, 1].
"""

from __future__ import annotations

import logging

import numpy as np
import pyamg

from ..errors import MeshError
from ..mesh.block import block_mesh
from ..mesh.hexmesh import HexMesh
from ..mesh.morph import JacobianRatio
from .elasticity import ElasticityAssembler, element_geometry, hex_reference

log = logging.getLogger(__name__)

DIRECT_MAX_NODES = 50_000        # free nodes up to which w is computed by a direct solve
CG_RTOL = 1e-12


def harmonic_weight(assembler, coords, one_nodes, zero_nodes) -> np.ndarray:
    """w (n_nodes,) with w = 1 on ``one_nodes``, 0 on ``zero_nodes``, discretely harmonic elsewhere
    (the scalar Laplacian of ``assembler``'s elements on the reference ``coords``).

    Nodes in no element get w = 0. With no ``zero_nodes`` the solution is w = 1 (a rigid lift)."""
    from .linsolve import factorize
    n = coords.shape[0]
    used = np.zeros(n, bool)
    used[assembler.elements.ravel()] = True
    one = np.zeros(n, bool)
    one[one_nodes] = True
    zero = np.zeros(n, bool)
    zero[zero_nodes] = True
    if np.any(one & zero):
        clash = np.flatnonzero(one & zero)
        raise MeshError(f"{clash.size} node(s) of the contact face lie on a part fixed in shape "
                        f"(first: {clash[:5].tolist()}); the face cannot move there")
    out = np.zeros(n)
    out[one] = 1.0
    free = np.flatnonzero(used & ~one & ~zero)
    if free.size == 0:
        return out
    K = assembler.scalar_laplacian(coords)
    Kff = K[free][:, free].tocsr()
    rhs = -(K[free][:, np.flatnonzero(one)] @ np.ones(int(one.sum())))
    if not np.any(zero):
        out[free] = 1.0
        return out
    if free.size <= DIRECT_MAX_NODES:
        with factorize(Kff) as fac:
            out[free] = fac.solve(rhs)
    else:
        out[free] = _amg_cg(Kff, rhs)
    over = max(out.max() - 1.0, -out.min(), 0.0)
    if over > 1e-9:
        log.warning("the harmonic morph weight leaves [0, 1] by %.2e on this mesh (no discrete maximum "
                    "principle); it is clipped", over)
    return np.clip(out, 0.0, 1.0)


def _amg_cg(K, rhs) -> np.ndarray:
    """K⁻¹ rhs by AMG-preconditioned CG (K the SPD Laplacian on the free nodes), seeded so that
    the same mesh gives the same w bit for bit."""
    saved = np.random.get_state()
    np.random.seed(20090101)
    try:
        ml = pyamg.smoothed_aggregation_solver(K.tocsr(), symmetry="symmetric")
    finally:
        np.random.set_state(saved)
    res = []
    x = ml.solve(rhs, tol=CG_RTOL, accel="cg", maxiter=500, residuals=res)
    if not res[-1] <= CG_RTOL * max(res[0], 1e-300) * 10:
        raise MeshError(f"the morph weight's CG did not converge (relative residual "
                        f"{res[-1] / res[0]:.1e} after {len(res) - 1} iterations)")
    log.debug("morph weight by AMG-CG: %d iterations, relative residual %.1e", len(res) - 1,
              res[-1] / res[0])
    return x


def block_hexmesh(nx: int, ny: int, nz: int, surface, c: float):
    """The paper's block [0, a]×[0, b]×[0, c] as a :class:`~contactopt.mesh.hexmesh.HexMesh` on
    its own (without a configuration): its weight is the harmonic extension of 1 on the contact
    face and 0 on the top, and designs that invert an element are refused (``mesh.ratio``)."""
    ref = block_mesh(surface.a, surface.b, c, nx, ny, nz)
    laplace = ElasticityAssembler(ref.cells, ref.n_nodes, [], 1.0, 0.0)   # its scalar Laplacian only
    weight = harmonic_weight(laplace, ref.points, ref.parts["contact"].nodes, ref.parts["top"].nodes)
    mesh = HexMesh(nx, ny, nz, surface, c, reference=ref, weight=weight)
    G, _ = element_geometry(ref.points[ref.cells], hex_reference()[1])
    mesh.ratio = JacobianRatio(ref.cells, G[..., 2], mesh.dx3_dalpha(), 0.0,
                               qpoints=ref.points[ref.cells].mean(axis=1),
                               fixed_parts={"top": ref.parts["top"].nodes})
    return mesh
