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

independent of the design α: computed once per run.

A curved contact face (a chart other than x3 = 0, :mod:`contactopt.design.chart`) meets a curved top
face of any shape: contact node m's partner is where the line through the node along its contact
normal n_m (the body's inward face normal, from the foundation to the body) meets the top face,
and its initial gap g_m the signed distance along n_m (negative: an interference); with mortar
partners both faces are segmented on the body's chart instead (:func:`mortar_partners`). The coupling
then acts in the nodes' frames R_m = (t1, t2, n_m): Π → Rᵀ Π, C → Rᵀ C R, q_f → Rᵀ q_f
(:meth:`Foundation.rotate`). Condensed with the body's S(α) u_c = ℓ + r,

    w = W r + S⁻¹ℓ − Π q_f,   W = S⁻¹ + C

(docs/foundation.md). The foundation's own loads f_f (``[foundation] loads``: tractions,
pressures on its parts and a body force, the same in every load case) give q_f; without them q_f = 0.
"""

from __future__ import annotations

import copy
import logging

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.linalg import solve_triangular
from scipy.linalg.blas import dsyrk

from .._progress import task
from ..errors import ConfigError
from ..mesh.foundation import build_foundation_mesh, other_top
from ..mesh.reference import FACE_CORNERS
from .dense import cholesky_lower, cholesky_solve, spd_inverse, symmetrize_lower
from .elasticity import ElasticityAssembler
from .elements import element_type, face_type, tri_rule
from .faceviews import check_apart, face_view
from .loadset import load_set
from .memory import CounterpartSize, matrix_entries
from .mortar import MortarCoupling, mortar_matrices, transformed_basis

log = logging.getLogger(__name__)

INSIDE_TOL = 1e-8     # reference-coordinate slack of "the point lies in the face"
NEWTON_STEPS = 30     # inverse of the bilinear map of a quadrilateral face


class Foundation:
    """The elastic foundation of a configuration (module docstring).

    Attributes: ``mesh`` (:class:`~contactopt.mesh.foundation.FoundationMesh`), ``assembler`` (on
    its free DOFs), ``support`` (top-face nodes carrying partners), ``Pi`` (3p × 3n_s sparse, per
    contact node (t1, t2, ν) and support node (x1, x2, x3)), ``partner`` ('point', 'average' or 'mortar'), ``W_f``
    (on the free support DOFs), ``C`` (3p × 3p), ``q_f`` (3p,), ``condensation`` (of K_f onto the
    free support DOFs: the foundation's displacement for outputs)."""

    def __init__(self, spec, body, source: str = "<dict>", backend: str = "auto", check=None, normals=None,
                 floating: bool = False, condensed: bool = True, shared=None, faces=None):
        """``spec`` the ``[foundation]`` section of the configuration read from ``source``;
        ``check(size)``: called with its :attr:`memory_sizes` (its sizes, counted from its mesh)
        before K_f is assembled and condensed (the model's memory check, on the path that will run),
        so that a foundation too large is refused first.
        ``normals`` (p, 3): the contact normals of a curved contact face (module docstring), whose
        partners lie along them; None: the face on x3 = 0, partners below the nodes.
        ``condensed=False``: K_f is assembled and kept as it is (``K``, the full-space path's
        block, paths/fullspace.py), nothing is factorized and C, W_f, ``condensation`` are None.

        ``shared``: a counterpart body of several pairs (fem.counterparts), ``[(spec_k, body_k,
        normals_k)]`` per pair, ``body_k`` the face body as pair k sees it (its contact nodes the
        pair's) and ``spec_k`` its ``[foundation]`` (the body's, ``top`` and ``partner`` the pair's):
        each pair's partners are searched on its own top part alone, and the body is condensed once
        onto the union of their supports, its rows the pairs' contact nodes one pair after the
        other. ``spec``, ``body`` and ``normals`` are then the first pair's.

        ``faces``: {pair k: its face part} of the pairs whose faces lie on this body
        (:mod:`contactopt.fem.faces`): ``face_views`` {k: the pair's face as a body's contact face},
        their contact nodes among the support (:meth:`face_columns`)."""
        views = [(spec, body, normals)] if shared is None else list(shared)
        contact_xy = body.reference.points[body.contact_nodes, :2]
        self.mesh = fm = build_foundation_mesh(spec, contact_xy, source, curved=normals is not None,
                                               floating=floating)
        self.face_views = {}
        if faces:
            self.face_views = {k: face_view(fm, part, k, source) for k, part in faces.items()}
        ref = fm.reference
        self.loads = load_set(fm, spec.loads, where=f"{source}: foundation.loads")
        self.assembler = ElasticityAssembler(ref.cells, ref.n_nodes, fm.fixed_dofs, fm.E, fm.nu,
                                             element=element_type(ref.cell_type))
        where = f"{source}: foundation.top"
        self.basis = None           # mortar partners on six-node triangles: T on the contact nodes (fem.mortar)
        parts, kinds, gaps, start = [], [], [], 0
        for k, (spec_k, body_k, normals_k) in enumerate(views):
            fm_k = fm
            if k:
                xy = body_k.reference.points[body_k.contact_nodes, :2]
                fm_k = other_top(fm, spec_k.top, xy, source, curved=normals_k is not None)
            rows, cols, vals, gap, kind, basis = self._partners(spec_k, body_k, fm_k, normals_k, where, source)
            if basis is not None and len(views) > 1:
                raise ConfigError([f"{where}: mortar partners on six-node triangles take one pair per counterpart "
                                   "body so far; use partner = 'point' or linear elements"])
            self.basis = basis
            parts.append((rows + start, cols, vals))
            kinds.append(kind)
            gaps.append(gap)
            start += body_k.contact_nodes.size
        rows, cols, vals = (np.concatenate(x) for x in zip(*parts))
        self.partner = kinds[0] if len(set(kinds)) == 1 else ", ".join(kinds)
        self.gap0 = None if any(g is None for g in gaps) else np.concatenate(gaps)   # a curved face's gaps
        p = start
        Pn = sp.csr_matrix((vals, (rows, cols)), shape=(p, ref.n_nodes))
        Pn.sum_duplicates()
        Pn.eliminate_zeros()
        self.support = np.unique(Pn.indices)                     # top-face nodes carrying partners
        if self.face_views:             # ... and the nodes of the faces of pairs that lie on this body
            check_apart(self.support, self.face_views, source)
            self.support = np.unique(np.concatenate([self.support] + [v.contact_nodes for v in self.face_views.values()]))
        self.Pi = sp.kron(Pn[:, self.support], sp.identity(3), format="csr")
        free = self.assembler.full_to_free[(3 * self.support[:, None] + np.arange(3)).ravel()]
        keep = free >= 0                                         # clamped components do not move
        self._support_free = free[keep]
        self._column = np.where(keep, np.cumsum(keep) - 1, -1).reshape(-1, 3)   # per support node: P's columns
        free_per_node = np.ones(3 * ref.n_nodes, bool)
        free_per_node[fm.fixed_dofs] = False
        nnz_K = matrix_entries(ref.cells, ref.n_nodes, free_per_node.reshape(-1, 3).sum(axis=1))
        self.memory_sizes = [CounterpartSize(self.assembler.n_free, nnz_K, self._support_free.size, 3 * p)]
        if check is not None:
            check(self.memory_sizes[0])
        self.rigid = fm.rigid     # held only by its contacts: K_f singular, no W_f, C, q_f (fem.counterparts)
        self.K = None             # K_f on the free DOFs where it is not condensed
        P = self.Pi.tocsc()[:, np.flatnonzero(keep)]
        if not condensed:
            self.K = sp.csr_matrix(self.assembler.stiffness(ref.points))
            self.condensation = self.W_f = self.C = None
        else:
            self._condense(backend, P, p)
        self.P = P                # Π on the free support DOFs (the clamped ones do not move)
        f_full = self.loads.vector(ref.points, self.assembler)
        self.load_resultant = f_full.reshape(-1, 3).sum(axis=0)
        self.f_f = f_full[self.assembler.free]                    # K_f u_f0 = f_f
        # the loads condensed onto the free support DOFs: ℓ_f = f_s − K_si K_ii⁻¹ f_i
        self.ell_f = None if not condensed else self.condensation.condense_load(self.f_f)
        if self.rigid is not None or not condensed:     # (uncondensed: f_f is the full-space load's)
            self._u0 = None
            self.q_f = np.zeros(3 * p)
        else:
            self._u0 = self.condensation.solve(self.f_f) if np.any(self.f_f) else np.zeros_like(self.f_f)
            self.q_f = P @ self._u0[self._support_free]               # Π K_f⁻¹ f_f (3p,)
        self._motion(spec)
        log.info("elastic foundation %s: %d nodes, %d free DOFs, E = %g, nu = %g; %d top-face nodes carry "
                 "the partners of %d contact nodes", ref.source, ref.n_nodes, self.assembler.n_free, fm.E, fm.nu,
                 self.support.size, p)

    coords = None         # the node coordinates K_f is formed on (None: the reference mesh's)
    face_rows = None      # a pair's face on this body: the coupling's pieces are the counterparts' (fem.faces)
    face_map = None       # ... and the map of its nodes (fem.counterparts)

    def face_columns(self, nodes: np.ndarray) -> np.ndarray:
        """(len(nodes), 3): the columns of P (free support DOFs) of the support nodes ``nodes`` per
        global component (u1, u2, u3), −1 where the component is clamped."""
        return self._column[np.searchsorted(self.support, nodes)]

    def _condense(self, backend, P, p: int, coords=None) -> None:
        """K_f condensed onto the free support DOFs: ``condensation``, W_f and C = Π W_f Πᵀ (none
        for a counterpart held only by its contacts, whose K_f is shifted by γ I_s); on the mesh
        moved to ``coords`` where given (a designed counterpart, fem.cpdesigns)."""
        from .linsolve import condense
        ref = self.mesh.reference
        with task(f"the foundation's compliance at {3 * p} contact unknowns"):
            K = self.assembler.stiffness(ref.points if coords is None else coords)
            if self.rigid is not None:          # K_f + γ I_s: its Schur complement is S_f + γ I (paths/rigid.py)
                from ..paths.rigid import with_contact_diagonal
                K, shift = with_contact_diagonal(K, self._support_free)
            if self._support_free.size < K.shape[0]:
                self.condensation = condense(K, self._support_free, backend=backend)
            else:                       # a slab one cell thick: every free DOF carries a partner
                self.condensation = _WholeMatrix(K, self._support_free)
            if self.rigid is not None:
                self.condensation.S = self.condensation.S - shift * np.eye(self._support_free.size)
                self.W_f = self.C = None
            else:
                self.W_f = spd_inverse(self.condensation.S)
                PW = (P @ self.W_f)                                      # (3p, n) dense
                C = np.asarray((P @ PW.T).T)
                self.C = 0.5 * (C + C.T)

    def _motion(self, spec) -> None:
        """The prescribed or force-driven translation of the foundation (its ``motion`` Π d)."""
        fm = self.mesh
        # control = 'displacement' | 'force': the part `loaded` and the foundation with it translate
        # rigidly by d (mesh.foundation checks that the clamps allow it): the partners move by Π d
        self.control = spec.control
        self.translation = None if fm.loaded is None else np.asarray(spec.translation, float)
        self.motion = None          # (3p,) Π d per contact node, d the translation (per unit s with 'force')
        if self.translation is not None:
            self.motion = np.asarray(self.Pi @ np.tile(self.translation, self.support.size))
            if spec.control == "displacement":
                self.q_f = self.q_f + self.motion

    def _partners(self, spec, body, fm, normals, where: str, source: str):
        """(rows, cols, values) of the partners of ``body``'s contact nodes on ``fm``'s top face
        (rows the contact nodes, columns the foundation's nodes), the initial gaps along the contact
        normals (None on x3 = 0), the partner kind and the transformed basis (module docstring)."""
        contact_nodes = body.contact_nodes
        contact_xy = body.reference.points[contact_nodes, :2]
        ref = fm.reference
        p = contact_xy.shape[0]
        gap0 = basis = None
        partner = spec.partner
        if normals is None:
            faces, weights = locate_partners(ref.points, fm.top.faces, ref.face_type, contact_xy, contact_nodes,
                                             where)
        else:
            if partner == "average":
                raise ConfigError([f"{where}: foundation.partner = 'average' takes a contact face on x3 = 0; "
                                   "a curved face's partners are points along its normals (partner = 'point') "
                                   "or its mortar partners on the face's chart (partner = 'mortar')"])
            x = body.reference.points[contact_nodes]
            faces, weights, gap0 = ray_partners(ref.points, fm.top.faces, ref.face_type, x, normals,
                                                contact_nodes, where)
            smooth = smooth_gaps(ref.points, fm.top, ref.face_type, x, normals, fm.tol)
            if smooth is not None:
                gap0 = smooth
        self._check_pinned(body, fm, faces, weights, source)
        if partner == "auto":
            partner = auto_partner(weights, face_type(body.reference.face_type).degree, curved=normals is not None)
            if partner == "mortar" and open_edges(body).size:
                partner = "point"      # the transformed basis needs whole edges in contact
            log.info("foundation.partner = 'auto': %r", partner)
        if partner == "point":
            rows, cols, vals = np.repeat(np.arange(p), weights.shape[1]), fm.top.faces[faces].ravel(), weights.ravel()
        elif partner == "mortar":
            rows, cols, vals, basis = mortar_partners(body, fm, where, chart=None if normals is None else body.chart)
        else:
            rows, cols, vals = averaged_partners(body, fm, where)
        return np.asarray(rows), np.asarray(cols), np.asarray(vals), gap0, partner, basis

    def _check_pinned(self, body, fm, faces, weights, source) -> None:
        """A clamped component of a contact node (a symmetry plane through the contact face) must be
        clamped at its partners too: the plane runs through both bodies, so that the foundation's
        compliance adds nothing to the clamped direction."""
        if body.pinned_dofs.size == 0:
            return
        fixed = np.zeros(3 * fm.reference.n_nodes, bool)
        fixed[fm.fixed_dofs] = True
        node, comp = np.divmod(body.pinned_dofs, 3)
        m = np.searchsorted(body.contact_nodes, node)
        partners = fm.top.faces[faces[m]]
        w = np.abs(weights[m]) > 1e-12
        bad = np.flatnonzero(np.any(w & ~fixed[3 * partners + comp[:, None]], axis=1))
        if bad.size:
            i = bad[0]
            # (a face on a counterpart body of another pair, fem.faces: the bodies by their names)
            mine, theirs = (("body.clamped", "foundation.clamped") if body.owner is None else
                            (f"bodies.{body.owner[0]}.clamped", f"bodies.{body.owner[1]}.clamped"))
            raise ConfigError([f"{source}: {mine}: {bad.size} tangential component(s) of contact nodes are "
                               f"clamped (a symmetry plane through the contact face) but free at their partners on "
                               f"the foundation, first u{int(comp[i]) + 1} of body node {int(node[i])}: clamp the "
                               f"same plane of the foundation ({theirs}), else its compliance would add "
                               "to the clamped direction"])

    def at_coordinates(self, coords: np.ndarray, backend: str = "auto") -> "Foundation":
        """A copy of this counterpart on its mesh moved to ``coords`` (a designed counterpart,
        :mod:`contactopt.fem.cpdesigns`): K_f, its condensation, W_f, C, f_f, ℓ_f and q_f formed
        there; the partners Π (in the contact nodes' frames), the support and the translation are
        this one's (found on the reference). MeshError where the moved mesh is inverted."""
        from ..errors import MeshError
        det = self.assembler.jacobian_determinants(coords)
        if not np.all(det > 0):
            e = int(np.unique(np.nonzero(~(det > 0))[0])[0])
            raise MeshError(f"the design would leave element {e} of the counterpart {self.mesh.reference.source} "
                            "inverted (det J ≤ 0)")
        out = copy.copy(self)
        out.coords = coords
        out._condense(backend, self.P, self.P.shape[0] // 3, coords)
        f_full = self.loads.vector(coords, self.assembler)
        out.load_resultant = f_full.reshape(-1, 3).sum(axis=0)
        out.f_f = f_full[self.assembler.free]
        out.ell_f = out.condensation.condense_load(out.f_f)
        out._u0 = out.condensation.solve(out.f_f) if np.any(out.f_f) else np.zeros_like(out.f_f)
        out.q_f = self.P @ out._u0[self._support_free]
        if self.motion is not None and self.control == "displacement":
            out.q_f = out.q_f + self.motion
        return out

    def rotate(self, R: np.ndarray) -> None:
        """Express the coupling in the contact nodes' frames R (p, 3, 3), columns (t1, t2, n):
        Π → Rᵀ Π, C → Rᵀ C R, q_f → Rᵀ q_f (per node (t1, t2, ν))."""
        Q = sp.block_diag([np.asarray(r).T for r in R], format="csr")
        self.Pi = sp.csr_matrix(Q @ self.Pi)
        self.P = sp.csr_matrix(Q @ self.P)
        if self.C is not None:          # (none where the counterpart is held only by its contacts)
            C = np.asarray(Q @ (Q @ self.C).T)
            self.C = 0.5 * (C + C.T)
        self.q_f = Q @ self.q_f
        if self.motion is not None:
            self.motion = Q @ self.motion

    @property
    def n_nodes(self) -> int:
        return self.mesh.reference.n_nodes

    def partner_displacement(self, r: np.ndarray) -> np.ndarray:
        """Π u_f = Π q_f − C r (3p,) for the contact forces r on the body (3p, per node (t1, t2, ν))."""
        return self.q_f - self.C @ np.ravel(r)

    ell_o = None          # the loads of several pairs' counterparts on their support (fem.counterparts)
    load_displacement = None   # ... and their partners' displacement under them (here in q_f)

    def support_compliance(self, x: np.ndarray) -> np.ndarray:
        """W_f x: the displacement of the free support DOFs under the forces x on them."""
        return self.W_f @ x

    def kernel(self):
        """None: the one foundation is held by its clamps (fem.counterparts: several pairs)."""
        return None

    @property
    def parts(self) -> list:
        """The counterparts one per pair: this one (fem.counterparts: several)."""
        return [self]

    @property
    def pairs(self) -> list:
        """The pairs of each counterpart body: the one pair (fem.counterparts: several)."""
        return [[0]]

    @property
    def rows(self) -> list:
        """The contact nodes of each pair: all (fem.counterparts: several)."""
        return [np.arange(self.P.shape[0] // 3)]

    def displacement(self, r: np.ndarray, s: float = 0.0, support=None, coupling=None, w=None,
                     ell=None) -> np.ndarray:
        """The foundation's full displacement (3·n_f,) under its own loads f_f and −Πᵀ r (zero on
        its clamped DOFs), plus its rigid translation: d with control = 'displacement', s f̂ with
        control = 'force' (``s`` the state's translation). ``support``: its displacement on the free
        support DOFs where the coupling gives it (a counterpart held only by contact: the interior
        is recovered from it)."""
        if support is not None:          # (``coupling``, ``w``, ``ell``: Counterparts' signature)
            u = self.assembler.to_full(self.condensation.recover(self.f_f, support))
        else:
            f = np.zeros(self.assembler.n_free)
            f[self._support_free] = -(self.P.T @ np.ravel(r))
            u = self.assembler.to_full(self.condensation.solve(f) + self._u0)
        if self.translation is not None:
            scale = 1.0 if self.control == "displacement" else s
            u = u + scale * np.tile(self.translation, self.n_nodes)
        return u

    def summary(self) -> dict:
        """The foundation as summary.json and state.json write it; with control = 'displacement'
        or 'force' the translation d or the force's direction f̂ (the state's
        ``obstacle_translation`` is then s, the translation along f̂)."""
        fm = self.mesh
        control = {} if self.translation is None else {
            "control": self.control, ("displacement" if self.control == "displacement" else "direction"):
            self.translation.tolist(), "loaded_nodes": int(fm.loaded.size)}
        return {**self._summary(fm), **control}

    def _summary(self, fm) -> dict:
        return {"source": fm.reference.source, "cell_type": fm.reference.cell_type, "nodes": int(self.n_nodes),
                "cells": int(fm.reference.n_cells), "free_dofs": int(self.assembler.n_free), "E": fm.E,
                "nu": fm.nu, "support_nodes": int(self.support.size), "partner": self.partner,
                "loads": {"tractions": [name for name, _, _ in self.loads.tractions],
                          "pressures": [name for name, _, _ in self.loads.pressures],
                          "body_force": self.loads.body_force.tolist(),
                          "resultant": self.load_resultant.tolist()}}


class _WholeMatrix:
    """K condensed onto all its DOFs (``order``, a permutation of them): S = K in that order,
    dense, and solves K x = f by its Cholesky factorization — what :func:`condense` gives when
    there is no interior to eliminate."""

    def __init__(self, K, order: np.ndarray):
        self._order = np.asarray(order)
        self.S = np.asarray(K[np.ix_(self._order, self._order)].toarray())
        self._factor = sla.cho_factor(self.S, lower=True)

    def solve(self, f: np.ndarray) -> np.ndarray:
        x = np.zeros_like(f)
        x[self._order] = sla.cho_solve(self._factor, f[self._order])
        return x

    def condense_load(self, f: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(f[self._order])

    def recover(self, f: np.ndarray, u_c: np.ndarray) -> np.ndarray:
        x = np.zeros_like(f)
        x[self._order] = u_c
        return x


class Coupling:
    """The body's condensed stiffness S(α) of one design coupled with the foundation (module
    docstring). The contact law's compliance is

        W = S⁻¹ + C,   C = P W_f Pᵀ,   W_f = S_f⁻¹

    (S_f the foundation's stiffness condensed on its free support DOFs, P = Π on them): a
    product W b is a solve with the body's Cholesky factor and a product with C, which is formed
    once per run. The zone's problem (:class:`~contactopt.contact.zone.CoupledZoneProblem`) and
    the adjoint in W-form need nothing else: W_Z = (S⁻¹)_ZZ + C_ZZ on the zone Z, and the law's
    free displacement W ℓ_eff = S⁻¹ℓ − :attr:`offset`, so that a design adds no dense algebra on
    all contact DOFs to the body's own (``compliant``; docs/foundation.md).

    Where S_eff = W⁻¹ itself is asked for (:attr:`S_eff`, ℓ_eff, the transfers; a counterpart held
    only by its contacts, which has no C; a force-controlled foundation; an objective of the whole
    displacement), it comes from the Woodbury identity, formed on first use:

        S_eff = S − G M⁻¹ Gᵀ,   G = S P,   M = S_f + Pᵀ S P   (m × m, m = free support DOFs),

    formed as S − Y Yᵀ with Y = G L_M⁻ᵀ (M = L_M L_Mᵀ): no inverse of S and none of S + …, one
    Cholesky factorization of M (m is about the number of top-face DOFs under the contact face;
    where the foundation is coarser than the body, m < 3p). The transfers

        S_eff S⁻¹ x = x − G M⁻¹ Pᵀ x,     S⁻¹ S_eff v = v − P M⁻¹ Gᵀ v

    give ℓ_eff = S_eff (S⁻¹ℓ − Π q_f) and the adjoint's z = S⁻¹ S_eff v_u. Per contact node the
    order is (t1, t2, ν); r is the contact force on the body."""

    def __init__(self, S: np.ndarray, foundation: Foundation, anchored: bool = False):
        """``anchored``: the body is held only by contact (paths/rigid.py), its law that of
        S_eff + γQQᵀ: not ``compliant``."""
        self.foundation = f = foundation
        self._P = f.P
        self.S = S
        # W = S⁻¹ + C and r = S_eff w − ℓ_eff: every body held by its clamps (a counterpart held
        # only by its contacts has no C; an anchored body's law is another)
        self.compliant = f.C is not None and not anchored
        self._G = self._L = self._S_eff = None
        self.zone_problem = None     # the last zone problem on this design's factor of S (paths/condensation.py)

    def _woodbury(self) -> None:
        """G = S P and the Cholesky factor of M = S_f + Pᵀ S P, once per design (class docstring)."""
        if self._L is not None:
            return
        P = self._P
        if P.shape[1] == 0:          # every counterpart rigid (fem.counterparts): no support, S_eff = S
            self._G, self._L = np.zeros((P.shape[0], 0)), np.zeros((0, 0))
            return
        G = np.ascontiguousarray((P.T @ self.S).T)                # S P, S symmetric
        M = np.array(self.foundation.condensation.S, dtype=np.float64, order="C") + np.asarray(P.T @ G)
        self._L = cholesky_lower(0.5 * (M + M.T))
        self._G = G

    @property
    def S_eff(self) -> np.ndarray:
        """S_eff = (S⁻¹ + C)⁻¹ (3p × 3p), formed on first use (class docstring): S_law − G M⁻¹ Gᵀ,
        S_law the stiffness of the law's own displacement (S here; fem.faces adds its rows)."""
        if self._S_eff is None:
            self._woodbury()
            S = self.S_law
            if self._G.shape[1] == 0:
                self._S_eff = S
                return self._S_eff
            Y = solve_triangular(self._L.T, self._G.T, lower=False, trans="T", check_finite=False)   # L_M⁻¹ Gᵀ
            YtY = dsyrk(1.0, Y.T, trans=0, lower=1)              # lower triangle of YᵀY (half a product)
            self._S_eff = symmetrize_lower(np.ascontiguousarray(np.tril(S) - YtY))
        return self._S_eff

    @property
    def S_law(self) -> np.ndarray:
        """The stiffness of the law's own displacement before the counterparts' coupling: S."""
        return self.S

    def _solve_M(self, b: np.ndarray) -> np.ndarray:
        self._woodbury()
        if self._L.shape[0] == 0:
            return np.zeros(b.shape)
        return cholesky_solve(self._L, b)

    @property
    def offset(self) -> np.ndarray:
        """Π q_f + Π W_f ℓ_o (3p,): the partners' displacement under no contact force, so that the
        contact law's free displacement is W ℓ_eff = S⁻¹ℓ − offset (``compliant`` only; ℓ_eff
        itself is :meth:`ell_eff`). W G M⁻¹ = Π W_f turns the loads ℓ_o of the counterparts of
        several pairs into Π W_f ℓ_o (:attr:`~contactopt.fem.counterparts.Counterparts.load_displacement`)."""
        f = self.foundation
        loads = f.load_displacement
        return f.q_f if loads is None else f.q_f + loads

    def to_eff(self, x: np.ndarray) -> np.ndarray:
        """S_eff S⁻¹ x (3p,)."""
        self._woodbury()
        return x - self._G @ self._solve_M(self._P.T @ x)

    def ell_eff(self, ell: np.ndarray) -> np.ndarray:
        """ℓ_eff = S_eff (S⁻¹ℓ − Π q_f) (3p,). Counterparts of several pairs
        (:mod:`contactopt.fem.counterparts`) give their loads condensed on their support DOFs, ℓ_o,
        and q = Π d of their prescribed translations: ℓ_eff = S_eff S⁻¹ℓ − G M⁻¹ ℓ_o − S_eff q, the
        same where a counterpart is held (S_eff Π S_o⁻¹ = G M⁻¹) and defined where it is held only
        by its contacts (S_o singular)."""
        out = self.to_eff(ell)
        f = self.foundation
        ell_o = f.ell_o
        if ell_o is not None:
            if np.any(ell_o):
                out -= self._G @ self._solve_M(ell_o)
        if np.any(f.q_f):
            out -= self.S_eff @ f.q_f
        return out

    def support_displacement(self, w: np.ndarray, ell: np.ndarray, r: np.ndarray | None = None) -> np.ndarray:
        """Counterparts of several pairs: their displacement o on the free support DOFs (less their
        prescribed translations) for the law's w under the body's load ℓ (that of the solve, per
        load case and step), M o = Pᵀ(ℓ − S (w + q)) + ℓ_o. Given the contact forces ``r`` of that
        state on the body (3p or (p, 3)) and every counterpart held, the same o is
        S_f⁻¹(ℓ_o − Pᵀ r) (M o − Pᵀ S P o = S_f o), with no factorization per design."""
        f = self.foundation
        if r is not None and self.compliant:
            return f.support_compliance(f.ell_o - self._P.T @ np.ravel(r))
        u = np.ravel(w) + f.q_f
        return self._solve_M(self._P.T @ ell - self._G.T @ u + f.ell_o)

    def adjoint_z(self, v_u: np.ndarray) -> np.ndarray:
        """z = S⁻¹ S_eff v_u (3p,): the design terms' adjoint on the body's contact DOFs."""
        self._woodbury()
        return v_u - self._P @ self._solve_M(self._G.T @ v_u)

    def body_displacement(self, w: np.ndarray, r: np.ndarray, ell: np.ndarray | None = None) -> np.ndarray:
        """The body's contact displacement u_c = w + Π u_f = w + Π q_f − C r (3p,); with the
        counterparts of several pairs w + Π o + q (:meth:`support_displacement`, ``ell`` the
        body's condensed load of the solve)."""
        f = self.foundation
        if f.ell_o is not None:
            return np.ravel(w) + self._P @ self.support_displacement(w, ell, r) + f.q_f
        return np.ravel(w) + f.partner_displacement(r)


def locate_partners(points: np.ndarray, faces: np.ndarray, ftype: str, xy: np.ndarray, contact_nodes, where: str,
                    what: str = "contact node(s)"):
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
        if what == "contact node(s)":
            first = ", ".join(f"contact node {m} (body node {int(contact_nodes[m])}) at {_fmt(xy[m])}"
                              for m in miss[:5])
        else:
            first = ", ".join(f"{_fmt(xy[m])} (on the face of body node {int(contact_nodes[m])})" for m in miss[:5])
        raise ConfigError([f"{where}: the vertical lines of {miss.size} of {p} {what} miss the foundation's "
                           f"top face, first: {first}"])
    N, _ = ft.shape(ref)
    return face, N


def ray_partners(points: np.ndarray, faces: np.ndarray, ftype: str, x: np.ndarray, n: np.ndarray, contact_nodes,
                 where: str):
    """(face (p,), weights (p, k), gap (p,)): where the line x_m − g n_m through each contact node
    along its unit contact normal n_m meets the top face (the nearest meeting, |g| smallest), the
    face's shape functions there and the signed distance g (negative where the node lies inside
    the foundation). Newton on x_f(ξ) + g n_m = x_m per candidate face. ConfigError naming the
    nodes whose lines miss the face."""
    ft = face_type(ftype)
    X = points[faces]                                               # (F, k, 3)
    nc = FACE_CORNERS[ftype]
    centre = X[:, :nc].mean(axis=1)
    diam = np.linalg.norm(X[:, :nc] - centre[:, None], axis=2).max(axis=1)
    v = centre[None] - x[:, None]                                   # (p, F, 3)
    off = np.linalg.norm(v - np.einsum("pfj,pj->pf", v, n)[..., None] * n[:, None], axis=2)
    m, f = np.nonzero(off <= 1.5 * diam[None])
    quad = ft.name.startswith("quad")
    xi = np.zeros((m.size, 2)) if quad else np.full((m.size, 2), 1.0 / 3.0)
    g = np.zeros(m.size)
    for _ in range(NEWTON_STEPS):
        N, dN = ft.shape(xi)
        res = np.einsum("qa,qaj->qj", N, X[f]) + g[:, None] * n[m] - x[m]
        J = np.stack([np.einsum("qa,qaj->qj", dN[..., 0], X[f]), np.einsum("qa,qaj->qj", dN[..., 1], X[f]), n[m]],
                     axis=2)
        step = np.linalg.solve(J, res[..., None])[..., 0]
        xi -= step[:, :2]
        g -= step[:, 2]
        if np.abs(step).max(initial=0.0) < 1e-14 * max(1.0, float(np.abs(x).max())):
            break
    if quad:
        inside = np.all(np.abs(xi) <= 1 + INSIDE_TOL, axis=1)
    else:
        inside = (xi.min(axis=1) >= -INSIDE_TOL) & (xi.sum(axis=1) <= 1 + INSIDE_TOL)
    p = x.shape[0]
    best = np.full(p, -1)
    best_g = np.full(p, np.inf)
    for i in np.flatnonzero(inside):
        if abs(g[i]) < abs(best_g[m[i]]):
            best[m[i]], best_g[m[i]] = i, g[i]
    miss = np.flatnonzero(best < 0)
    if miss.size:
        first = ", ".join(f"contact node {k} (body node {int(contact_nodes[k])}) at {_fmt(x[k])}" for k in miss[:5])
        raise ConfigError([f"{where}: the normal lines of {miss.size} of {p} contact node(s) miss the foundation's "
                           f"top face, first: {first}"])
    N, _ = ft.shape(xi[best])
    return f[best], N, best_g


def smooth_gaps(points, top, ftype: str, x: np.ndarray, n: np.ndarray, tol: float):
    """The gaps along the contact normals n_m to the plane or circular cylinder the top face's nodes
    lie on (to ``tol``), or None when they lie on neither: surface smoothing, as for interference
    fits in Abaqus. A faceted cylinder's chords lie inside it by ρ(1 − cos(Δθ/2)), which on a
    mesh that does not match the body's is of the order of an interference itself; its nodes lie on
    the cylinder, so the smooth surface is the one the mesh approximates. The partners' weights
    stay those of the faceted face."""
    from ..design.chart import face_normals, fit_cylinder, fit_plane
    y = points[np.unique(top.faces)]
    nf, _ = face_normals(points, top.faces, ftype)
    plane, res = fit_plane(y, nf)
    if res <= tol:
        return ((x - plane.origin) @ plane.normal) / np.einsum("ij,j->i", n, plane.normal)
    cyl, res = fit_cylinder(y, nf)
    if cyl is None or res > tol:
        return None
    a = cyl.axis
    w = x - cyl.origin
    w -= np.outer(w @ a, a)
    nt = n - np.outer(n @ a, a)
    A, B, C = np.sum(nt * nt, axis=1), np.sum(w * nt, axis=1), np.sum(w * w, axis=1) - cyl.radius ** 2
    disc = np.sqrt(np.maximum(B * B - A * C, 0.0))
    roots = np.stack([(B - disc) / A, (B + disc) / A])
    return roots[np.argmin(np.abs(roots), axis=0), np.arange(x.shape[0])]


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


def auto_partner(weights: np.ndarray, body_degree: int, tol: float = 1e-9, curved: bool = False) -> str:
    """``partner = "auto"``: 'point' where every point partner is a node of the top face (one
    weight 1: matching meshes, where point partners are exact node-to-node contact) or the body's
    faces are quadratic on a curved face (the transformed basis is built on the plane x3 = 0),
    else 'mortar' — point partners do not converge as the foundation alone is refined, and mortar
    partners pass the contact patch test on non-matching meshes (docs/foundation.md, docs/mortar.md)."""
    on_nodes = bool(np.all(np.abs(weights).max(axis=1) >= 1.0 - tol))
    return "point" if on_nodes or (body_degree != 1 and curved) else "mortar"


def mortar_partners(body, fm, where: str, chart=None):
    """(rows, cols, values, T) of Π = D⁻¹M for ``partner = "mortar"`` (:mod:`contactopt.fem.mortar`):
    the body's contact face projected along x3 on the top face x3 = 0, segmented against the top
    faces, the relative displacement of contact node m weighted by its dual basis function Φ_m,

        w_m = u_m − (Π u_f)_m = D_mm⁻¹ ∫ Φ_m (u − u_f) dA,

    so that a uniform pressure and a uniform strain pass across non-matching meshes exactly. Per
    node the order is (t1, t2, ν) = (x1, x2, x3), ν = +x3 into the body. Rows are contact nodes,
    columns foundation nodes. The body's face must lie over the top face and be linear.

    A curved contact face (``chart``, :mod:`contactopt.design.chart`) is segmented on its chart:
    both faces are mapped to the chart's coordinates ξ — on a cylinder (ρθ, axial position), the
    top face's nodes at the same angle as the body's whatever their radius — and clipped and
    integrated there. Π's rows still sum to one and reproduce fields linear in ξ, so the
    relative displacement keeps the form of the flat face's; Π acts on the nodes' global
    components, rotated into the contact frames (t1, t2, n_m) afterwards (:meth:`Foundation.rotate`).
    Top faces that straddle the cylinder's cut θ = ±π (the side opposite the body's face) are
    left out.

    Six-node triangles (a flat face only) take the transformed dual basis: T (p × p, on the
    contact nodes; None on linear faces) is the change of basis N̂ = T N, and the rows of Π are
    those of the transformed nodal values û = T⁻ᵀ u (:mod:`contactopt.fem.mortar`)."""
    ref = body.reference
    ftype = face_type(ref.face_type)
    if ftype.degree != 1 and chart is not None:
        raise ConfigError([f"{where}: foundation.partner = 'mortar' on a curved face needs a body of linear "
                           f"elements (its contact face has {ftype.name} faces); use partner = 'point'"])
    faces = body.contact_face.faces
    top = fm.top.faces
    if chart is None:
        s_xy, m_xy = ref.points[:, :2], fm.reference.points[:, :2]
    else:
        s_xy = np.zeros((ref.n_nodes, 2))
        used = np.unique(faces)
        s_xy[used] = chart.parameters(ref.points[used])
        m_xy = chart.parameters(fm.reference.points)
        if chart.kind == "cylinder":
            span = np.ptp(m_xy[top][:, :, 0], axis=1)
            top = top[span < np.pi * chart.radius]
    D, M, seg = mortar_matrices(ftype.name, faces, s_xy, fm.reference.face_type, top, m_xy)
    coupling = MortarCoupling(D, M, seg, body.contact_nodes)
    if coupling.uncovered.size:
        f = coupling.uncovered
        first = ", ".join(f"face of body nodes {faces[i, :FACE_CORNERS[ref.face_type]].tolist()} "
                          f"({100 * (1 - seg.covered[i] / seg.slave_area[i]):.3g} % outside)" for i in f[:3])
        raise ConfigError([f"{where}: {f.size} face(s) of the contact face do not lie wholly over the "
                           f"foundation's top face (mortar partners integrate over them), first: {first}"])
    Pi = coupling.Pi.tocoo()
    log.info("mortar partners: %d cells of the segmentation of %d body faces against %d top faces",
             seg.n_cells, faces.shape[0], top.shape[0])
    basis = None
    if ftype.degree != 1:
        off = open_edges(body)
        if off.size:
            raise ConfigError([f"{where}: foundation.partner = 'mortar' on six-node triangles needs every node of "
                               f"an edge of the contact face in contact (the transformed basis mixes an edge's "
                               f"nodes), and {off.size} node(s) on such edges are not, first: body node "
                               f"{int(off[0])}"])
        nodes = body.contact_nodes
        basis = sp.csr_matrix(transformed_basis(ftype, faces, ref.n_nodes)[nodes][:, nodes])
    return Pi.row, Pi.col, Pi.data, basis


def open_edges(body) -> np.ndarray:
    """The nodes of the contact face outside the contact set that share an edge of a six-node
    triangle with a contact node (empty on linear faces): the transformed basis (fem.mortar) mixes
    an edge's nodes, so it needs whole edges in contact."""
    ref = body.reference
    ftype = face_type(ref.face_type)
    faces = body.contact_face.faces
    off = np.setdiff1d(np.unique(faces), body.contact_nodes)
    if ftype.degree == 1 or off.size == 0:
        return np.zeros(0, int)
    T = transformed_basis(ftype, faces, ref.n_nodes)
    nodes = body.contact_nodes
    mixed = (abs(T[off][:, nodes]).sum(axis=1).A1 > 0) | (abs(T[nodes][:, off]).sum(axis=0).A1 > 0)
    return off[mixed]


def averaged_partners(body, fm, where: str):
    """(rows, cols, values) of Π for ``partner = "average"``: contact node m's partner
    displacement is the mean of u_f over its tributary area on the contact face,

        (Π u_f)_m = ∫ φ_m u_f dA / ∫ φ_m dA,

    φ_m the body's face shape function of node m, integrated over the body's contact faces
    projected on x3 = 0 by a composite Gauss rule fine enough for the foundation's faces. The
    force −r_m on the foundation is then the traction r_m φ_m/∫φ_m (work-conjugate): a smooth
    load, so the foundation's compliance converges as its mesh is refined, where point partners
    carry a point load whose compliance grows like 1/h_f (docs/foundation.md). Rows are contact
    nodes, columns foundation nodes."""
    ref = body.reference
    ftype = face_type(ref.face_type)
    if ftype.degree != 1:
        raise ConfigError([f"{where}: foundation.partner = 'average' needs a body of linear elements "
                           f"(its contact face has {ftype.name} faces, whose corner nodes carry no area); "
                           "use partner = 'point'"])
    faces = body.contact_face.faces
    X = ref.points[faces, :2]                                     # (F, n, 2)
    top = fm.reference.points[fm.top.faces[:, :FACE_CORNERS[fm.reference.face_type]], :2]
    h_body = np.median(np.linalg.norm(X - np.roll(X, -1, axis=1), axis=2))
    h_top = np.median(np.linalg.norm(top - np.roll(top, -1, axis=1), axis=2))
    k = max(2, int(np.ceil(2.0 * h_body / h_top)))
    q, w = _composite_rule(ftype.name, k)
    N, dN = ftype.shape(q)                                        # (Q, n), (Q, n, 2)
    x = np.einsum("qa,fai->fqi", N, X)
    J = np.einsum("qaj,fai->fqij", dN, X)
    dA = np.abs(np.linalg.det(J)) * w                             # (F, Q)
    which = np.full(ref.n_nodes, -1)
    which[body.contact_nodes] = np.arange(body.contact_nodes.size)
    xq = x.reshape(-1, 2)
    fq, Nf = locate_partners(fm.reference.points, fm.top.faces, fm.reference.face_type, xq,
                             np.repeat(faces[:, 0], q.shape[0]), where, what="quadrature point(s) of the contact face")
    fnodes = fm.top.faces[fq]                                     # (F·Q, nf)
    rows, cols, vals = [], [], []
    phi = (N[None] * dA[:, :, None]).reshape(-1, N.shape[1])      # (F·Q, n): φ_a dA
    for a in range(N.shape[1]):
        m = which[np.repeat(faces[:, a], q.shape[0])]
        ok = m >= 0                                               # clamped face nodes: no contact node
        rows.append(np.repeat(m[ok], fnodes.shape[1]))
        cols.append(fnodes[ok].ravel())
        vals.append((phi[ok, a][:, None] * Nf[ok]).ravel())
    rows, cols, vals = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
    area = np.bincount(rows, weights=vals, minlength=body.contact_nodes.size)   # Σ_b N_b = 1: ∫φ_m dA
    return rows, cols, vals / area[rows]


def _composite_rule(name: str, k: int):
    """Points (Q, 2) and weights of a composite rule on the reference face: k×k squares with
    2×2 Gauss on [−1, 1]², or k² triangles with the 3-point rule on the unit triangle."""
    if name == "quad":
        g = np.array([-1.0, 1.0]) / np.sqrt(3.0)
        t = (np.arange(k)[:, None] + (g[None] + 1) / 2).ravel() * (2.0 / k) - 1.0      # (2k,)
        q = np.array([(a, b) for b in t for a in t])
        return q, np.full(q.shape[0], (1.0 / k) ** 2)
    qt, wt = tri_rule(2)
    pts, wts = [], []
    for i in range(k):
        for j in range(k - i):
            tris = [((i, j), (i + 1, j), (i, j + 1))]
            if i + j <= k - 2:
                tris.append(((i + 1, j), (i + 1, j + 1), (i, j + 1)))
            for A, B, C in tris:
                A, B, C = np.array(A) / k, np.array(B) / k, np.array(C) / k
                pts.append(A + np.outer(qt[:, 0], B - A) + np.outer(qt[:, 1], C - A))
                wts.append(wt / k ** 2)
    return np.vstack(pts), np.concatenate(wts)


def _fmt(x) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in np.asarray(x)) + ")"
