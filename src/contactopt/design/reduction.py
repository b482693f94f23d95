"""Symmetric and fixed control points by reducing the design variables: α = P β + α_fixed.

``[design] symmetry = ["x1"]`` mirrors the control net about the mid-line x1 = x1lo + a/2 of the
design rectangle (α[i, j] = α[d1 − i, j]), ``"x2"`` about x2 = x2lo + b/2 (α[i, j] = α[i, d2 − j]).
The columns of the 0/1 matrix P are the orbits of the mirror group on the control points (one 1
per row of P), so every α = P β is exactly symmetric, bit for bit. ``fixed`` control points (and
their whole orbit) drop out of β and keep their initial value in the constant α_fixed.

The optimizer works on β: U's rows become A P β ≤ b − A α_fixed (rows that vanish are dropped,
duplicates merged, rows on one variable turned into its bounds), the bounds of β are the
tightest of its orbit's, and the subgradient of Θ(P β + α_fixed) is Pᵀ ξ. The run's outputs stay
in α.

Symmetry is checked, not enforced, on the rest of the model (a warning naming what breaks it):
the contact face (every node mirrored lies on the face), the extent across the line of every
clamped part and loaded part, and the load components across the line (body force, tractions).
"""

from __future__ import annotations

import logging

import numpy as np

from ..errors import ConfigError

log = logging.getLogger(__name__)

AXES = {"x1": 0, "x2": 1}


class DesignReduction:
    """α = P β + α_fixed (see the module docstring); P is stored as the orbit of every control
    point (``orbit[k]`` the column of α_k, −1 for a fixed one)."""

    def __init__(self, d1: int, d2: int, alpha0, *, symmetry=(), fixed=(), where: str = "[design]"):
        n1, n2 = d1 + 1, d2 + 1
        n = n1 * n2
        idx = np.arange(n).reshape(n1, n2)
        parent = np.arange(n)

        def find(k):
            while parent[k] != k:
                k = parent[k]
            return k
        for ax in symmetry:
            mirror = idx[::-1, :] if ax == "x1" else idx[:, ::-1]
            for k, m in zip(idx.ravel(), mirror.ravel()):
                a, b = find(k), find(m)
                parent[max(a, b)] = min(a, b)
        roots = np.array([find(k) for k in range(n)])
        a0 = np.asarray(alpha0, float).reshape(-1)
        problems = []
        for r in np.unique(roots):
            members = np.flatnonzero(roots == r)
            vals = a0[members]
            if np.ptp(vals) > 1e-12 * max(1.0, np.abs(vals).max()):
                i, j = divmod(int(members[np.argmax(np.abs(vals - vals[0]))]), n2)
                problems.append(f"{where}: design.initial is not symmetric as design.symmetry = {list(symmetry)} "
                                f"asks: α[{i},{j}] = {a0[i * n2 + j]:.8g} ≠ α[{members[0] // n2},"
                                f"{members[0] % n2}] = {vals[0]:.8g}")
                break
        if problems:
            raise ConfigError(problems)
        is_fixed = np.zeros(n, bool)
        for i, j in fixed:
            is_fixed[roots == roots[i * n2 + j]] = True
        free_roots = np.unique(roots[~is_fixed])
        if not free_roots.size:
            raise ConfigError([f"{where}: design.fixed fixes every control point (with design.symmetry, "
                               "their mirror images): nothing is left to optimize"])
        col = {int(r): c for c, r in enumerate(free_roots)}
        self.orbit = np.array([-1 if is_fixed[k] else col[int(roots[k])] for k in range(n)])
        self.n_alpha, self.n_beta = n, free_roots.size
        self.offset = np.where(is_fixed, a0, 0.0)        # α_fixed
        self.free = np.flatnonzero(~is_fixed)
        self.P = np.zeros((n, self.n_beta))
        self.P[self.free, self.orbit[self.free]] = 1.0
        self.beta0 = self.restrict(a0)

    def expand(self, beta) -> np.ndarray:
        """α = P β + α_fixed (by copying: mirror images are the same float)."""
        out = self.offset.copy()
        out[self.free] = np.asarray(beta, float)[self.orbit[self.free]]
        return out

    def restrict(self, alpha) -> np.ndarray:
        """β of a design α = P β + α_fixed: the value at one control point of each orbit."""
        a = np.asarray(alpha, float).reshape(-1)
        beta = np.empty(self.n_beta)
        beta[self.orbit[self.free][::-1]] = a[self.free][::-1]     # the first member of each orbit
        return beta

    def pullback(self, xi) -> np.ndarray:
        """The subgradient in β of Θ(P β + α_fixed): Pᵀ ξ."""
        return self.P.T @ np.asarray(xi, float)

    def constraints(self, U, where: str = "[design]") -> dict:
        """U's rows in β (keyword arguments for minimize_bundle); ConfigError when they leave no
        admissible β (e.g. fixed points that the mean value cannot accommodate)."""
        P, c = self.P, self.offset
        lb = np.full(self.n_beta, -np.inf)
        ub = np.full(self.n_beta, np.inf)
        np.maximum.at(lb, self.orbit[self.free], U.lb[self.free])
        np.minimum.at(ub, self.orbit[self.free], U.ub[self.free])
        bad = []
        fixed = np.flatnonzero(self.orbit < 0)
        if np.any(c[fixed] < U.lb[fixed] - 1e-12) or np.any(c[fixed] > U.ub[fixed] + 1e-12):
            bad.append("a fixed control point lies outside its bounds")
        A, b = U.A_ub @ P, U.b_ub - U.A_ub @ c
        A, b = _merge_rows(A, b, lb, ub, bad, "≤")
        Ae, be = (U.A_eq @ P, U.b_eq - U.A_eq @ c) if U.A_eq.size else (np.zeros((0, self.n_beta)), np.zeros(0))
        Ae, be = _independent_rows(Ae, be, bad)
        if bad or not U.nonempty(A, b, Ae, be, lb, ub):
            what = "; ".join(bad) if bad else "the bounds, slopes, mean value and rows have no common point"
            raise ConfigError([f"{where}: design.fixed / design.symmetry leave no admissible design: {what}"])
        log.info("design reduced by symmetry / fixed control points: %d of %d variables, %d inequality "
                 "and %d equality rows", self.n_beta, self.n_alpha, A.shape[0], Ae.shape[0])
        return dict(lb=lb, ub=ub, A_ub=A, b_ub=b, A_eq=Ae if Ae.size else None, b_eq=be if Ae.size else None)


