"""The common segmentation of two faces in contact: clipped face pairs, triangulated, with a rule.

Mortar coupling integrates over the body's contact face against its counterpart's face
(:mod:`contactopt.fem.mortar`). Both faces are projected on a common plane — for the elastic
foundation its top face x3 = 0, the body's face projected along x3 — and each pair of projected
faces that overlap is clipped (Sutherland–Hodgman: a convex polygon cut by the half-planes of
another convex polygon). The pieces are convex polygons, split into triangles from their
centroid; on each triangle a rule of the reference triangle integrates functions of both faces,
whose reference coordinates at the rule's points are found by inverting each face's map.

Faces are segmented by their corner polygons (straight sides in the plane: the projections of
linear faces, and of quadratic faces whose mid-side nodes lie at the mid-points of the
projected sides). Polygons are oriented counter-clockwise in the plane's coordinates (y1, y2);
a face given clockwise is reversed for clipping only, its node order untouched.

Geometry only: nothing here imports ``fem/``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NEWTON_STEPS = 30      # inverse of the bilinear map of a quadrilateral face
_QSIGN = np.array([(-1, -1), (1, -1), (1, 1), (-1, 1)], float)


def signed_area(poly: np.ndarray) -> float:
    """The signed area of a polygon (k, 2) (shoelace formula): > 0 counter-clockwise."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def clip_convex(subject: np.ndarray, clip: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """The intersection of the convex polygon ``subject`` (k, 2) with the convex polygon ``clip``
    (m, 2), both counter-clockwise (Sutherland–Hodgman): a counter-clockwise polygon (j, 2), empty
    (0, 2) when they do not overlap. A point within ``tol`` of a clipping line counts as inside."""
    out = np.asarray(subject, float)
    m = clip.shape[0]
    for i in range(m):
        if out.shape[0] == 0:
            break
        a, b = clip[i], clip[(i + 1) % m]
        e = b - a
        d = e[0] * (out[:, 1] - a[1]) - e[1] * (out[:, 0] - a[0])          # > 0: left of a→b, inside
        d = d / max(np.hypot(e[0], e[1]), 1e-300)
        inside = d >= -tol
        if inside.all():
            continue
        pts = []
        k = out.shape[0]
        for j in range(k):
            jn = (j + 1) % k
            if inside[j]:
                pts.append(out[j])
            if inside[j] != inside[jn]:
                t = d[j] / (d[j] - d[jn])
                pts.append(out[j] + t * (out[jn] - out[j]))
        out = np.array(pts) if pts else np.zeros((0, 2))
    return out


def triangulate(poly: np.ndarray) -> np.ndarray:
    """Triangles (k, 3, 2) of a convex polygon (k, 2) from its centroid (a fan; k ≥ 3)."""
    c = poly.mean(axis=0)
    nxt = np.roll(poly, -1, axis=0)
    return np.stack([np.broadcast_to(c, poly.shape), poly, nxt], axis=1)


@dataclass(frozen=True)
class Segmentation:
    """The common segmentation of two faces: triangle t lies in body face ``slave[t]`` and in
    counterpart face ``master[t]``, with corners ``triangles[t]`` (3, 2) in the common plane
    (counter-clockwise). ``slave_area`` (F_s,) is the area of each body face in the plane and
    ``covered`` (F_s,) the part of it the counterpart's faces cover."""

    slave: np.ndarray
    master: np.ndarray
    triangles: np.ndarray
    slave_area: np.ndarray
    covered: np.ndarray

    @property
    def n_cells(self) -> int:
        return int(self.slave.size)

    def quadrature(self, rule):
        """Points (T, Q, 2) in the plane and weights (T, Q) (area measure) of the rule
        ``rule = (q (Q, 2), w (Q,))`` of the reference triangle (area 1/2) on every triangle."""
        q, w = rule
        A, B, C = self.triangles[:, 0], self.triangles[:, 1], self.triangles[:, 2]
        x = A[:, None] + q[None, :, :1] * (B - A)[:, None] + q[None, :, 1:] * (C - A)[:, None]
        det = (B - A)[:, 0] * (C - A)[:, 1] - (B - A)[:, 1] * (C - A)[:, 0]
        return x, np.abs(det)[:, None] * w[None]


