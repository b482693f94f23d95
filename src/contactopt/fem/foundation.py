"""An elastic foundation under the body: partners Π, stiffness K_f and compliance C (issue #22).

The foundation (mesh and parts: :mod:`contactopt.mesh.foundation`) has its top face on x3 = 0.
Design moves are vertical, so contact node m of the body (reference (x1, x2)) has a fixed
partner: the point of the top face directly below it, with weights Π_m, the top face's shape
functions there (bilinear on quadrilaterals, linear/quadratic on triangles). The Coulomb law acts
on the relative displacement w_m = u_c,m − (Π u_f)_m of the body's node and its partner.

Contact convention (per contact node m, order (t1, t2, ν) = (x1, x2, x3)): r_m is the contact
force on the body, λ = r_ν ≥ 0, τ = −r_t; the foundation carries −r_m, spread by Π_m:
K_f u_f = f_f − Πᵀ r. With W_f the foundation's compliance on the DOFs of its top-face nodes
that carry partners (clamped components fixed) and q_f = (K_f⁻¹ f_f) there,

    Π u_f = Π q_f − C r,     C = Π W_f Πᵀ   (3p × 3p, symmetric positive semidefinite),

independent of the design α: computed once per run. Condensed with the body's S(α) u_c = ℓ + r,

    w = W r + S⁻¹ℓ − Π q_f,   W = S⁻¹ + C

(docs/foundation.md). The foundation carries no loads of its own yet: q_f = 0.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from ..errors import ConfigError
from ..mesh.foundation import build_foundation_mesh
from ..mesh.reference import FACE_CORNERS
from .dense import spd_inverse
from .elasticity import ElasticityAssembler
from .elements import element_type, face_type

log = logging.getLogger(__name__)

INSIDE_TOL = 1e-8     # reference-coordinate slack of "the point lies in the face"
NEWTON_STEPS = 30     # inverse of the bilinear map of a quadrilateral face


class Foundation:
    """The elastic foundation of a configuration (module docstring).

    Attributes: ``mesh`` (:class:`~contactopt.mesh.foundation.FoundationMesh`), ``assembler`` (on
    its free DOFs), ``support`` (top-face nodes carrying partners), ``Pi`` (3p × 3n_s sparse, per
    contact node (t1, t2, ν) and support node (x1, x2, x3)), ``partner_faces`` (p,), ``W_f``
    (on the free support DOFs), ``C`` (3p × 3p), ``q_f`` (3p,), ``condensation`` (of K_f onto the
    free support DOFs: the foundation's displacement for outputs)."""

    def __init__(self, cfg, contact_xy: np.ndarray, contact_nodes: np.ndarray, backend: str = "auto"):
        from .linsolve import condense
        self.mesh = fm = build_foundation_mesh(cfg, contact_xy)
        ref = fm.reference
        self.assembler = ElasticityAssembler(ref.cells, ref.n_nodes, fm.fixed_dofs, fm.E, fm.nu,
                                             element=element_type(ref.cell_type))
        faces, weights = locate_partners(ref.points, fm.top.faces, ref.face_type, contact_xy, contact_nodes,
                                         f"{cfg.source}: foundation.top")
        self.partner_faces = faces
        p = contact_xy.shape[0]
        nodes = fm.top.faces[faces]                              # (p, k) support nodes of each partner
        self.support = np.unique(nodes)
        self.Pi = _partner_matrix(nodes, weights, self.support, p)
        free = self.assembler.full_to_free[(3 * self.support[:, None] + np.arange(3)).ravel()]
        keep = free >= 0                                         # clamped components do not move
        self._support_free = free[keep]
        K = self.assembler.stiffness(ref.points)
        self.condensation = condense(K, self._support_free, backend=backend)
        self.W_f = spd_inverse(self.condensation.S)
        P = self.Pi.tocsc()[:, np.flatnonzero(keep)]
        PW = (P @ self.W_f)                                      # (3p, n) dense
        C = np.asarray((P @ PW.T).T)
        self.C = 0.5 * (C + C.T)
        self._P = P
        self.q_f = np.zeros(3 * p)
        log.info("elastic foundation %s: %d nodes, %d free DOFs, E = %g, nu = %g; %d top-face nodes carry "
                 "the partners of %d contact nodes", ref.source, ref.n_nodes, self.assembler.n_free, fm.E, fm.nu,
                 self.support.size, p)

    @property
    def n_nodes(self) -> int:
        return self.mesh.reference.n_nodes

    def partner_displacement(self, r: np.ndarray) -> np.ndarray:
        """Π u_f = Π q_f − C r (3p,) for the contact forces r on the body (3p, per node (t1, t2, ν))."""
        return self.q_f - self.C @ np.ravel(r)

    def displacement(self, r: np.ndarray) -> np.ndarray:
        """The foundation's full displacement (3·n_f,) under −Πᵀ r (zero on its clamped DOFs)."""
        f = np.zeros(self.assembler.n_free)
        f[self._support_free] = -(self._P.T @ np.ravel(r))
        return self.assembler.to_full(self.condensation.solve(f))

    def summary(self) -> dict:
        fm = self.mesh
        return {"source": fm.reference.source, "cell_type": fm.reference.cell_type, "nodes": int(self.n_nodes),
                "cells": int(fm.reference.n_cells), "free_dofs": int(self.assembler.n_free), "E": fm.E,
                "nu": fm.nu, "support_nodes": int(self.support.size)}


def locate_partners(points: np.ndarray, faces: np.ndarray, ftype: str, xy: np.ndarray, contact_nodes, where: str):
    """(face (p,), weights (p, k)): the top face containing each point of ``xy`` (p, 2) in its
    projection on x3 = 0, and its shape functions there. A point no face contains is an error
    naming their count and the first ones (``contact_nodes``: the body's node numbers)."""
    ft = face_type(ftype)
    nc = FACE_CORNERS[ftype]
    corners = points[faces[:, :nc], :2]                           # (F, nc, 2)
    lo, hi = corners.min(axis=1), corners.max(axis=1)
    slack = 1e-9 * max(float(np.max(hi - lo)), 1e-300)
    p = xy.shape[0]
    face = np.full(p, -1)
    ref = np.zeros((p, 2))
    for m in range(p):
        cand = np.flatnonzero(np.all((xy[m] >= lo - slack) & (xy[m] <= hi + slack), axis=1))
        for f in cand:
            xi, inside = _reference_point(corners[f], xy[m], nc)
            if inside:
                face[m], ref[m] = f, xi
                break
    miss = np.flatnonzero(face < 0)
    if miss.size:
        first = ", ".join(f"contact node {m} (body node {int(contact_nodes[m])}) at {_fmt(xy[m])}" for m in miss[:5])
        raise ConfigError([f"{where}: the vertical lines of {miss.size} of {p} contact node(s) miss the foundation's "
                           f"top face, first: {first}"])
    N, _ = ft.shape(ref)
    return face, N


def _reference_point(X: np.ndarray, x: np.ndarray, nc: int):
    """(ξ, inside) of the point x in the face of corners X (nc, 2): barycentric (η, ζ) of the
    triangle 0-1-2, or the inverse of the bilinear map of the quadrilateral on [−1, 1]²."""
    if nc == 3:
        J = np.column_stack([X[1] - X[0], X[2] - X[0]])
        xi = np.linalg.solve(J, x - X[0])
        return xi, bool(xi.min() >= -INSIDE_TOL and xi.sum() <= 1 + INSIDE_TOL)
    s = np.array([(-1, -1), (1, -1), (1, 1), (-1, 1)], float)
    xi = np.zeros(2)
    for _ in range(NEWTON_STEPS):
        lin = 1.0 + xi[None] * s
        N = lin[:, 0] * lin[:, 1] / 4.0
        dN = np.column_stack([s[:, 0] * lin[:, 1], s[:, 1] * lin[:, 0]]) / 4.0
        res = N @ X - x
        step = np.linalg.solve(X.T @ dN, res)
        xi -= step
        if np.abs(step).max() < 1e-14:
            break
    return xi, bool(np.abs(xi).max() <= 1 + INSIDE_TOL)


def _partner_matrix(nodes: np.ndarray, weights: np.ndarray, support: np.ndarray, p: int) -> sp.csr_matrix:
    """Π (3p × 3n_s): row 3m + k, column 3j + k holds the weight of support node j at partner m."""
    col = np.searchsorted(support, nodes)                         # (p, k)
    k = np.arange(3)
    rows = (3 * np.arange(p)[:, None, None] + k).repeat(nodes.shape[1], axis=1)   # (p, k, 3)
    cols = 3 * col[:, :, None] + k
    vals = np.broadcast_to(weights[:, :, None], cols.shape)
    return sp.csr_matrix((vals.ravel(), (rows.ravel(), cols.ravel())), shape=(3 * p, 3 * support.size))


def _fmt(x) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in np.asarray(x)) + ")"