def _merge_rows(A, b, lb, ub, bad, op):
    """Drop vanishing rows (checking 0 ≤ b), turn rows on one variable into its bounds, merge
    duplicate rows keeping the tightest right-hand side."""
    tol = 1e-12
    nz = np.abs(A) > 0
    count = nz.sum(axis=1)
    for r in np.flatnonzero(count == 0):
        if b[r] < -tol * max(1.0, abs(b[r])):
            bad.append(f"a row reduces to 0 {op} {b[r]:.6g}")
    for r in np.flatnonzero(count == 1):
        k = int(np.flatnonzero(nz[r])[0])
        v = b[r] / A[r, k]
        if A[r, k] > 0:
            ub[k] = min(ub[k], v)
        else:
            lb[k] = max(lb[k], v)
    keep = np.flatnonzero(count > 1)
    A, b = A[keep], b[keep]
    if not A.shape[0]:
        return A, b
    _, first, inv = np.unique(A, axis=0, return_index=True, return_inverse=True)
    inv = np.asarray(inv).reshape(-1)
    rhs = np.full(first.size, np.inf)
    np.minimum.at(rhs, inv, b)
    order = np.argsort(first)          # the rows in their first order
    return A[first[order]], rhs[order]


def _independent_rows(A, b, bad):
    """Equality rows without vanishing or linearly dependent ones (a consistent set stays equal)."""
    if not A.shape[0]:
        return A, b
    keep = []
    for r in range(A.shape[0]):
        if not np.any(A[r]):
            if abs(b[r]) > 1e-10 * max(1.0, abs(b[r])):
                bad.append(f"an equality row reduces to 0 = {b[r]:.6g}")
            continue
        trial = keep + [r]
        if np.linalg.matrix_rank(A[trial]) == len(trial):
            keep = trial
    return A[keep], b[keep]


