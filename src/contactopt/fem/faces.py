"""Pairs whose faces lie on several bodies: the condensation path's coupling (DESIGN: W = Σ_b B_b K_b⁻¹ B_bᵀ).

In a model of several pairs (:mod:`contactopt.fem.counterparts`) the face body A (the one the
design moves) carries the faces of some pairs; a pair may also have its face on a counterpart body
C of another pair (a chain: head/plate, plate/plate, plate/nut), its counterpart part on a third
body D. The law's rows are the face body's contact nodes (rows a, first) and then, pair after pair,
the contact nodes of the faces on other bodies (rows b). Per row (t1, t2, ν) in the node's frame, ν
from the counterpart to the face, r the contact force on the face side, λ = r_ν ≥ 0 and

    w = u_face − Π o,        u_face = u_A (rows a),   u_face = E o (rows b),

u_A the face body's contact DOFs (condensed stiffness S(α)), o the counterparts' free support DOFs
(stiffness S_o, block diagonal over the bodies, condensed once per run), which hold C's face nodes
of a row b as well as every partner, and E the rotation of C's face nodes into the rows' frames.

With S padded by zero rows at rows b the compliance W = Q S⁻¹ Qᵀ + (Π − E) S_o⁻¹ (Π − E)ᵀ has no
Woodbury form on S alone. The route taken: C's face DOFs o_e of rows b join the face body's as the
law's own displacement, u_c = (u_A, E o_e), the other support DOFs o_r stay the counterparts'. The
energy ½u_Aᵀ S u_A + ½oᵀ S_o o in (u_c, o_r) is

    ½ u_cᵀ S_c u_c + u_cᵀ S_co o_r + ½ o_rᵀ S_rr o_r,   S_c = diag(S, E S_ee Eᵀ),  S_co = (0; E S_er),

and w = u_c − P o_r (no partner lies on a face node of rows b, checked). The Woodbury form of
:class:`~contactopt.fem.foundation.Coupling` holds with S → S_c and the coupling term S_co:

    S_eff = S_c − G M⁻¹ Gᵀ,   G = S_c P + S_co,   M = S_rr + Pᵀ S_c P + Pᵀ S_co + S_coᵀ P,
    ℓ_eff = ℓ_c − G M⁻¹ (Pᵀ ℓ_c + ℓ_r) − S_eff q,   ℓ_c = (ℓ, E ℓ_e),

and with S_co = 0, no rows b, it is that class's form (which stays the one used there, bit for
bit). A clamped component of a face node of rows b (a symmetry plane through C's face) is a pinned
row, as on the face body: a decoupled unit diagonal of S_c. The transfers: the face body's contact
displacement of a law displacement v at fixed forces is the rows a of v − P M⁻¹ Gᵀ v (the
adjoint's z); a state's u_c = w + q + P o_r gives the face body's u_A (rows a), C's face (rows b)
and the counterparts' support o = (Eᵀ u_c,b, o_r). Each of these is one Cholesky factor of M
(m_r × m_r) per design, as today's. The zone problem's W-form (``compliant``) would need S⁻¹ on
rows a alone; this coupling forms S_eff instead.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .dense import cholesky_lower
from .foundation import Coupling


@dataclass
class FaceRows:
    """The design-independent pieces of the coupling with rows b (module docstring): ``n_a`` = 3p_a
    the face body's rows, ``Scb`` (n_b × n_b) = E S_ee Eᵀ (+ I on pinned rows), ``Sco`` (n_b × m_r) =
    E S_er, ``Srr``, ``P`` (3p × m_r, sparse) the partners on o_r, ``ell_b`` = E ℓ_e, ``ell_r``,
    ``E`` (n_b × m_e) and the columns ``e``, ``r`` of o (the counterparts' free support DOFs)."""

    n_a: int
    Scb: np.ndarray
    Sco: np.ndarray
    Srr: np.ndarray
    P: sp.csr_matrix
    ell_b: np.ndarray
    ell_r: np.ndarray
    E: np.ndarray
    e: np.ndarray
    r: np.ndarray
    m: int

    @classmethod
    def build(cls, cps, n_a: int) -> "FaceRows":
        """From the counterparts ``cps`` (their Π, S_o, ℓ_o and face maps ``cps.face_map``: per row b
        and frame column the column of o or −1, and the entry)."""
        n = 3 * cps.p
        n_b = n - n_a
        m = cps.P.shape[1]
        rows, cols, vals = cps.face_map
        e = np.unique(cols)
        r = np.setdiff1d(np.arange(m), e)
        Ee = np.zeros((n_b, e.size))
        Ee[rows - n_a, np.searchsorted(e, cols)] = vals
        S = cps.condensation.S
        Scb = Ee @ S[np.ix_(e, e)] @ Ee.T
        pinned = ~np.any(Ee != 0, axis=1)
        Scb[pinned, pinned] = 1.0                 # a decoupled unit diagonal: the pinned DOFs of a face body
        Scb = 0.5 * (Scb + Scb.T)
        Sco = Ee @ S[np.ix_(e, r)]
        Srr = np.array(S[np.ix_(r, r)], dtype=np.float64, order="C")
        P = sp.csr_matrix(cps.P[:, r])          # (no partner on o_e: fem.foundation checks it per body)
        ell = np.zeros(m) if cps.ell_o is None else cps.ell_o
        return cls(n_a, Scb, Sco, Srr, P, Ee @ ell[e], ell[r], Ee, e, r, m)

    def support(self, u_c: np.ndarray, o_r: np.ndarray) -> np.ndarray:
        """o (m,) of the face displacement u_c (3p,) and o_r: o_e = Eᵀ u_c,b (E orthonormal on its rows)."""
        o = np.zeros(self.m)
        o[self.e] = self.E.T @ u_c[self.n_a:]
        o[self.r] = o_r
        return o


class FacesCoupling(Coupling):
    """:class:`~contactopt.fem.foundation.Coupling` of a model with faces on several bodies
    (module docstring): S (3p_a × 3p_a) the face body's, the law's rows 3p. Never ``compliant``:
    S_eff is formed from the Woodbury form with S_c and S_co."""

    def __init__(self, S: np.ndarray, foundation, anchored: bool = False):
        super().__init__(S, foundation, anchored)
        self.faces = fr = foundation.face_rows
        self.compliant = False
        self._P = fr.P
        n = fr.n_a + fr.Scb.shape[0]
        Sc = np.zeros((n, n))
        Sc[:fr.n_a, :fr.n_a] = S
        Sc[fr.n_a:, fr.n_a:] = fr.Scb
        self.S_c = Sc

    def _woodbury(self) -> None:
        if self._L is not None:
            return
        fr, P = self.faces, self._P
        if P.shape[1] == 0:
            self._G, self._L = np.zeros((P.shape[0], 0)), np.zeros((0, 0))
            return
        G = np.ascontiguousarray((P.T @ self.S_c).T)
        G[fr.n_a:] += fr.Sco
        M = fr.Srr + np.asarray(P.T @ G) + np.asarray(P[fr.n_a:].T @ fr.Sco)
        self._L = cholesky_lower(0.5 * (M + M.T))
        self._G = G

    @property
    def S_law(self) -> np.ndarray:
        """S_c = diag(S, E S_ee Eᵀ): the law's own displacement's stiffness (module docstring)."""
        return self.S_c

    def _pad(self, x: np.ndarray) -> np.ndarray:
        """A vector on the face body's rows (3p_a) with zeros on rows b."""
        out = np.zeros(self.S_c.shape[0])
        out[:self.faces.n_a] = np.ravel(x)
        return out

    def to_eff(self, x: np.ndarray) -> np.ndarray:
        """S_eff S_c⁻¹ x_c of a vector on the face body's rows (zero on rows b)."""
        self._woodbury()
        x = self._pad(x)
        return x - self._G @ self._solve_M(self._P.T @ x)

    def _ell_c(self, ell: np.ndarray) -> np.ndarray:
        out = self._pad(ell)
        out[self.faces.n_a:] = self.faces.ell_b
        return out

    def ell_eff(self, ell: np.ndarray) -> np.ndarray:
        """ℓ_eff = ℓ_c − G M⁻¹ (Pᵀ ℓ_c + ℓ_r) − S_eff q (module docstring)."""
        fr = self.faces
        ell_c = self._ell_c(ell)
        out = ell_c - self._G_solve(self._P.T @ ell_c + fr.ell_r)
        q = self.foundation.q_f
        if np.any(q):
            out -= self.S_eff @ q
        return out

    def _G_solve(self, b: np.ndarray) -> np.ndarray:
        self._woodbury()
        return self._G @ self._solve_M(b)

    def _o_r(self, w: np.ndarray, ell: np.ndarray) -> np.ndarray:
        u = np.ravel(w) + self.foundation.q_f
        return self._solve_M(self._P.T @ self._ell_c(ell) + self.faces.ell_r - self._G.T @ u)

    def face_displacement(self, w: np.ndarray, ell: np.ndarray) -> np.ndarray:
        """u_c = w + q + P o_r (3p,): the face sides' displacement of every row."""
        self._woodbury()
        return np.ravel(w) + self.foundation.q_f + self._P @ self._o_r(w, ell)

    def support_displacement(self, w: np.ndarray, ell: np.ndarray, r=None) -> np.ndarray:
        """o (m,): the counterparts' free support DOFs of the law's w under the face body's load ℓ."""
        self._woodbury()
        o_r = self._o_r(w, ell)
        u_c = np.ravel(w) + self.foundation.q_f + self._P @ o_r
        return self.faces.support(u_c, o_r)

    def adjoint_z(self, v_u: np.ndarray) -> np.ndarray:
        """The face body's rows of v − P M⁻¹ Gᵀ v (3p_a,)."""
        self._woodbury()
        return (v_u - self._P @ self._solve_M(self._G.T @ v_u))[:self.faces.n_a]

    def body_displacement(self, w: np.ndarray, r: np.ndarray, ell: np.ndarray | None = None) -> np.ndarray:
        """The face body's contact displacement u_A (3p_a,): the rows a of :meth:`face_displacement`."""
        return self.face_displacement(w, ell)[:self.faces.n_a]
