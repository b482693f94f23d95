"""Rigid-body motions a body's clamps leave free (a body held only by contact).

The six rigid motions of the points x are the translations e_k and the rotations e_k × (x − x̄)
about the axes through the centroid x̄ of the reference mesh, k = 1, 2, 3 (coefficients c ∈ R⁶,
translations first). The clamps fix the components ``fixed`` (n, 3); the motions they leave free
are the coefficients C (6 × k) with (Σ c_j mode_j)(x_n)_m = 0 on every clamped component (n, m).
Where a canonical motion is free it is a column of C as it is, so that messages name "the
translation along x1"; the other columns are orthonormal and named by the axis they turn about.

Geometry only: the stiffness's kernel, its use in the state and the adjoint are in
:mod:`contactopt.paths.condensation` (docs/obstacles.md, "Bodies held only by contact").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

AXES = ("x1", "x2", "x3")


@dataclass
class RigidModes:
    """The free rigid motions of a body: ``coefficients`` C (6 × k), ``centroid`` x̄ (3,)."""

    coefficients: np.ndarray
    centroid: np.ndarray

    @property
    def count(self) -> int:
        return self.coefficients.shape[1]

    def vectors(self, points: np.ndarray) -> np.ndarray:
        """(n, 3, k): the free motions at the points (the current coordinates of a design)."""
        return motions(points, self.centroid) @ self.coefficients

    def names(self) -> list:
        return [mode_name(c, self.centroid) for c in self.coefficients.T]


def motions(points: np.ndarray, centroid: np.ndarray) -> np.ndarray:
    """(n, 3, 6): the translations e_k and rotations e_k × (x − x̄) at the points."""
    x = np.asarray(points, float) - centroid
    out = np.zeros((x.shape[0], 3, 6))
    out[:, :, :3] = np.eye(3)
    for k in range(3):
        out[:, :, 3 + k] = np.cross(np.eye(3)[k], x)
    return out


def free_modes(points: np.ndarray, fixed: np.ndarray, rtol: float = 1e-9) -> RigidModes:
    """The rigid motions that the clamped components ``fixed`` (n, 3) leave free (module docstring)."""
    points = np.asarray(points, float)
    centroid = points.mean(axis=0)
    nodes, comps = np.nonzero(fixed)
    M = motions(points[nodes], centroid)[np.arange(nodes.size), comps] if nodes.size else np.zeros((0, 6))
    scale = np.ones(6)
    scale[3:] = max(np.ptp(points, axis=0).max(), 1e-300)      # rotations in units of length
    Ms = M * scale
    if Ms.shape[0]:
        # Vt is all we need: the thin SVD where the clamps give six rows or more (the full one
        # forms U of rows × rows, 7 GB for the 30k clamped components of a hub 64 × 128)
        _, sv, Vt = np.linalg.svd(Ms, full_matrices=Ms.shape[0] < 6)
        rank = int(np.sum(sv > rtol * max(sv.max(initial=0.0), 1e-300)))
    else:
        Vt, rank = np.eye(6), 0
    null = Vt[rank:].T * scale[:, None]                           # back to unit coefficients
    if null.shape[1] == 0:
        return RigidModes(np.zeros((6, 0)), centroid)
    cols = []
    # named motions first: the translations e_k, then the rotations about an axis along e_k (through
    # whatever point the clamps leave), each where the free motions hold one independent of the others
    for k in range(6):
        if k < 3:
            c = np.eye(6)[k]
            ok = np.linalg.norm(null @ np.linalg.lstsq(null, c, rcond=None)[0] - c) <= 1e-9
        else:
            y = np.linalg.lstsq(null[3:], np.eye(3)[k - 3], rcond=None)[0]
            c = null @ y
            ok = np.linalg.norm(c[3:] - np.eye(3)[k - 3]) <= 1e-9
        if ok and np.linalg.matrix_rank(np.array(cols + [c]) * np.r_[np.ones(3), scale[3:]], tol=1e-9) == len(cols) + 1:
            cols.append(np.where(np.abs(c) <= 1e-12 * np.abs(c).max(), 0.0, c))
    if len(cols) < null.shape[1]:       # complete by orthonormal others
        E = np.array(cols).T.reshape(6, -1)
        P = null - E @ np.linalg.lstsq(E, null, rcond=None)[0] if E.size else null
        U, s, _ = np.linalg.svd(P, full_matrices=False)
        cols += list(U[:, :null.shape[1] - len(cols)].T)
    return RigidModes(np.array(cols).T, centroid)


def mode_name(c: np.ndarray, centroid: np.ndarray) -> str:
    """'the translation along x1', 'the rotation about x3', or for another motion
    'the rotation about the axis (…) through (…)' / 'the translation along (…)'."""
    c = np.asarray(c, float)
    lead = c[3:] if np.linalg.norm(c[3:]) > 1e-12 * max(np.linalg.norm(c[:3]), 1e-300) else c[:3]
    if lead[np.argmax(np.abs(lead))] < 0:          # a motion and its opposite are one name
        c = -c
    t, w = c[:3], c[3:]
    if np.linalg.norm(w) <= 1e-12 * max(np.linalg.norm(t), 1e-300):
        return f"the translation along {_direction(t)}"
    p = centroid + np.cross(w, t) / (w @ w)         # a point of the axis: t = −w × (p − x̄)
    along = (t @ w) / (w @ w)                       # a screw's translation along its axis
    name = f"the rotation about {_direction(w)}"
    if np.linalg.norm(p - centroid) > 1e-9 * max(np.abs(centroid).max(), 1.0):
        name += f" through {_fmt(p)}"
    else:
        name += " through the centroid " + _fmt(centroid)
    if abs(along) > 1e-9:
        name += f" (with a translation {along:.3g} per radian along it)"
    return name


def _direction(v: np.ndarray) -> str:
    v = np.asarray(v, float) / np.linalg.norm(v)
    k = int(np.argmax(np.abs(v)))
    if abs(abs(v[k]) - 1.0) <= 1e-12:
        return ("−" if v[k] < 0 else "") + AXES[k]
    return "the axis " + _fmt(v)


def _fmt(x) -> str:
    x = np.asarray(x, float)
    x = np.where(np.abs(x) <= 1e-12 * max(np.abs(x).max(), 1.0), 0.0, x)
    return "(" + ", ".join(f"{v:.4g}" for v in x) + ")"