def symmetry_warnings(model, symmetry, loads=None) -> list[str]:
    """What is not symmetric about the mirror lines of ``symmetry`` (module docstring): a list of
    messages about the clamps and the loads, each logged as a warning (the state is solved on the
    whole body, so they act as they are). A contact face that is not symmetric is a ConfigError:
    the mirrored control points would then shape different parts of the face. ``loads``: the
    LoadSets to check (default the model's)."""
    body, sf = model.body, model.surface
    pts = body.reference.points
    face = body.contact_face
    out = []
    for name in symmetry:
        k = AXES[name]
        mid = (sf.x1lo + sf.a / 2) if k == 0 else (sf.x2lo + sf.b / 2)
        line = f"{name} = {mid:.6g}"
        # the contact face: every node mirrored lies on the face (within 5 % of an element)
        xy = pts[face.nodes, :2].copy()
        xy[:, k] = 2 * mid - xy[:, k]
        worst, at = _outside_face(pts[:, :2], face.faces, xy)
        if worst > 0.05:
            m = int(face.nodes[at])
            raise ConfigError(f"design.symmetry = '{name}': the contact face is not symmetric about {line}: "
                              f"node {m} at ({pts[m, 0]:.4g}, {pts[m, 1]:.4g}) has its mirror image off the "
                              f"face; drop '{name}' from design.symmetry or make the face symmetric")
        tol = 1e-6 * max(np.ptp(pts[:, 0]), np.ptp(pts[:, 1]), 1e-300)
        for part, _comps in body.clamped:
            lo, hi = pts[part.nodes, k].min(), pts[part.nodes, k].max()
            if abs((lo + hi) / 2 - mid) > tol + 1e-3 * (hi - lo):
                out.append(f"design.symmetry = '{name}': the clamped part '{part.name}' spans {name} in "
                           f"[{lo:.4g}, {hi:.4g}], not symmetric about {line}")
        for ls in ([model.loads] if loads is None else loads):
            if ls.body_force[k] != 0:
                out.append(f"design.symmetry = '{name}': only the loads break it: the body force has the "
                           f"component {ls.body_force[k]:.4g} across {line}")
            for kind, items in (("traction", ls.tractions), ("pressure", ls.pressures)):
                for pname, faces, t in items:
                    nodes = np.unique(faces)
                    lo, hi = pts[nodes, k].min(), pts[nodes, k].max()
                    if kind == "traction" and t[k] != 0:
                        out.append(f"design.symmetry = '{name}': only the loads break it: the traction on "
                                   f"'{pname}' has the component {t[k]:.4g} across {line}")
                    elif abs((lo + hi) / 2 - mid) > tol + 1e-3 * (hi - lo):
                        out.append(f"design.symmetry = '{name}': only the loads break it: the {kind} on "
                                   f"'{pname}' spans {name} in [{lo:.4g}, {hi:.4g}], not symmetric about {line}")
    for msg in out:
        log.warning(msg)
    return out


def _outside_face(xy_nodes, faces, q):
    """How far the points q lie outside the face (triangles / quadrilaterals of ``faces`` in the
    plane): the worst over q of −(the best least barycentric coordinate), ≤ 0 inside; and its
    index."""
    faces = np.asarray(faces)
    tris = faces[:, :3] if faces.shape[1] in (3, 6) else np.vstack([faces[:, [0, 1, 2]], faces[:, [0, 2, 3]]])
    T = xy_nodes[tris]                               # (F, 3, 2)
    v0, v1 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    det = v0[:, 0] * v1[:, 1] - v0[:, 1] * v1[:, 0]
    best = np.full(len(q), -np.inf)
    for s in range(0, len(q), 256):
        d = q[s:s + 256, None, :] - T[None, :, 0]      # (Q, F, 2)
        l1 = (d[..., 0] * v1[:, 1] - d[..., 1] * v1[:, 0]) / det
        l2 = (v0[:, 0] * d[..., 1] - v0[:, 1] * d[..., 0]) / det
        lmin = np.minimum(np.minimum(l1, l2), 1 - l1 - l2)
        best[s:s + 256] = lmin.max(axis=1)
    at = int(np.argmin(best))
    return float(-best[at]), at


def reduction_of(problem, alpha0):
    """The reduction of a shape problem's ``[design] symmetry`` / ``fixed``, or None without
    them (the paper's setting: the optimizer works on α itself). Its ``warnings`` list what is
    not symmetric (:func:`symmetry_warnings`)."""
    d = problem.config.design
    symmetry, fixed = d.symmetry, d.fixed
    more = [k for k, dk in enumerate(problem.config.designs) if dk.symmetry or dk.fixed]
    if len(problem.config.designs) > 1 and more:
        raise ConfigError([f"{problem.config.source}: designs[{more[0]}]: symmetry and fixed control points are "
                           "taken in a model of one design so far; with several [[designs]] drop them"])
    if not symmetry and not fixed:
        return None
    model = problem.model
    where = str(problem.config.source)
    red = DesignReduction(model.surface.d1, model.surface.d2, alpha0, symmetry=symmetry,
                          fixed=[tuple(p) for p in fixed], where=where)
    red.bounds = red.constraints(model.admissible, where)
    red.warnings = symmetry_warnings(model, symmetry, [model.loads if c.loads is None else c.loads
                                                                for c in problem.cases]) if symmetry else []
    return red
