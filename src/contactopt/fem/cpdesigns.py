"""Designs on counterpart bodies: a designed face on the second body of an assembly.

A ``[[designs]]`` entry may name a counterpart body's part that is a pair's counterpart face (the
slab's top under the block, a plate under a roller). That body then has its own morph,

    x_f(β) = x_f,ref + ϑ_β(x1, x2)·w_f(x_f,ref)·e3,

ϑ_β its Bézier surface on the face's design rectangle in (x1, x2) and w_f its harmonic weight
(1 on the designed face, 0 on the nodes whose x3 component is clamped, on its loaded part and on
its other pairs' faces), and its stiffness K_f(β), loads f_f(β) and condensed compliance
C(β) = Π K_f(β)⁻¹ Πᵀ are formed per design (:meth:`CounterpartDesigns.foundation_at`); the
counterparts no design moves keep what was condensed once per run. α = (α_face, β): the face
body's designs first, then the counterparts' in ``[[designs]]`` order; the face body's morph does
not see β (:class:`PaddedMorph`), the counterpart's does not see α_face.

Partners frozen at the reference: the partner of each contact node (its point on the counterpart
face and the weights Π) is found once on the reference meshes and kept, so Π does not depend on
β. On a face on a plane x3 = const moved along e3 (the only face taken so far) the vertical
partner search is unchanged by the motion anyway; along the contact normals of a curved face of
the face body Π is the reference's. The partner point moves with the face: the gap of contact
node m falls by n_m·(Π δx_f)_m, so the gap rows take the counterpart design's columns

    ∂g_m/∂β = −n_m·(Π ∂x_f/∂β)_m     (the sign of a counterpart that moves towards the body).

Subgradient (the adjoint (4.15) keeps its form): with r the contact force on the face body (per
node (t1, t2, ν)), the counterpart carries −Πᵀr, u_f = K_f⁻¹(f_f − Πᵀr) (fem.foundation). The
contact law's r = S_eff w − ℓ_eff differentiated at fixed w gives −S_eff Π K_f⁻¹(∂K_f u_f − ∂f_f)
for the counterpart (S_eff S⁻¹(∂S u_c − ∂ℓ) for the face body), so its design term is

    ṽ_fᵀ(∂K_f/∂β u_f − ∂f_f/∂β),   ṽ_f = −K_f⁻¹ Πᵀ s,

s = S_eff v_u the adjoint's contact force (with ∂J/∂u on every DOF of the face body, s gains
what J sees of the partners' displacement: s = S_eff(v_u − C y_c) + y_c), plus v_λᵀ ∂g/∂β.
"""

from __future__ import annotations

import copy
import logging

import numpy as np

from ..design.bezier import BezierSurface
from ..design.chart import face_normals
from ..design.several import DesignSurfaces, surfaces_of
from ..errors import ConfigError, MeshError
from ..mesh.body import _domain
from ..mesh.morph import MorphedMesh, moved
from ..mesh.reference import describe_part, select_part
from .weight import harmonic_weight

log = logging.getLogger(__name__)


class CounterpartDesign:
    """One design on a counterpart body: its ``part`` (index into the model's counterparts), its
    face's nodes on the counterpart's mesh, surface, weight and morph, and its columns of α."""

    def __init__(self, index: int, part: int, face, surface: BezierSurface, morph: MorphedMesh, columns: slice):
        self.index, self.part, self.face = index, part, face
        self.surface, self.morph, self.columns = surface, morph, columns


