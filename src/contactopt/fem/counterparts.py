"""Several elastic counterparts of one face body: the pairs of an assembly on the condensation path.

An assembly of K contact pairs whose faces all lie on one body (the face body, the one the design
moves) and whose counterparts are parts of B ≤ K other bodies: pair k's face nodes (rows
``pair_rows[k]`` of the contact nodes) meet its counterpart part, as one ``[foundation]`` meets its
body (:class:`~contactopt.fem.foundation.Foundation`: partners Π_b, compliance C_b = Π_b W_b Π_bᵀ,
q_b = Π_b K_b⁻¹ f_b). A body that is the counterpart of several pairs (the slot of a dovetail under
both flanks of the blade, a race under two rollers) is condensed once, onto the union of its
pairs' supports: its rows ``rows[b]`` are its pairs' contact nodes one pair after the other, each
pair's partners searched on its own counterpart part alone, and its compliance block couples its
pairs' nodes (the flanks talk through the slot). The bodies share no DOF, so with the relative
displacement w = u_c − Π u_o of every contact node (DESIGN: W = Σ_b B_b A_b⁻¹ B_bᵀ over the bodies)

    Π = diag_b(Π_b) (rows in contact-node order),   C = diag_b(C_b),   q = (q_b),   S_o = diag_b(S_b),

and the coupling of :class:`~contactopt.fem.foundation.Coupling` takes them as it takes one
foundation: S_eff = (S⁻¹ + C)⁻¹, each counterpart body condensed once per run, the face body once
per design. One pair is the foundation itself (this class is not built for it).

Contact convention: per contact node (t1, t2, ν) in the node's frame (ν from the counterpart to the
face body), r the contact force on the face body, λ = r_ν ≥ 0; counterpart body b carries −Π_bᵀ r_b.

A pair's face may also lie on a counterpart body of another pair (:mod:`contactopt.fem.faces`): its
contact nodes are rows of the law after the face body's (``p`` counts them all), that body's support
holds them too, and E (``face_map``) maps its support DOFs onto them; such a body carries +Eᵀ r_b.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..errors import ConfigError
from .faces import FaceRows
from .faceviews import face_frames

log = logging.getLogger(__name__)


class _BlockCondensation:
    """The counterparts' condensed stiffnesses as one block-diagonal S (for the coupling's M)."""

    def __init__(self, parts):
        self.S = sla.block_diag(*[np.asarray(f.condensation.S) for f in parts])


class RigidCounterpart:
    """A rigid counterpart of one of several pairs (``[[contacts]] counterpart`` a table of
    ``[obstacle]``): a counterpart block with no DOFs. Its partners and compliance are empty
    (Π_k has no columns, C_k = 0), its gaps ``gap0`` the distances of the pair's contact nodes to
    the obstacle along its normal (as the one-pair obstacle's, fem.model), and a prescribed
    translation d (``control = "displacement"``) its ``motion`` R_mᵀ d per contact node (t1, t2, ν):
    the law's relative displacement is w = u_c − R_mᵀ d, as with an elastic counterpart moved by d."""

    basis = None
    rigid = None          # no rigid motions free: it is held
    condensed = True
    n_nodes = 0
    partner = "rigid"
    memory_sizes: list = []     # no DOFs: nothing to count (fem.memory)

    def __init__(self, spec, gap0: np.ndarray):
        self.spec, self.control = spec, spec.control
        p = np.asarray(gap0).size
        self.gap0 = np.asarray(gap0, float).copy()
        self.translation = np.asarray(spec.displacement, float) if spec.control == "displacement" else None
        self.P = sp.csr_matrix((3 * p, 0))
        self.Pi = sp.csr_matrix((3 * p, 0))
        self.C = np.zeros((3 * p, 3 * p))
        self.ell_f = np.zeros(0)
        self.load_resultant = np.zeros(3)
        self.condensation = type("Empty", (), {"S": np.zeros((0, 0))})()
        self.rotate(np.broadcast_to(np.eye(3), (p, 3, 3)))

    def rotate(self, R: np.ndarray) -> None:
        """Its translation in the contact nodes' frames R (p, 3, 3), columns (t1, t2, n)."""
        self.motion = None
        if self.translation is not None and np.any(self.translation):
            self.motion = np.einsum("mij,i->mj", R, self.translation).ravel()
        self.q_f = np.zeros(self.P.shape[0]) if self.motion is None else self.motion.copy()

    def displacement(self, r=None, s: float = 0.0, support=None, **_) -> np.ndarray:
        """No DOFs: an empty displacement (the file of the counterpart bodies leaves it out)."""
        return np.zeros(0)

    def summary(self) -> dict:
        sp_ = self.spec
        out = {"rigid": sp_.shape, "control": sp_.control}
        if sp_.control == "displacement":
            out["displacement"] = list(map(float, sp_.displacement))
        return out


def build_counterparts(specs, body, source: str, check=None, normals=None, frames=None,
                       names=None, rigid=None, condensed: bool = True, faces=None) -> Counterparts:
    """The counterparts of the pairs ``specs`` (``[foundation]`` tables, one per pair) of ``body``:
    one :class:`~contactopt.fem.foundation.Foundation` per counterpart body, named per pair by
    ``names`` (None: each pair its own body), built on the pairs' views of the body (their faces
    and nodes); ``normals`` (p, 3) of a curved face, ``frames`` (p, 3, 3) the contact nodes' frames
    the coupling is expressed in. ``rigid``: {pair: (its ``[obstacle]``, the gaps of its contact
    nodes)} of the pairs against rigid counterparts (:class:`RigidCounterpart`; their ``specs``
    entries are not read).

    ``faces``: {pair k: (the counterpart body its face lies on, its face part)} of the pairs whose
    faces lie off the face body (:mod:`contactopt.fem.faces`): their rows follow the face body's,
    pair after pair, each body condensed before the counterpart of its faces; ``frames`` are then
    the face body's rows' (their own are their faces' frames)."""
    from .foundation import Foundation
    rigid = rigid or {}
    faces = faces or {}
    names = list(range(len(specs))) if names is None else list(names)
    groups = {}
    for k, name in enumerate(names):
        groups.setdefault(("rigid", k) if k in rigid else name, []).append(k)
    built, views_of, order = {}, {}, _build_order(groups, faces)
    p_a = body.contact_nodes.size
    for key in order:
        pairs = groups[key]
        if isinstance(key, tuple):
            built[key] = RigidCounterpart(*rigid[pairs[0]])
            continue
        views = []
        for k in pairs:
            if k in faces:
                v = views_of[k]
                v.owner = (faces[k][0], key)                  # (named in messages)
                views.append((specs[k], v, v.normals))
            else:
                views.append((specs[k], body.pair_view(k),
                              None if normals is None else normals[np.flatnonzero(body.pair_of == k)]))
        where = f"{source}: {_which(pairs)}"
        spec, view, n = views[0]
        mine = {k: part for k, (b, part) in faces.items() if b == key}
        f = built[key] = Foundation(spec, view, source=where, check=check, normals=n, floating=True,
                                    shared=views if len(pairs) > 1 else None, condensed=condensed, faces=mine)
        views_of.update(f.face_views)
    start, off_rows = p_a, {}
    for k in sorted(faces):
        off_rows[k] = np.arange(start, start + views_of[k].contact_nodes.size)
        start += off_rows[k].size

    def rows_of(k):
        return off_rows[k] if k in faces else np.flatnonzero(body.pair_of == k)
    parts = [built[key] for key in groups]
    rows = [np.concatenate([rows_of(k) for k in pairs]) for pairs in groups.values()]
    out = Counterparts(parts, rows, start, pairs=list(groups.values()),
                       pair_rows=[rows_of(k) for k in range(len(specs))])
    if faces:
        out.set_faces(p_a, {k: views_of[k] for k in sorted(faces)}, off_rows, [built[faces[k][0]] for k in sorted(faces)],
                      frames)
    elif frames is not None:
        out.rotate(frames)
    return out


def _build_order(groups: dict, faces: dict) -> list:
    """The counterpart bodies (keys of ``groups``) in an order that builds each body that carries a
    face (``faces``: {pair: (body, part)}) before the counterpart of that face (config.assembly
    refuses a cycle)."""
    need = {key: {faces[k][0] for k in pairs if k in faces} for key, pairs in groups.items()}
    order, done = [], set()
    while len(order) < len(groups):
        ready = [key for key in groups if key not in done and need[key] <= done]
        if not ready:
            raise ConfigError(["contacts: the bodies that carry faces off the face body carry each other's faces "
                               "in a cycle"])
        order.append(ready[0])
        done.add(ready[0])
    return order


def _which(pairs: list) -> str:
    """The pairs of one counterpart body in words: ``contacts[1]``, ``contacts[0] and contacts[1]``."""
    words = [f"contacts[{k}]" for k in pairs]
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


class Counterparts:
    """The elastic counterpart bodies of one face body's K pairs (module docstring).

    Attributes as :class:`~contactopt.fem.foundation.Foundation`'s, over all contact nodes: ``P``
    (3p × m, Π on the counterparts' free support DOFs), ``Pi``, ``C``, ``q_f``, ``gap0`` (curved
    faces), ``condensation.S``; ``parts`` the counterpart bodies' foundations, ``rows`` their
    contact nodes (a body's pairs one after the other) and ``pairs`` their pairs' indices;
    ``pair_rows`` the contact nodes of each pair."""

    basis = None          # mortar partners on six-node triangles: one pair only (Foundation)
    translation = None
    face_rows = None      # faces on several bodies: the coupling's design-independent pieces (fem.faces)
    face_map = None       # ... the face nodes of rows b on o: (rows, columns, entries of E)

    def __init__(self, parts: list, rows: list, p: int, pairs=None, pair_rows=None):
        self.parts, self.rows, self.p = list(parts), [np.asarray(r) for r in rows], p
        self.pairs = [[k] for k in range(len(self.parts))] if pairs is None else [list(x) for x in pairs]
        self.pair_rows = self.rows if pair_rows is None else [np.asarray(r) for r in pair_rows]
        for f in self.parts:
            if f.basis is not None:
                raise ConfigError(["contacts: mortar partners on six-node triangles take one pair per model so far; "
                                   "use partner = 'point' or linear elements"])
        # the counterpart body pressed by a force, if any (one per model: config.assembly); a rigid
        # one's search is fem.model's, on no DOFs
        pressed = [b for b, f in enumerate(self.parts) if f.control == "force" and f.n_nodes]
        assert len(pressed) <= 1, "one counterpart body pressed by a force per model (config.assembly)"
        self.pressed = pressed[0] if pressed else None
        self.refresh()

    @property
    def control(self) -> str:
        """'force' where a counterpart body is pressed by a force (its translation s f̂ searched,
        paths/force.py), else 'fixed' (prescribed translations are in q)."""
        return "fixed" if self.pressed is None else "force"

    def refresh(self) -> None:
        """What is gathered from the parts (after one of them changed: a designed counterpart,
        fem.cpdesigns): gaps, the bodies' sizes (fem.memory), the block condensation, the loads' resultant, Π, C, q, ℓ_o."""
        p = self.p
        self.gap0 = None
        if all(f.gap0 is not None for f in self.parts):
            self.gap0 = np.zeros(p)
            for f, r in zip(self.parts, self.rows):
                self.gap0[r] = f.gap0
        self.memory_sizes = [size for f in self.parts for size in f.memory_sizes]
        # (none where the bodies are kept assembled: the full-space path, paths/coupled.py)
        self.condensation = None if any(f.condensation is None for f in self.parts) else _BlockCondensation(self.parts)
        self.load_resultant = sum(f.load_resultant for f in self.parts)
        self._gather()

    def _dofs(self, k: int) -> np.ndarray:
        return (3 * self.rows[k][:, None] + np.arange(3)).ravel()

    def _gather(self) -> None:
        """Π, P, C, q and ℓ_o over all contact nodes from the pairs' (after a rotation into frames):
        q holds only the prescribed translations Π d, the loads enter as ℓ_o (Coupling.ell_eff);
        C is None where a counterpart is held only by its contacts (its compliance is infinite
        along its rigid motions). ``motion`` (3p,): the partners' motion Π f̂ per unit s of the
        body pressed by a force on its contact nodes, zero on the others' (None: none pressed); its
        translation s f̂ is an unknown of the state (paths/force.py), not in q."""
        n = 3 * self.p
        self.P = sp.csr_matrix(self._stack([f.P for f in self.parts]))
        self.Pi = sp.csr_matrix(self._stack([f.Pi for f in self.parts]))
        # (faces on several bodies: the law's compliance is not P W Pᵀ, and the coupling forms S_eff, fem.faces)
        held = self.face_map is None and all(f.C is not None for f in self.parts)
        self.C = np.zeros((n, n)) if held else None
        self.q_f = np.zeros(n)
        self.motion = None if self.pressed is None else np.zeros(n)
        for k, f in enumerate(self.parts):
            d = self._dofs(k)
            if self.C is not None:
                self.C[np.ix_(d, d)] = f.C
            if f.motion is not None:
                if k == self.pressed:
                    self.motion[d] = f.motion
                elif f.control == "displacement":
                    self.q_f[d] = f.motion
        self.ell_o = None if any(f.ell_f is None for f in self.parts) else np.concatenate([f.ell_f for f in self.parts])
        # Π W_o ℓ_o: the partners' displacement under the counterparts' own loads (Coupling.offset)
        self.load_displacement = None
        if self.C is not None and self.ell_o is not None and np.any(self.ell_o):
            self.load_displacement = np.asarray(self.P @ self.support_compliance(self.ell_o))

    def set_faces(self, p_a: int, views: dict, off_rows: dict, carriers: list, frames) -> None:
        """The pairs whose faces lie off the face body (fem.faces): ``views`` {k: its face}, ``off_rows``
        {k: its rows}, ``carriers`` the bodies that carry them (in the order of ``views``), ``frames``
        the face body's rows' frames (None: the axes). Sets every row's frames (``frames``), the rows b's
        pinned frame components (``off_pinned``), areas, E and the coupling's pieces."""
        R = np.zeros((self.p, 3, 3))
        R[:p_a] = np.eye(3) if frames is None else frames
        self.off_pinned = np.zeros((self.p - p_a, 3), bool)
        self.off_areas = np.zeros(self.p - p_a)
        self.off_pairs = np.zeros(self.p - p_a, np.int64)
        self.off_points = np.zeros((self.p - p_a, 3))      # the rows' nodes on their bodies' reference meshes
        self.off_nodes = np.zeros(self.p - p_a, np.int64)   # ... their numbers there
        self.off_columns = np.full((self.p - p_a, 3), -1, np.int64)   # ... their columns of o per component (u1, u2, u3)
        self.off_part = np.zeros(self.p - p_a, np.int64)    # ... the index of their body in ``parts``
        starts = {id(f): s for f, s in zip(self.parts, np.cumsum([0] + [f.P.shape[1] for f in self.parts]))}
        rows, cols, vals = [], [], []
        for (k, v), f in zip(views.items(), carriers):
            mine = off_rows[k]
            Rk, pinned = face_frames(v)
            R[mine] = Rk
            self.off_pinned[mine - p_a] = pinned
            self.off_areas[mine - p_a] = v.areas
            self.off_pairs[mine - p_a] = k
            self.off_points[mine - p_a] = v.reference.points[v.contact_nodes]
            self.off_nodes[mine - p_a] = v.contact_nodes
            col = f.face_columns(v.contact_nodes)                     # (p_k, 3) per global component
            self.off_columns[mine - p_a] = np.where(col >= 0, starts[id(f)] + col, -1)
            self.off_part[mine - p_a] = next(b for b, g in enumerate(self.parts) if g is f)
            for i in range(3):                                        # row 3m + i: t_i · u (frame column i)
                for c in range(3):
                    ok = (col[:, c] >= 0) & (np.abs(Rk[:, c, i]) > 0)
                    rows.append(3 * mine[ok] + i)
                    cols.append(starts[id(f)] + col[ok, c])
                    vals.append(Rk[ok, c, i])
        self.frames = R
        self.off_views = views
        self.face_map = tuple(np.concatenate(x) for x in (rows, cols, vals))
        self.rotate(R)
        # (the condensation path's pieces; the full space keeps the bodies assembled, paths/coupled.py)
        self.face_rows = None if self.condensation is None else FaceRows.build(self, 3 * p_a)

    def _relative(self) -> sp.csr_matrix:
        """Π − E on the free support DOFs: the relative displacement of a motion o of the counterparts."""
        if self.face_map is None:
            return self.P
        rows, cols, vals = self.face_map
        return sp.csr_matrix(self.P - sp.csr_matrix((vals, (rows, cols)), shape=self.P.shape))

    def support_compliance(self, x: np.ndarray) -> np.ndarray:
        """W_o x = diag_b(W_b) x: the displacement of the counterparts' free support DOFs (in the
        order of ``P``'s columns) under the forces x on them; every counterpart held (a rigid one
        has no support DOFs)."""
        out, start = np.empty(x.shape), 0
        for f in self.parts:
            m = f.P.shape[1]
            if m:
                out[start:start + m] = f.W_f @ x[start:start + m]
            start += m
        return out

    def check_held(self, friction, names: list, source: str) -> None:
        """ConfigError naming each rigid motion of a counterpart held only by its contacts that no
        contact force can hold: one that moves no contact node along its normal, where its pairs
        have no friction (``friction`` F per contact node, a scalar or (p,); ``names`` the
        counterparts' bodies in pair order)."""
        mu = np.broadcast_to(np.asarray(friction, float), (self.p,))
        problems = []
        rel = self._relative()
        for b, f, R in self._floating():
            G = np.asarray(rel @ R).reshape(self.p, 3, -1)
            scale = np.abs(G).max(initial=0.0)
            name, pairs = names[self.pairs[b][0]], self.pairs[b]
            for j, motion in enumerate(f.rigid.names()):
                normal = np.abs(G[:, 2, j]).max(initial=0.0) > 1e-9 * max(scale, 1e-300)
                rubbed = np.any((np.abs(G[:, :2, j]).max(axis=1) > 1e-9 * scale) & (mu > 0))
                if not (normal or rubbed):
                    problems.append(f"{source}: bodies.{name}: {motion} is not held: the body is held only by "
                                    f"its contacts, and no contact force of {_which(pairs)} acts along it (it moves "
                                    f"no contact node along its normal, and {'the pair has' if len(pairs) == 1 else 'its pairs have'} "
                                    "no friction); clamp it in bodies." + name + ".clamped")
        if problems:
            raise ConfigError(problems)

    def kernel(self):
        """(R (3p, k), names) of the counterparts held only by their contacts: the relative
        displacement −Π R_o of each free rigid motion R_o (on its free support DOFs), along which
        the coupled stiffness S_eff is singular and the contact forces must balance the body's
        loads (paths/rigid.py); None when every counterpart is held."""
        cols, names = [], []
        rel = self._relative()
        for b, f, R in self._floating():
            cols.append(-(rel @ R))
            names += [f"{n} of the counterpart of {_which(self.pairs[b])}" for n in f.rigid.names()]
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
        """Each counterpart body's full displacement (3·n_k,): its support DOFs from the coupling's
        :meth:`~contactopt.fem.foundation.Coupling.support_displacement` of the law's w under the
        face body's load ℓ, its interior recovered under its own loads, plus its prescribed translation."""
        return self.recovered(coupling.support_displacement(w, ell, r))

    def recovered(self, o: np.ndarray, s: float = 0.0) -> list:
        """Each counterpart's full displacement (3·n_k,) from o on the free support DOFs of all
        (:meth:`displacements`): its interior recovered under its own loads, plus its translation
        (s f̂ of the body pressed by a force, ``s`` the state's translation)."""
        out, start = [], 0
        for f in self.parts:
            m = f.P.shape[1]
            out.append(f.displacement(None, s, support=o[start:start + m]))
            start += m
        return out

    def displacement(self, r: np.ndarray, s: float = 0.0, coupling=None, w=None, ell=None) -> np.ndarray:
        """The counterpart bodies' displacements one after the other (their VTU file tags each body's)."""
        return np.concatenate(self.recovered(coupling.support_displacement(w, ell, r), s))

    def summary(self) -> dict:
        return {"pairs": [f.summary() for f in self.parts]}

    def pair_forces(self, r: np.ndarray) -> list:
        """Σ of the contact forces (per node frame) of each pair: (3,) per pair."""
        r = np.reshape(r, (-1, 3))
        return [r[rows].sum(axis=0) for rows in self.pair_rows]
