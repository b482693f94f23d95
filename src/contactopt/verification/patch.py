"""The contact patch test on an elastic foundation (Taylor & Papadopoulos), overlap loading.

Two blocks of one material on the unit square [0, 1]²: the body (height 1) over the foundation
(height 0.5, top face on x3 = 0), pressed together by the constant design −d (the body's contact
face at x3 = −d). The body's top is held in x3, the foundation's bottom in x3; both are held in
x1 on x1 = 0 and in x2 on x2 = 0 away from the contact face (symmetry planes the exact state
respects; on the contact face itself the foundation does not take clamped tangential
components). The exact state is uniaxial stress in both blocks: the contact pressure

    p = E d / (h + H_f)        (h the body's height in Ω(α), H_f = 0.5)

on the whole interface, and no shear: one material, the same lateral strain ν p / E on both
sides, so no slip. A discretization that passes carries λ_m = p a_m at every contact node
(a_m = ∫ N_m dA) and τ_m = 0, whatever the meshes on either side.

Per contact node the order is (t1, t2, ν) = (x1, x2, x3); λ = r_ν ≥ 0 is the normal force on
the body, τ = −r_t.
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np

from ..config import load_config
from ..io.pressure import contact_areas
from ..mesh.block import block_mesh, graded_block_mesh
from ..mesh.foundation import foundation_block
from ..mesh.tetsplit import hex_to_tets, tet4_to_tet10

__all__ = ["H_BODY", "H_FOUNDATION", "OVERLAP", "exact_pressure", "patch_config"]

H_BODY, H_FOUNDATION, OVERLAP = 1.0, 0.5, 0.01
E, NU = 21.19, 0.277


def _write(path: Path, points, cells, ctype: str) -> str:
    meshio.write(path, meshio.Mesh(points, [(ctype, cells)]))
    return str(path)


def patch_config(body_cells: int, foundation_cells: int, friction: float, directory, *,
                 body: str = "hexahedron", foundation: str = "hexahedron", partner: str = "auto"):
    """The configuration of the test (module docstring): the body body_cells² × 2 (``body``
    'hexahedron' or 'tetra': each hexahedron split into six), the foundation foundation_cells² × 2
    (``foundation`` 'hexahedron', 'tetra', 'tetra10' or 'offset': hexahedra whose node lines lie half
    a cell from a uniform grid's), ``partner`` as ``[foundation] partner``. Mesh files are written
    to ``directory``."""
    directory = Path(directory)
    n = body_cells
    raw = {"name": "patch", "material": {"E": E, "nu": NU}, "friction": {"coefficient": friction},
           "design": {"degree": [1, 1], "lower": -1.0, "nonnegative_gap": False, "initial": -OVERLAP, "C2": 0.0},
           "objective": {"type": "compliance"}, "state": {"method": "newton", "tol": 1e-13}}
    clamps = [{"on": {"box": [[-1e-6, 1e-6], [-1, 2], [0.25, 2]]}, "components": [1]},
              {"on": {"box": [[-1, 2], [-1e-6, 1e-6], [0.25, 2]]}, "components": [2]},
              {"on": {"x3": H_BODY}, "components": [3]}]
    raw["body"] = {"clamped": clamps}
    if body in ("tetra", "tetra10"):
        ref = block_mesh(1.0, 1.0, H_BODY, n, n, 2)
        pts, cells = ref.points, hex_to_tets(ref.cells, ref.points)
        if body == "tetra10":
            pts, cells = tet4_to_tet10(pts, cells)
        raw["body"].update(mesh=_write(directory / "patch_body.vtu", pts, cells, body), contact={"x3": 0.0})
    else:
        raw.update(geometry={"a": 1.0, "b": 1.0, "c": H_BODY}, mesh={"nx": n, "ny": n, "nz": 2},
                   loads={"top_traction": [0.0, 0.0, 0.0], "right_traction": [0.0, 0.0, 0.0]})
    f = {"clamped": [{"on": "bottom", "components": [3]}, {"on": "left", "components": [1]},
                     {"on": "front", "components": [2]}], "partner": partner}
    m = foundation_cells
    if foundation in ("tetra10", "offset"):
        if foundation == "offset":
            x = [0.0, *((np.arange(m) + 0.5) / m)[:-1], 1.0]
            ref = graded_block_mesh(x, x, [0.0, H_FOUNDATION / 2, H_FOUNDATION])
            f["mesh"] = _write(directory / "patch_foundation.vtu", ref.points - [0.0, 0.0, H_FOUNDATION],
                               ref.cells, "hexahedron")
        else:
            ref = foundation_block([1.0, 1.0, H_FOUNDATION], [m, m, 2], [0.0, 0.0], "tetra")
            p10, c10 = tet4_to_tet10(ref.points, ref.cells)
            f["mesh"] = _write(directory / "patch_foundation.vtu", p10, c10, "tetra10")
        f["top"] = {"x3": 0.0}
        f["clamped"] = [{"on": {"x3": -H_FOUNDATION}, "components": [3]}, {"on": {"x1": 0.0}, "components": [1]},
                        {"on": {"x2": 0.0}, "components": [2]}]
    else:
        f["block"] = {"size": [1.0, 1.0, H_FOUNDATION], "cells": [m, m, 2], "origin": [0.0, 0.0],
                      "element": foundation}
    raw["foundation"] = f
    return load_config(raw)


def exact_pressure(coords: np.ndarray, contact_nodes: np.ndarray) -> float:
    """p = E d / (h + H_f) from the body's coordinates in Ω(α) (module docstring)."""
    d = -float(coords[contact_nodes, 2].mean())
    return E * d / (float(np.ptp(coords[:, 2])) + H_FOUNDATION)


def node_areas(problem) -> np.ndarray:
    """a_m = ∫ N_m dA of the contact nodes on the reference face, or ∫ N̂_m dA = (T a)_m in the
    transformed basis of six-node triangles with mortar partners (:mod:`contactopt.fem.mortar`),
    where the state's forces are the transformed ones: λ_m = p a_m under a uniform pressure p."""
    b = problem.model.body
    area = contact_areas(b.reference.points, b.contact_face.faces, b.contact_nodes)
    f = problem.model.foundation
    return area if f is None or f.basis is None else f.basis @ area


def patch_errors(problem, state) -> dict:
    """max and rms of (λ/a − p)/p and max ‖τ‖/(a p) over the contact nodes of a solved state."""
    b = problem.model.body
    area = node_areas(problem)
    p = exact_pressure(state.coords, b.contact_nodes)
    e = state.lam / area / p - 1.0
    return {"max": float(np.abs(e).max()), "rms": float(np.sqrt(np.mean(e ** 2))),
            "shear": float((np.linalg.norm(state.tau, axis=1) / (area * p)).max())}