def segment(slave: np.ndarray, master: np.ndarray, rel_tol: float = 1e-12) -> Segmentation:
    """The common segmentation of the body's faces ``slave`` (F_s, n_s, 2) and the counterpart's
    ``master`` (F_m, n_m, 2), their corner polygons in the common plane (any orientation). Pieces
    thinner than ``rel_tol`` times a face's size (shared edges, touching corners) are dropped."""
    slave = _ccw(np.asarray(slave, float))
    master = _ccw(np.asarray(master, float))
    s_lo, s_hi = slave.min(axis=1), slave.max(axis=1)
    m_lo, m_hi = master.min(axis=1), master.max(axis=1)
    size = float(np.median(np.max(s_hi - s_lo, axis=1))) if slave.size else 1.0
    tol = rel_tol * size
    areas = np.array([signed_area(p) for p in slave])
    tri, si, mi = [], [], []
    covered = np.zeros(slave.shape[0])
    for f in range(slave.shape[0]):
        cand = np.flatnonzero(np.all((m_lo < s_hi[f] - tol) & (m_hi > s_lo[f] + tol), axis=1))
        for g in cand:
            piece = clip_convex(slave[f], master[g], tol)
            if piece.shape[0] < 3:
                continue
            piece = _dedupe(piece, tol)
            if piece.shape[0] < 3:
                continue
            a = signed_area(piece)
            if a <= tol * size:
                continue
            covered[f] += a
            t = triangulate(piece)
            tri.append(t)
            si.append(np.full(t.shape[0], f))
            mi.append(np.full(t.shape[0], g))
    if tri:
        tri, si, mi = np.concatenate(tri), np.concatenate(si), np.concatenate(mi)
    else:
        tri, si, mi = np.zeros((0, 3, 2)), np.zeros(0, int), np.zeros(0, int)
    return Segmentation(si, mi, tri, areas, covered)


def reference_coordinates(corners: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Reference coordinates (n, 2) of the points x (n, 2) in the faces of corner polygons
    ``corners`` (n, k, 2) (the face holding each point, in the face's node order): the
    barycentric (η, ζ) of the triangle 0-1-2 (k = 3), or the inverse of the bilinear map of
    [−1, 1]² (k = 4, Newton's method from the centre)."""
    X = np.asarray(corners, float)
    if X.shape[1] == 3:
        J = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]], axis=2)              # (n, 2, 2)
        return np.linalg.solve(J, (x - X[:, 0])[..., None])[..., 0]
    xi = np.zeros((x.shape[0], 2))
    for _ in range(NEWTON_STEPS):
        lin = 1.0 + xi[:, None, :] * _QSIGN[None]
        N = lin[:, :, 0] * lin[:, :, 1] / 4.0
        dN = np.stack([_QSIGN[None, :, 0] * lin[:, :, 1], _QSIGN[None, :, 1] * lin[:, :, 0]], axis=2) / 4.0
        res = np.einsum("na,nai->ni", N, X) - x
        J = np.einsum("nai,naj->nij", X, dN)
        step = np.linalg.solve(J, res[..., None])[..., 0]
        xi -= step
        if np.abs(step).max() < 1e-14:
            break
    return xi


def is_affine(corners: np.ndarray, rel_tol: float = 1e-12) -> bool:
    """Whether every face of corner polygons (F, k, 2) has an affine map from its reference face:
    triangles always, quadrilaterals when they are parallelograms (then functions of the face are
    polynomials in the plane's coordinates, and a rule of the triangle integrates them exactly)."""
    X = np.asarray(corners, float)
    if X.shape[1] == 3:
        return True
    size = np.max(np.ptp(X, axis=1))
    return bool(np.abs(X[:, 0] + X[:, 2] - X[:, 1] - X[:, 3]).max() <= rel_tol * size)


def _ccw(polys: np.ndarray) -> np.ndarray:
    if polys.size == 0:
        return polys
    x, y = polys[:, :, 0], polys[:, :, 1]
    a = np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
    out = polys.copy()
    out[a < 0] = out[a < 0, ::-1]
    return out


def _dedupe(poly: np.ndarray, tol: float) -> np.ndarray:
    """Drop consecutive vertices closer than ``tol`` (from clipping along a shared edge)."""
    keep = np.linalg.norm(poly - np.roll(poly, 1, axis=0), axis=1) > tol
    return poly[keep] if keep.any() else poly[:1]
