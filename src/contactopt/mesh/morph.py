"""The morph of a reference mesh by the design surface, affine in α (docs/theory.md).

    x(α) = x_ref + ϑ_α(x1, x2)·w(x_ref)·e3,

with a weight w fixed on the reference mesh (1 on the contact face, 0 on the parts fixed in
shape; :func:`contactopt.fem.weight.harmonic_weight`). Node coordinates are affine in α, so
∂x3/∂α_k = β_k(x1, x2)·w and the element-wise design-derivative contractions (docs/theory.md) hold unchanged.
On the contact face w = 1: a contact node at (x1, x2, 0) moves to (x1, x2, ϑ_α(x1, x2)), its gap
to the foundation x3 ≤ 0 (outward normal e3 of the foundation) is g = ϑ_α(x1, x2).

ϑ_α is evaluated at the node's (x1, x2) (its chart coordinates ξ) clamped to the design rectangle: nodes of the body that
lie beyond the rectangle (they have w < 1) move like its nearest point, so the Bernstein
polynomials are never extrapolated and the lift stays within [lower, C0]·w on U.

On a face of any shape (:mod:`contactopt.design.chart`) the design surface lives on the face's
chart ξ(x) and, with ``[design] motion = "normal"``, moves each node along a unit direction d(x)
instead of e3 — the face's inward unit normal at its nodes, that of the nearest face node
elsewhere:

    x(α) = x_ref + ϑ_α(ξ(x_ref))·w(x_ref)·d(x_ref),    ∂x/∂α_k = β_k(ξ)·w·d,

still affine in α. The design derivatives contract the per-node coordinate derivative with d
(:meth:`MorphedMesh.contract_dx`); on the paper's map d = e3 and ξ = (x1, x2).

Element quality (docs/theory.md): with h = ϑ_α w the lift, the Jacobian of a morphed element is
J = J_ref + e3 ⊗ ∇_ξ h, so det J / det J_ref = 1 + ∂h/∂x3 (the derivative on the reference
element) — exactly, for every element type, and affine in α: ratio = 1 + R α with R fixed.
:class:`JacobianRatio` checks it per design before assembly and bounds it over U: on U every
control point lies in [lower, C0] (lower = 0 in the paper), so
min_U (Rα)_q ≥ C0·Σ_k min(0, R_qk) + lower·Σ_k max(0, R_qk) — exact for the block (R ≤ 0
there: ratio = 1 − ϑ_α/c, which a negative ϑ_α only raises). With a direction field d that
varies (normal motion on a curved face) the ratio is det(I + Σ_a h_a d_a ⊗ ∇N_a); :class:`JacobianRatio`
then holds its part of first order, 1 + Σ_a h_a d_a·∇N_a, exact where d is constant (a plane).
"""

from __future__ import annotations

import logging

import numpy as np

from ..errors import MeshError

log = logging.getLogger(__name__)