class CounterpartDesigns:
    """The designs on counterpart bodies of a model (module docstring): ``designs`` in
    ``[[designs]]`` order, ``n_face`` the size of the face body's block of α."""

    def __init__(self, designs: list, n_face: int, foundation, backend: str = "auto"):
        self.designs, self.n_face, self.base, self.backend = list(designs), n_face, foundation, backend
        self._last = None           # (β, the counterparts formed at β)

    @property
    def parts(self) -> list:
        """The indices of the designed counterpart bodies, each once."""
        return list(dict.fromkeys(d.part for d in self.designs))

    def coordinates(self, b: int, beta: np.ndarray) -> np.ndarray:
        """The node coordinates of counterpart body b at the counterparts' design β."""
        x = self.base.parts[b].mesh.reference.points.copy()
        for d in self.designs:
            if d.part == b:
                a = beta[d.columns.start - self.n_face:d.columns.stop - self.n_face]
                if not np.all(np.isfinite(a)):
                    raise MeshError("design produces non-finite surface heights")
                moved(x, d.morph, a)
        return x

    def foundation_at(self, alpha: np.ndarray):
        """The model's counterparts (a :class:`~contactopt.fem.foundation.Foundation` of one pair or
        the :class:`~contactopt.fem.counterparts.Counterparts` of several) with the designed ones
        formed on their meshes at α (K_f, its condensation, C, q_f, ℓ_o); the others as condensed
        once per run. The last design's is kept."""
        beta = np.asarray(alpha, float)[self.n_face:].copy()
        if self._last is not None and np.array_equal(self._last[0], beta):
            return self._last[1]
        base = self.base
        if len(base.parts) == 1 and base.parts[0] is base:       # one pair: the Foundation itself
            out = base.at_coordinates(self.coordinates(0, beta), self.backend)
        else:
            out = copy.copy(base)
            out.parts = list(base.parts)
            for b in self.parts:
                out.parts[b] = base.parts[b].at_coordinates(self.coordinates(b, beta), self.backend)
            out.refresh()
        self._last = (beta, out)
        return out

    def gap_columns(self, p: int, n_design: int) -> np.ndarray:
        """(p, n_design) ∂g/∂β at the contact nodes (module docstring), zero in the face body's columns."""
        G = np.zeros((p, n_design))
        base = self.base
        for d in self.designs:
            f = base.parts[d.part]
            dx3 = d.morph.dx3_dalpha()[f.support]                     # (n_s, nβ) along e3
            delta = np.zeros((3 * f.support.size, dx3.shape[1]))
            delta[2::3] = dx3
            rows = base.rows[d.part]
            G[rows, d.columns] -= np.asarray(f.Pi @ delta)[2::3]
        return G

    def design_terms(self, found, r: np.ndarray, s: np.ndarray, n_design: int) -> np.ndarray:
        """(n_design,) ṽ_fᵀ(∂K_f/∂β u_f − ∂f_f/∂β) of every counterpart design (module docstring),
        for the contact forces r on the face body and the adjoint's contact force s (3p, per node
        (t1, t2, ν)); ``found`` the counterparts at this design (:meth:`foundation_at`)."""
        out = np.zeros(n_design)
        r, s = np.reshape(r, (-1, 3)), np.reshape(s, (-1, 3))
        for b in self.parts:
            f = found.parts[b]
            rows = found.rows[b]
            u = f.displacement(r[rows].ravel())
            x = np.zeros(f.assembler.n_free)
            x[f._support_free] = -(f.P.T @ s[rows].ravel())
            v = f.assembler.to_full(f.condensation.solve(x))
            d = f.assembler.stiffness_shape_contraction(f.coords, u, v)
            d -= f.loads.shape_contraction(f.coords, v, f.assembler)
            for dsg in self.designs:
                if dsg.part == b:
                    out[dsg.columns] += dsg.morph.contract_dx(d)
        return out


class PaddedMorph:
    """The face body's morph in a model whose α also holds counterpart designs: it moves the face
    body by α's first ``n_face`` entries and none by the others (its columns of ∂x/∂α are zero
    there); everything else is the morph's own."""

    def __init__(self, inner, surface: DesignSurfaces, n_face: int):
        self.inner, self.surface, self.n_face = inner, surface, n_face
        self.ratio = None

    def __getattr__(self, name):
        if name == "inner":            # (not set yet: a copy or an unpickling in progress)
            raise AttributeError(name)
        return getattr(self.inner, name)

    @property
    def _pad(self) -> int:
        return self.surface.size - self.n_face

    def coordinates(self, alpha) -> np.ndarray:
        alpha = self.surface.as_vector(alpha)
        if not np.all(np.isfinite(alpha)):
            raise MeshError("design produces non-finite surface heights")
        if self.ratio is not None:
            self.ratio.check(alpha)
        return self.inner.coordinates(alpha[:self.n_face])

    def contract_dx(self, d: np.ndarray) -> np.ndarray:
        return np.concatenate([self.inner.contract_dx(d), np.zeros(self._pad)])

    def gap_matrix(self) -> np.ndarray:
        G = self.inner.gap_matrix()
        return np.hstack([G, np.zeros((G.shape[0], self._pad))])


def padded_ratio(jr, pad: int):
    """The Jacobian ratio of the face body (mesh.morph.JacobianRatio) with ``pad`` zero columns: the
    counterparts' designs do not move its elements."""
    out = copy.copy(jr)
    out.R = np.hstack([jr.R, np.zeros((jr.R.shape[0], pad), jr.R.dtype)])
    return out


