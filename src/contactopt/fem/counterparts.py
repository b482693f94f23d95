"""Several elastic counterparts of one face body: the pairs of an assembly on the condensation path.

An assembly of K contact pairs whose faces all lie on one body (the face body, the one the design
moves) and whose counterparts are K other bodies: pair k's face nodes (rows ``rows[k]`` of the
contact nodes) meet body k's face, as one ``[foundation]`` meets its body
(:class:`~contactopt.fem.foundation.Foundation`: partners Π_k, compliance C_k = Π_k W_k Π_kᵀ,
q_k = Π_k K_k⁻¹ f_k). The counterparts share no DOF, so with the relative displacement
w = u_c − Π u_o of every contact node (DESIGN: W = Σ_b B_b A_b⁻¹ B_bᵀ over the bodies)

    Π = diag_k(Π_k) (rows in contact-node order),   C = diag_k(C_k),   q = (q_k),   S_o = diag_k(S_k),

and the coupling of :class:`~contactopt.fem.foundation.Coupling` takes them as it takes one
foundation: S_eff = (S⁻¹ + C)⁻¹, each counterpart condensed once per run, the face body once per
design. One pair is the foundation itself (this class is not built for it).

Contact convention: per contact node (t1, t2, ν) in the node's frame (ν from the counterpart to the
face body), r the contact force on the face body, λ = r_ν ≥ 0; counterpart k carries −Π_kᵀ r_k.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..errors import ConfigError

log = logging.getLogger(__name__)


class _BlockCondensation:
    """The counterparts' condensed stiffnesses as one block-diagonal S (for the coupling's M)."""

    def __init__(self, parts):
        self.S = sla.block_diag(*[np.asarray(f.condensation.S) for f in parts])


def build_counterparts(specs, body, source: str, check=None, normals=None, frames=None) -> Counterparts:
    """The counterparts of the pairs ``specs`` (``[foundation]`` tables, one per pair) of ``body``,
    each built on the pair's view of the body (its face and nodes); ``normals`` (p, 3) of a curved
    face, ``frames`` (p, 3, 3) the contact nodes' frames the coupling is expressed in."""
    from .foundation import Foundation
    parts, rows = [], []
    for k, spec in enumerate(specs):
        r = np.flatnonzero(body.pair_of == k)
        view = body.pair_view(k)
        parts.append(Foundation(spec, view, source=f"{source}: contacts[{k}]", check=check,
                                normals=None if normals is None else normals[r], floating=True))
        rows.append(r)
    out = Counterparts(parts, rows, body.contact_nodes.size)
    if frames is not None:
        out.rotate(frames)
    return out