class MorphedMesh:
    """A reference mesh moved by the design surface: ``coordinates(alpha)``, ``dx3_dalpha()``.

    ``reference`` is a :class:`~contactopt.mesh.reference.ReferenceMesh`, ``weight`` the
    (n_nodes,) weight w, ``contact_nodes`` the contact nodes in contact order and
    ``fixed_shape`` the names of the parts with w = 0 (for messages).
    """

    def __init__(self, reference, surface, weight, contact_nodes, *, fixed_shape=(), chart=None, directions=None):
        self.reference = reference
        self.surface = surface
        self.weight = np.asarray(weight, float)
        self.contact_nodes = np.asarray(contact_nodes, np.int64)
        self.fixed_shape = tuple(fixed_shape)
        self.elements = reference.cells
        self.chart = chart                # None: ξ = (x1, x2)
        # (n_nodes, 3) unit directions d of the motion, None: e3 (the paper's vertical map)
        self.directions = None if directions is None else np.asarray(directions, float)
        x = reference.points
        self.moving = np.flatnonzero(self.weight != 0.0)
        xy = self._in_domain(self.chart_points(x[self.moving]))
        # ∂x3/∂α on the moving nodes: β_k(x1, x2)·w; constant in α
        self._basis = surface.basis_matrix(xy[:, 0], xy[:, 1])
        self._dx3 = self._basis * self.weight[self.moving, None]
        self.ratio = None          # JacobianRatio, attached by the model (needs the element type)

    def chart_points(self, x) -> np.ndarray:
        """(k, 2) chart coordinates ξ of points x (k, 3): (x1, x2) without a chart."""
        return x[:, :2] if self.chart is None else self.chart.parameters(x)

    def _in_domain(self, xy):
        s = self.surface
        lo = np.array([s.x1lo, s.x2lo])
        return np.clip(xy, lo, lo + np.array([s.a, s.b]))

    # ------------------------------------------------------------------ topology
    @property
    def n_nodes(self) -> int:
        return self.reference.n_nodes

    @property
    def n_elements(self) -> int:
        return self.reference.n_cells

    @property
    def cell_type(self) -> str:
        return self.reference.cell_type

    @property
    def parts(self) -> dict:
        return self.reference.parts

    # ------------------------------------------------------------------ geometry
    def lift(self, alpha) -> np.ndarray:
        """ϑ_α·w at the moving nodes (in the order of ``self.moving``)."""
        return self._dx3 @ self.surface.as_vector(alpha)

    def coordinates(self, alpha) -> np.ndarray:
        """Node coordinates (n_nodes, 3) of Ω(α); raises MeshError if an element would invert or
        fall below the Jacobian-ratio threshold (checked before any assembly)."""
        alpha = checked_design(self, alpha)
        x = self.reference.points.copy()
        moved(x, self, alpha)
        return x

    def dx3_dalpha(self) -> np.ndarray:
        """∂x3/∂α for every node: (n_nodes, n_design) = β_k(x1, x2)·w. Constant in α. With a
        direction field d (normal motion) the amplitude of ∂x/∂α = β_k(ξ)·w·d along d."""
        out = np.zeros((self.n_nodes, self.surface.size))
        out[self.moving] = self._dx3
        return out

    def contract_dx3(self, d3: np.ndarray) -> np.ndarray:
        """Σ_n (∂x3_n/∂α) d3_n for a per-node array d3: the chain rule of the design derivatives."""
        return self._dx3.T @ d3[self.moving]

    def contract_dx(self, d: np.ndarray) -> np.ndarray:
        """Σ_n (∂x_n/∂α)·d_n for a per-node array d (n_nodes, 3): the chain rule of the design
        derivatives along the motion's directions (e3 on the paper's map)."""
        if self.directions is None:
            return self.contract_dx3(d[:, 2])
        m = self.moving
        return self._dx3.T @ np.einsum("ij,ij->i", d[m], self.directions[m])

    def ratio_gradient(self, G: np.ndarray) -> np.ndarray:
        """(E, Q, n) ∇N_a·d_a from the reference shape-function gradients G (E, Q, n, 3): what
        :class:`JacobianRatio` contracts with the lift amplitudes (∂N_a/∂x3 on the paper's map)."""
        if self.directions is None:
            return G[..., 2]
        return np.einsum("eqaj,eaj->eqa", G, self.directions[self.elements])

    def contact_points(self) -> np.ndarray:
        """Chart coordinates ξ of the contact nodes ((x1, x2) on the paper's plane), in contact-node
        order: the unrolled face of plots and maps."""
        return self.chart_points(self.reference.points[self.contact_nodes])

    def gap_matrix(self) -> np.ndarray:
        """G with gap g = G α: the initial gap of contact node i is ϑ_α(x'_i) (foundation x3 ≤ 0)."""
        xy = self.contact_points()
        return self.surface.basis_matrix(xy[:, 0], xy[:, 1])