def build_counterpart_designs(model, cfg, foundation) -> CounterpartDesigns:
    """The counterpart designs of ``cfg`` (``cfg.counterpart_designs``) on the model's counterparts
    ``foundation``; ConfigError naming what is not taken so far."""
    _check_objectives(cfg)
    names = [c.counterpart for c in cfg.assembly.contacts]
    parts = foundation.parts
    n_face = sum(s.size for s in surfaces_of(model.surface))
    start, out, problems = n_face, [], []
    for n, df in cfg.counterpart_designs:
        key = f"designs[{n}]"
        pair = names.index(cfg.assembly.designs[n])
        b = next(i for i, ks in enumerate(foundation.pairs) if pair in ks)
        f = parts[b]
        why = _not_taken(f, df.design)
        if why:
            problems.append(f"{cfg.source}: {key}.face = {cfg.assembly.designs[n]!r}: {why}")
            continue
        ref = f.mesh.reference
        try:
            face = select_part(ref, df.face, f.mesh.tol)
        except MeshError as exc:
            problems.append(f"{cfg.source}: {key}.face = {describe_part(df.face)}: {exc}")
            continue
        nf, _ = face_normals(ref.points, face.faces, ref.face_type)
        if np.abs(nf[:, 2]).min(initial=1.0) < 1.0 - 1e-9:
            problems.append(f"{cfg.source}: {key}.face = {cfg.assembly.designs[n]!r}: a designed counterpart face "
                            "lies on a plane x3 = const so far (it moves along x3), and this face is not plane")
            continue
        try:
            (x1lo, x1hi), (x2lo, x2hi) = _domain(df.design.domain, ref.points[face.nodes, :2], face, f.mesh.tol,
                                                 cfg.source)
        except ConfigError as exc:
            problems += [q.replace("design.", f"{key}.").replace("body.contact", f"{key}.face") for q in exc.problems]
            continue
        d1, d2 = df.design.degree
        surface = BezierSurface(d1, d2, x1hi - x1lo, x2hi - x2lo, x1lo, x2lo)
        zero = _held_nodes(f, face.nodes)
        if np.intersect1d(zero, face.nodes).size:
            problems.append(f"{cfg.source}: {key}.face = {cfg.assembly.designs[n]!r}: its nodes are clamped along x3 "
                            "or lie on the loaded part, so the design cannot move them")
            continue
        weight = harmonic_weight(f.assembler, ref.points, face.nodes, zero)
        morph = MorphedMesh(ref, surface, weight, face.nodes)
        out.append(CounterpartDesign(n, b, face, surface, morph, slice(start, start + surface.size)))
        start += surface.size
    if problems:
        raise ConfigError(problems)
    return CounterpartDesigns(out, n_face, foundation, backend=cfg.linear_solver.library)


# objectives whose ∂J/∂α at a fixed state holds the counterparts' compliance C (the body's u_c = w + Π u_f)
THROUGH_COMPLIANCE = ("compliance", "frictional_dissipation")


def _check_objectives(cfg) -> None:
    """ConfigError naming each objective or constraint not taken with a counterpart design so far:
    those whose ∂J/∂α at a fixed state goes through the counterpart's compliance C(β) (this module
    differentiates the contact law, not them)."""
    which = ", ".join(cfg.assembly.designs[n] for n, _ in cfg.counterpart_designs)
    given = (("objective", cfg.objective.types), ("constraints", {c.type for c in cfg.constraints}))
    problems = [f"{cfg.source}: {where} {t!r} with a design on a counterpart body ({which}): its derivative "
                "through the counterpart's compliance C(α) is not formed so far; use another objective (the "
                "target forces, the pressure objectives, peak_stress)"
                for where, types in given for t in sorted(types) if t in THROUGH_COMPLIANCE]
    if problems:
        raise ConfigError(problems)


def _not_taken(f, design) -> str:
    """Why the counterpart ``f`` takes no design so far ('' where it does)."""
    if f.rigid is not None:
        return ("the counterpart body is held only by its contacts; a designed counterpart is held by its clamps "
                "so far")
    if f.condensation is None:
        return ("a designed counterpart is condensed per design on the condensation path so far; use "
                "linear_solver.path = 'condensation'")
    if f.basis is not None:
        return "mortar partners on six-node triangles take no counterpart design so far; use partner = 'point'"
    if f.control == "force":
        return "a counterpart pressed by control = 'force' takes no design so far"
    if design.motion != "vertical":
        return "a designed counterpart face moves along x3 (motion = 'vertical') so far"
    return ""


def _held_nodes(f, face_nodes) -> np.ndarray:
    """The nodes of counterpart f a design does not move: x3 clamped, the loaded part, and the
    faces of its other pairs (their partners stay where they were found)."""
    fm = f.mesh
    node, comp = np.divmod(np.asarray(fm.fixed_dofs), 3)
    held = [node[comp == 2]]
    if fm.loaded is not None:
        held.append(np.asarray(fm.loaded))
    others = np.setdiff1d(f.support, face_nodes)          # partners of this body's other pairs
    held.append(others)
    return np.unique(np.concatenate(held)).astype(np.int64)