class Counterparts:
    """The K elastic counterparts of one face body (module docstring).

    Attributes as :class:`~contactopt.fem.foundation.Foundation`'s, over all contact nodes: ``P``
    (3p × m, Π on the counterparts' free support DOFs), ``Pi``, ``C``, ``q_f``, ``gap0`` (curved
    faces), ``condensation.S``; ``parts`` the pairs' foundations and ``rows`` their contact nodes."""

    basis = None          # mortar partners on six-node triangles: one pair only (Foundation)
    motion = None         # a counterpart pressed by a force: one pair only (a displacement is in q)
    translation = None

    def __init__(self, parts: list, rows: list, p: int):
        self.parts, self.rows, self.p = list(parts), [np.asarray(r) for r in rows], p
        for f in self.parts:
            if f.basis is not None:
                raise ConfigError(["contacts: mortar partners on six-node triangles take one pair per model so far; "
                                   "use partner = 'point' or linear elements"])
            if f.control == "force":
                raise ConfigError(["bodies: a counterpart pressed by control = 'force' takes one pair per model so "
                                   "far; in a model of several pairs a counterpart is held by its clamps or moved "
                                   "by control = 'displacement'"])
        self.gap0 = None
        if all(f.gap0 is not None for f in self.parts):
            self.gap0 = np.zeros(p)
            for f, r in zip(self.parts, self.rows):
                self.gap0[r] = f.gap0
        self.memory_parts = {}
        for f in self.parts:
            for key, v in f.memory_parts.items():
                self.memory_parts[key] = self.memory_parts.get(key, 0.0) + v
        self.condensation = _BlockCondensation(self.parts)
        self.load_resultant = sum(f.load_resultant for f in self.parts)
        self._gather()

    def _dofs(self, k: int) -> np.ndarray:
        return (3 * self.rows[k][:, None] + np.arange(3)).ravel()

    def _gather(self) -> None:
        """Π, P, C, q and ℓ_o over all contact nodes from the pairs' (after a rotation into frames):
        q holds only the prescribed translations Π d, the loads enter as ℓ_o (Coupling.ell_eff);
        C is None where a counterpart is held only by its contacts (its compliance is infinite
        along its rigid motions)."""
        n = 3 * self.p
        self.P = sp.csr_matrix(self._stack([f.P for f in self.parts]))
        self.Pi = sp.csr_matrix(self._stack([f.Pi for f in self.parts]))
        self.C = None if any(f.C is None for f in self.parts) else np.zeros((n, n))
        self.q_f = np.zeros(n)
        for k, f in enumerate(self.parts):
            d = self._dofs(k)
            if self.C is not None:
                self.C[np.ix_(d, d)] = f.C
            if f.motion is not None:
                self.q_f[d] = f.motion
        self.ell_o = np.concatenate([f.ell_f for f in self.parts])
        # Π W_o ℓ_o: the partners' displacement under the counterparts' own loads (Coupling.free_displacement)
        self.load_displacement = None
        if self.C is not None and np.any(self.ell_o):
            self.load_displacement = np.asarray(self.P @ self.support_compliance(self.ell_o))

    def support_compliance(self, x: np.ndarray) -> np.ndarray:
        """W_o x = diag_k(W_k) x: the displacement of the counterparts' free support DOFs (in the
        order of ``P``'s columns) under the forces x on them; every counterpart held."""
        out, start = np.empty(x.shape), 0
        for f in self.parts:
            m = f.P.shape[1]
            out[start:start + m] = f.W_f @ x[start:start + m]
            start += m
        return out

    def check_held(self, friction, names: list, source: str) -> None:
        """ConfigError naming each rigid motion of a counterpart held only by its contacts that no
        contact force can hold: one that moves no contact node along its normal, where its pair
        has no friction (``friction`` F per contact node, a scalar or (p,); ``names`` the
        counterparts' bodies in pair order)."""
        mu = np.broadcast_to(np.asarray(friction, float), (self.p,))
        problems = []
        for k, f, R in self._floating():
            G = np.asarray(self.P @ R).reshape(self.p, 3, -1)
            scale = np.abs(G).max(initial=0.0)
            for j, motion in enumerate(f.rigid.names()):
                normal = np.abs(G[:, 2, j]).max(initial=0.0) > 1e-9 * max(scale, 1e-300)
                rubbed = np.any((np.abs(G[:, :2, j]).max(axis=1) > 1e-9 * scale) & (mu > 0))
                if not (normal or rubbed):
                    problems.append(f"{source}: bodies.{names[k]}: {motion} is not held: the body is held only by "
                                    f"its contacts, and no contact force of contacts[{k}] acts along it (it moves "
                                    "no contact node along its normal, and the pair has no friction); clamp it "
                                    "in bodies." + names[k] + ".clamped")
        if problems:
            raise ConfigError(problems)

    def kernel(self):
        """(R (3p, k), names) of the counterparts held only by their contacts: the relative
        displacement −Π R_o of each free rigid motion R_o (on its free support DOFs), along which
        the coupled stiffness S_eff is singular and the contact forces must balance the body's
        loads (paths/rigid.py); None when every counterpart is held."""
        cols, names = [], []
        for k, f, R in self._floating():
            cols.append(-(self.P @ R))
            names += [f"{n} of the counterpart of contacts[{k}]" for n in f.rigid.names()]
        if not cols:
            return None
        return np.column_stack(cols), names

    def _floating(self):
        """(k, foundation, R) of each counterpart held only by its contacts: R (m, k_b) its free
        rigid motions on the free support DOFs of all counterparts (zero off its own)."""
        start = 0
        for k, f in enumerate(self.parts):
            m = f.P.shape[1]
            if f.rigid is not None:
                V = f.rigid.vectors(f.mesh.reference.points).reshape(-1, f.rigid.count)[f.assembler.free]
                R = np.zeros((self.P.shape[1], f.rigid.count))
                R[start:start + m] = V[f._support_free]
                yield k, f, R
            start += m

    def _stack(self, blocks: list) -> sp.csr_matrix:
        """The block-diagonal matrix of the pairs' blocks with its rows moved to their contact DOFs."""
        B = sp.block_diag(blocks, format="csr")
        order = np.concatenate([self._dofs(k) for k in range(len(self.parts))])
        perm = sp.csr_matrix((np.ones(order.size), (order, np.arange(order.size))), shape=(3 * self.p, order.size))
        return perm @ B

    def rotate(self, R: np.ndarray) -> None:
        """Into the contact nodes' frames R (p, 3, 3): each pair in its nodes' frames."""
        for f, r in zip(self.parts, self.rows):
            f.rotate(R[r])
        self._gather()

    @property
    def partner(self) -> str:
        return ", ".join(sorted({f.partner for f in self.parts}))

    @property
    def n_nodes(self) -> int:
        return sum(f.n_nodes for f in self.parts)

    def displacements(self, r: np.ndarray, coupling, w, ell) -> list:
        """Each counterpart's full displacement (3·n_k,): its support DOFs from the coupling's
        :meth:`~contactopt.fem.foundation.Coupling.support_displacement` of the law's w under the
        face body's load ℓ, its interior recovered under its own loads, plus its prescribed translation."""
        return self.recovered(coupling.support_displacement(w, ell, r))

    def recovered(self, o: np.ndarray) -> list:
        """Each counterpart's full displacement (3·n_k,) from o on the free support DOFs of all
        (:meth:`displacements`): its interior recovered under its own loads, plus its translation."""
        out, start = [], 0
        for f in self.parts:
            m = f.P.shape[1]
            out.append(f.displacement(None, support=o[start:start + m]))
            start += m
        return out

    def displacement(self, r: np.ndarray, s: float = 0.0, coupling=None, w=None, ell=None) -> np.ndarray:
        """The counterparts' displacements one after the other (their VTU file tags each pair's)."""
        return np.concatenate(self.displacements(r, coupling, w, ell))

    def summary(self) -> dict:
        return {"pairs": [f.summary() for f in self.parts]}

    def pair_forces(self, r: np.ndarray) -> list:
        """Σ of the contact forces (per node frame) of each pair: (3,) per pair."""
        r = np.reshape(r, (-1, 3))
        return [r[rows].sum(axis=0) for rows in self.rows]