class SeveralMorphs:
    """The morph of several designed faces (:mod:`contactopt.design.several`): one displacement
    field of the body,

        x(α) = x_ref + Σ_d ϑ_d(ξ_d(x_ref))·w_d(x_ref)·d_d(x_ref),

    one :class:`MorphedMesh` per design d (its surface, harmonic weight w_d — 1 on its face, 0 on
    the other designed faces and the parts fixed in shape —, chart ξ_d and directions d_d), α the
    designs' control points concatenated. Still affine in α: ∂x/∂α of design d's block is
    design d's own, and the design derivatives contract each block with its own directions.

    A contact node lies on one designed face at most (the faces share no node,
    :func:`contactopt.mesh.body.build_body`): its gap takes the columns of that design alone."""

    def __init__(self, morphs, surface):
        self.morphs = tuple(morphs)
        self.surface = surface                       # design.several.DesignSurfaces
        first = self.morphs[0]
        self.reference, self.contact_nodes, self.fixed_shape = first.reference, first.contact_nodes, first.fixed_shape
        self.elements = first.elements
        self.chart = first.chart          # the first design's (each design's: ``morphs``)
        self.offsets = surface.offsets
        self.weights = np.array([m.weight for m in self.morphs])        # (D, n_nodes)
        # per node the design whose weight is largest there: its chart and direction at contact nodes
        self.owner = np.argmax(self.weights, axis=0)
        if all(m.directions is None for m in self.morphs):
            self.directions = None
        else:
            dirs = np.array([np.broadcast_to([0.0, 0.0, 1.0], (self.n_nodes, 3)) if m.directions is None
                             else m.directions for m in self.morphs])
            self.directions = dirs[self.owner, np.arange(self.n_nodes)]
        self.ratio = None          # JacobianRatio, attached by the model

    n_nodes = MorphedMesh.n_nodes
    n_elements = MorphedMesh.n_elements
    cell_type = MorphedMesh.cell_type
    parts = MorphedMesh.parts

    def _blocks(self, alpha):
        a = self.surface.as_vector(alpha)
        o = self.offsets
        return [a[o[d]:o[d + 1]] for d in range(len(self.morphs))]

    def coordinates(self, alpha) -> np.ndarray:
        """Node coordinates (n_nodes, 3) of Ω(α) (as :meth:`MorphedMesh.coordinates`)."""
        alpha = checked_design(self, alpha)
        x = self.reference.points.copy()
        for m, a in zip(self.morphs, self._blocks(alpha)):
            moved(x, m, a)
        return x

    def dx3_dalpha(self) -> list:
        """Per design the (n_nodes, its size) amplitudes of ∂x/∂α (:class:`JacobianRatio` takes the list)."""
        return [m.dx3_dalpha() for m in self.morphs]

    def contract_dx(self, d: np.ndarray) -> np.ndarray:
        """Σ_n (∂x_n/∂α)·d_n, each design's block along its own directions."""
        return np.concatenate([m.contract_dx(d) for m in self.morphs])

    def ratio_gradient(self, G: np.ndarray) -> list:
        """Per design the (E, Q, n) ∇N_a·d_a of its directions (:meth:`MorphedMesh.ratio_gradient`)."""
        return [m.ratio_gradient(G) for m in self.morphs]

    def chart_points(self, x) -> np.ndarray:
        """Chart coordinates of points x on the first design's chart (per design: ``morphs``)."""
        return self.morphs[0].chart_points(x)

    def contact_points(self) -> np.ndarray:
        """Chart coordinates of the contact nodes, each on the chart of the design that moves it
        (the first design's where none does)."""
        nodes = self.contact_nodes
        x = self.reference.points[nodes]
        out = self.morphs[0].chart_points(x).astype(float)
        for d, m in enumerate(self.morphs[1:], start=1):
            mine = (self.owner[nodes] == d) & (m.weight[nodes] > 0)
            if np.any(mine):
                out[mine] = m.chart_points(x[mine])
        return out

    def gap_matrix(self) -> np.ndarray:
        """G with g = G α at the contact nodes: per node the columns of the design whose face it lies
        on (w_d = 1 there, 0 on the other designed faces and on faces no design moves)."""
        return np.hstack([m.weight[self.contact_nodes][:, None] * m.gap_matrix() for m in self.morphs])


def checked_design(mesh, alpha) -> np.ndarray:
    """α of a morphed mesh as a vector, after the checks that come before any assembly: finite,
    and (where the mesh has one) the Jacobian-ratio threshold; MeshError otherwise."""
    alpha = mesh.surface.as_vector(alpha)
    if not np.all(np.isfinite(alpha)):
        raise MeshError("design produces non-finite surface heights")
    if mesh.ratio is not None:
        mesh.ratio.check(alpha)
    return alpha


def moved(x: np.ndarray, morph, alpha) -> None:
    """Move the nodes ``x`` by one morph's lift at α: along x3, or along its direction field."""
    if morph.directions is None:
        x[morph.moving, 2] += morph.lift(alpha)
    else:
        x[morph.moving] += morph.lift(alpha)[:, None] * morph.directions[morph.moving]


class JacobianRatio:
    """det J(α) / det J_ref = 1 + R α at every quadrature point (see the module docstring).

    ``grad3`` are ∂N_a/∂x3 on the reference elements (E, Q, n); ``dx3`` the (n_nodes, n_design)
    ∂x3/∂α. ``threshold`` is the smallest ratio accepted; ``fixed_nodes`` mark parts fixed in
    shape (named in the message when an element touching them inverts)."""

    def __init__(self, elements, grad3, dx3, threshold, *, qpoints=None, fixed_parts=None, chunk=20000):
        self.elements = elements
        self.threshold = float(threshold)
        if isinstance(grad3, list):        # several designs (SeveralMorphs): per design its grad3 and dx3
            parts = [JacobianRatio(elements, g, x, threshold, chunk=chunk) for g, x in zip(grad3, dx3)]
            self.shape = parts[0].shape
            self.R = np.hstack([p.R for p in parts])
            self.qpoints, self.fixed_parts = qpoints, fixed_parts or {}
            return
        E, Q, _ = grad3.shape
        self.shape = (E, Q)
        nd = dx3.shape[1]
        big = E * Q * nd > 5_000_000
        self.R = np.empty((E * Q, nd), np.float32 if big else np.float64)
        for i in range(0, E, chunk):
            j = min(E, i + chunk)
            # R[e, q] = Σ_a ∂N_a/∂x3 (e, q) · (∂x3/∂α)_a
            self.R[i * Q:j * Q] = np.einsum("eqa,ead->eqd", grad3[i:j], dx3[elements[i:j]]).reshape(-1, nd)
        self.qpoints = qpoints
        self.fixed_parts = fixed_parts or {}

    def ratios(self, alpha) -> np.ndarray:
        """(E, Q) det J(α)/det J_ref."""
        return (1.0 + self.R @ np.asarray(alpha, self.R.dtype)).reshape(self.shape)

    def check(self, alpha) -> None:
        r = self.ratios(alpha)
        if r.min() > self.threshold:
            return
        bad_e = np.unique(np.nonzero(r <= self.threshold)[0])
        e = int(bad_e[np.argmin(r[bad_e].min(axis=1))])
        where = ""
        if self.qpoints is not None:
            where = " at (" + ", ".join(f"{v:.4g}" for v in self.qpoints[e]) + ")"
        kind = "inverted (det J ≤ 0)" if r[e].min() <= 0 else "distorted"
        msg = (f"the design would leave {bad_e.size} element(s) {kind if bad_e.size == 1 else 'inverted or distorted'}: "
               f"Jacobian ratio to the reference mesh {r[e].min():.3g} ≤ {self.threshold:g} in element {e}{where}")
        touched = [name for name, nodes in self.fixed_parts.items()
                   if np.any(np.isin(self.elements[bad_e], nodes))]
        if touched:
            msg += ("; the contact surface reaches the " + ", ".join(touched)
                    + " face" + ("s" if len(touched) > 1 else "") + " (fixed in shape)")
        raise MeshError(msg)

    def worst_on_box(self, C0: float, lower: float = 0.0):
        """(smallest ratio, element, quadrature point, −Σ_k min(0, R_qk) there) over designs with
        lower ≤ α ≤ C0: a bound of the worst ratio on U (exact where R ≤ 0, as for the block,
        whose ratio 1 − ϑ_α/c only grows where ϑ_α < 0)."""
        neg = np.minimum(self.R, 0.0).sum(axis=1, dtype=np.float64)
        if lower == 0:
            q = int(np.argmin(neg))
            return 1.0 + C0 * float(neg[q]), q // self.shape[1], q % self.shape[1], float(-neg[q])
        worst = 1.0 + C0 * neg + lower * np.maximum(self.R, 0.0).sum(axis=1, dtype=np.float64)
        q = int(np.argmin(worst))
        return float(worst[q]), q // self.shape[1], q % self.shape[1], float(-neg[q])

    def worst_on_bounds(self, lower: np.ndarray, upper: np.ndarray):
        """(smallest ratio, element, safe scale) over designs with lower ≤ α ≤ upper per design
        variable (several designs, each its own box): 1 + Σ_k min(0, R_qk) upper_k + max(0, R_qk)
        lower_k, and the largest t for which the box [lower, t·upper] keeps every ratio above the
        threshold (≤ 0: none)."""
        neg = np.minimum(self.R, 0.0).astype(np.float64) @ np.asarray(upper, float)
        pos = np.maximum(self.R, 0.0).astype(np.float64) @ np.asarray(lower, float)
        worst = 1.0 + neg + pos
        q = int(np.argmin(worst))
        room = 1.0 - self.threshold + pos
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = float(np.min(np.where(neg < 0, room / -neg, np.inf))) if np.all(room > 0) else 0.0
        return float(worst[q]), q // self.shape[1], scale

    def safe_C0(self, lower: float = 0.0) -> float:
        """Largest C0 for which every design of the box [lower, C0] keeps the ratio above the
        threshold (−inf when ``lower`` alone takes some ratio down to it)."""
        if lower == 0:
            s = self.worst_on_box(1.0)[3]
            return np.inf if s <= 0 else (1.0 - self.threshold) / s
        neg = -np.minimum(self.R, 0.0).sum(axis=1, dtype=np.float64)
        room = 1.0 - self.threshold + lower * np.maximum(self.R, 0.0).sum(axis=1, dtype=np.float64)
        if np.any(room <= 0):
            return -np.inf
        with np.errstate(divide="ignore"):
            return float(np.min(np.where(neg > 0, room / neg, np.inf)))
