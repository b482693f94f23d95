"""Rigid obstacles of any shape: the frame and the initial gap of each contact node.

``[obstacle]`` names a rigid counterpart: the plane x3 = 0 (the default), a sphere, a cylinder or
a closed triangulated surface (STL, or any surface meshio reads). Each contact node m gets a frame
from the obstacle at its closest point p_m in the reference configuration: the normal n_m points
from the obstacle to the body, t1_m is e1 projected on the tangent plane (e2 where n_m ∥ e1) and
t2_m = n_m × t1_m, so (t1, t2, n) is right-handed and the plane gives (e1, e2, e3) exactly. The
node's initial gap is its signed distance (x_m − p_m)·n_m, negative inside the obstacle.

Small deformations: the frames are fixed in the reference configuration. The design lifts the
face by ϑ_α e3, so the gap of a design is g_m = d_m + (n_m·e3) ϑ_α(x'_m), and a rigid translation
d of the obstacle (``control = "displacement"``) adds −d·n_m.

Geometry only: what is computed on it (the rotated condensed system) lives in ``fem`` and ``paths``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

log = logging.getLogger(__name__)

E3 = np.array([0.0, 0.0, 1.0])


@dataclass
class Frames:
    """Per node: ``normal`` (k, 3) from the obstacle to the node, ``distance`` (k,) the signed distance
    along it, ``closest`` (k, 3) the closest points; ``R`` (k, 3, 3) with columns (t1, t2, n)."""

    normal: np.ndarray
    distance: np.ndarray
    closest: np.ndarray

    @property
    def R(self) -> np.ndarray:
        return tangent_frames(self.normal)


def tangent_frames(n: np.ndarray) -> np.ndarray:
    """(k, 3, 3) rotations with columns (t1, t2, n): t1 the unit projection of e1 on the plane ⟂ n
    (of e2 where n is nearly parallel to e1), t2 = n × t1 (module docstring)."""
    n = np.asarray(n, float)
    ref = np.where((np.abs(n[:, 0]) > 0.9)[:, None], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0])
    t1 = ref - np.sum(ref * n, axis=1)[:, None] * n
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    t2 = np.cross(n, t1)
    return np.stack([t1, t2, n], axis=2)


class Obstacle:
    """A rigid obstacle (module docstring); ``frames(points)`` gives the :class:`Frames` of points."""

    shape = ""

    def frames(self, x: np.ndarray) -> Frames:
        raise NotImplementedError

    def signed_distance(self, x: np.ndarray) -> np.ndarray:
        return self.frames(x).distance


class Plane(Obstacle):
    shape = "plane"

    def frames(self, x):
        x = np.asarray(x, float)
        n = np.tile(E3, (x.shape[0], 1))
        closest = x.copy()
        closest[:, 2] = 0.0
        return Frames(n, x[:, 2].copy(), closest)


class Sphere(Obstacle):
    shape = "sphere"

    def __init__(self, center, radius):
        self.center, self.radius = np.asarray(center, float), float(radius)

    def frames(self, x):
        v = np.asarray(x, float) - self.center
        r = np.linalg.norm(v, axis=1)
        n = v / np.where(r > 0, r, 1.0)[:, None]
        n[r == 0] = E3
        return Frames(n, r - self.radius, self.center + self.radius * n)


class Cylinder(Obstacle):
    """The infinite circular cylinder of ``radius`` around the line through ``point`` along ``axis``."""

    shape = "cylinder"

    def __init__(self, point, axis, radius):
        a = np.asarray(axis, float)
        self.point, self.axis, self.radius = np.asarray(point, float), a / np.linalg.norm(a), float(radius)

    def frames(self, x):
        v = np.asarray(x, float) - self.point
        along = v @ self.axis
        w = v - along[:, None] * self.axis
        r = np.linalg.norm(w, axis=1)
        n = w / np.where(r > 0, r, 1.0)[:, None]
        n[r == 0] = E3
        return Frames(n, r - self.radius, self.point + along[:, None] * self.axis + self.radius * n)


class Surface(Obstacle):
    """A closed, consistently oriented triangle mesh (the obstacle is the solid it bounds).

    ``frames`` finds the closest point over every triangle (exact point–triangle distance); the
    sign of the distance is the generalized winding number's (inside where it is 1)."""

    shape = "surface"

    def __init__(self, points, triangles, source="surface"):
        self.points, self.tri, self.source = np.asarray(points, float), np.asarray(triangles, np.int64), source
        P = self.points[self.tri]
        self.normals = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
        self.normals /= np.linalg.norm(self.normals, axis=1)[:, None]
        if self._volume() < 0:           # oriented inward: turn it out
            self.tri = self.tri[:, ::-1].copy()
            self.normals = -self.normals

    def _volume(self) -> float:
        P = self.points[self.tri]
        return float(np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum() / 6.0)

    def closest(self, x, chunk=2_000_000):
        """(closest point (k, 3), distance (k,), triangle (k,), second-best distance at a point farther
        than ``tol`` away is reported by :meth:`ambiguous`) over all triangles."""
        x = np.asarray(x, float)
        best_p = np.zeros_like(x)
        best_d = np.full(x.shape[0], np.inf)
        best_t = np.zeros(x.shape[0], np.int64)
        step = max(1, chunk // max(self.tri.shape[0], 1))
        for s in range(0, x.shape[0], step):
            q = x[s:s + step]
            p = closest_on_triangles(q, self.points[self.tri])          # (k, T, 3)
            d = np.linalg.norm(p - q[:, None], axis=2)
            t = np.argmin(d, axis=1)
            best_t[s:s + step] = t
            best_d[s:s + step] = d[np.arange(q.shape[0]), t]
            best_p[s:s + step] = p[np.arange(q.shape[0]), t]
        return best_p, best_d, best_t

    def ambiguous(self, x, tol, chunk=2_000_000):
        """Indices of the points whose closest point is not unique: another triangle's closest point
        lies farther than ``tol`` from the best one at the same distance, to 1e-10 of max(distance,
        tol) (a tie: on a finely faceted curved surface, neighbouring facets' closest points of a
        far node differ in distance by far more)."""
        x = np.asarray(x, float)
        out = []
        step = max(1, chunk // max(self.tri.shape[0], 1))
        for s in range(0, x.shape[0], step):
            q = x[s:s + step]
            p = closest_on_triangles(q, self.points[self.tri])
            d = np.linalg.norm(p - q[:, None], axis=2)
            t = np.argmin(d, axis=1)
            k = np.arange(q.shape[0])
            near = d <= d[k, t][:, None] + 1e-10 * np.maximum(d[k, t], tol)[:, None]
            apart = np.linalg.norm(p - p[k, t][:, None], axis=2) > tol
            out.extend((s + np.flatnonzero(np.any(near & apart, axis=1))).tolist())
        return np.asarray(out, np.int64)

    def winding(self, x, chunk=2_000_000) -> np.ndarray:
        """The generalized winding number of the surface at points ``x`` (1 inside, 0 outside)."""
        x = np.asarray(x, float)
        out = np.zeros(x.shape[0])
        step = max(1, chunk // max(self.tri.shape[0], 1))
        P = self.points[self.tri]
        for s in range(0, x.shape[0], step):
            a, b, c = (P[None, :, i] - x[s:s + step, None] for i in range(3))
            la, lb, lc = (np.linalg.norm(v, axis=2) for v in (a, b, c))
            num = np.einsum("ktj,ktj->kt", a, np.cross(b, c))
            den = (la * lb * lc + np.einsum("ktj,ktj->kt", a, b) * lc + np.einsum("ktj,ktj->kt", b, c) * la
                   + np.einsum("ktj,ktj->kt", c, a) * lb)
            out[s:s + step] = np.arctan2(num, den).sum(axis=1) / (2 * np.pi)
        return out

    def frames(self, x, tol=0.0):
        x = np.asarray(x, float)
        p, d, t = self.closest(x)
        inside = self.winding(x) > 0.5
        sign = np.where(inside, -1.0, 1.0)
        v = x - p
        far = d > max(tol, 1e-12 * np.abs(self.points).max())
        n = self.normals[t].copy()
        n[far] = sign[far, None] * v[far] / d[far, None]
        return Frames(n, sign * d, p)


def closest_on_triangles(x: np.ndarray, P: np.ndarray) -> np.ndarray:
    """The closest point of each triangle P (T, 3, 3) to each point x (k, 3): (k, T, 3) (Ericson,
    Real-Time Collision Detection §5.1.5, vectorised over the Voronoi regions of the triangle)."""
    a, b, c = P[None, :, 0], P[None, :, 1], P[None, :, 2]
    q = x[:, None]
    ab, ac, ap = b - a, c - a, q - a

    def dot(u, v):
        return np.einsum("...j,...j->...", u, v)
    d1, d2 = dot(ab, ap), dot(ac, ap)
    bp = q - b
    d3, d4 = dot(ab, bp), dot(ac, bp)
    cp = q - c
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = 1.0 / (va + vb + vc)
        v = vb * denom
        w = vc * denom
        out = a + ab * v[..., None] + ac * w[..., None]                          # inside the face
        # edges
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    e_bc = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
    e_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    e_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    out = np.where(e_bc[..., None], b + (c - b) * np.nan_to_num(t_bc)[..., None], out)
    out = np.where(e_ac[..., None], a + ac * np.nan_to_num(t_ac)[..., None], out)
    out = np.where(e_ab[..., None], a + ab * np.nan_to_num(t_ab)[..., None], out)
    # vertices
    out = np.where(((d6 >= 0) & (d5 <= d6))[..., None], c, out)
    out = np.where(((d3 >= 0) & (d4 <= d3))[..., None], b, out)
    out = np.where(((d1 <= 0) & (d2 <= 0))[..., None], a, out)
    return np.broadcast_to(out, (x.shape[0], P.shape[0], 3))


def read_surface(path: str, key: str = "obstacle.mesh") -> Surface:
    """A closed triangle surface from a file meshio reads (STL, OBJ, VTK, Gmsh …): coincident
    points are merged (STL repeats them per triangle). ConfigError when it has no triangles or is
    not closed (an edge not shared by exactly two triangles, or two triangles of opposite
    orientation on an edge), naming the first such edge."""
    import contextlib
    import io

    import meshio
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            m = meshio.read(path)
    except Exception as exc:       # meshio raises many types for unreadable files
        raise ConfigError([f"{key} = {path!r}: cannot be read as a surface mesh: {exc}"]) from None
    tris = [c.data for c in m.cells if c.type == "triangle"]
    if not tris:
        raise ConfigError([f"{key} = {path!r}: has no triangles (a closed triangulated surface is needed)"])
    tri = np.concatenate(tris).astype(np.int64)
    pts = np.asarray(m.points, float)
    scale = max(np.ptp(pts, axis=0).max(), 1e-300)
    _, first, inverse = np.unique(np.round(pts / (1e-9 * scale)).astype(np.int64), axis=0,
                                  return_index=True, return_inverse=True)
    tri = inverse.ravel()[tri]
    pts = pts[first]
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])]
    directed = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    und, count = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    bad = und[count != 2]
    if bad.size == 0:
        dir_u, dir_count = np.unique(directed, axis=0, return_counts=True)
        if np.any(dir_count != 1):
            bad = dir_u[dir_count != 1]
            raise ConfigError([f"{key} = {path!r}: is not consistently oriented: {bad.shape[0]} edge(s) are "
                               f"traversed twice in the same direction, first between {_fmt(pts[bad[0, 0]])} and "
                               f"{_fmt(pts[bad[0, 1]])}; the obstacle must be a closed, oriented surface"])
        return Surface(pts, tri, source=str(path))
    raise ConfigError([f"{key} = {path!r}: is not closed: {bad.shape[0]} edge(s) are not shared by exactly two "
                       f"triangles, first between {_fmt(pts[bad[0, 0]])} and {_fmt(pts[bad[0, 1]])}; the "
                       "obstacle must be a closed surface (the solid it bounds is the obstacle)"])


def make_obstacle(spec) -> Obstacle:
    """The obstacle of a validated ``[obstacle]`` section."""
    shape = spec.shape
    if shape == "plane":
        return Plane()
    if shape == "sphere":
        return Sphere(spec.center, spec.radius)
    if shape == "cylinder":
        return Cylinder(spec.point, spec.axis, spec.radius)
    return read_surface(spec.mesh)


def contact_frames(obstacle: Obstacle, points: np.ndarray, face_nodes: np.ndarray, tol: float,
                   source: str = "", interference: bool = False) -> Frames:
    """The frames of the contact face's nodes, after the checks of the reference configuration:
    no node of the body lies inside the obstacle deeper than ``tol`` (with ``interference`` the
    overlap is intended: a press or shrink fit, whose contact nodes start with a negative gap), and
    (surface) the closest point of each face node is unique. ConfigError naming the first
    offending nodes."""
    pre = f"{source}: " if source else ""
    problems = []
    d = obstacle.signed_distance(points)
    inside = np.flatnonzero(d < -tol)
    inside = inside[np.argsort(d[inside], kind="stable")]
    if inside.size and interference:
        log.info("obstacle: %d node(s) of the body overlap the %s (body.interference), deepest %.3g",
                 inside.size, obstacle.shape, -d[inside[0]])
    elif inside.size:
        problems.append(f"{pre}obstacle: {inside.size} node(s) of the body lie inside the {obstacle.shape} "
                        f"deeper than the tolerance {tol:.3g}, deepest first: "
                        + ", ".join(f"node {n} at {_fmt(points[n])} (depth {-d[n]:.3g})" for n in inside[:5])
                        + " (an intended overlap, a press or shrink fit: body.interference = true)")
    if isinstance(obstacle, Surface):
        amb = obstacle.ambiguous(points[face_nodes], tol)
        if amb.size:
            problems.append(f"{pre}obstacle.mesh: the closest point on the surface is not unique for {amb.size} "
                            "node(s) of the contact face, first: "
                            + ", ".join(f"node {face_nodes[i]} at {_fmt(points[face_nodes[i]])}" for i in amb[:5])
                            + " (their normal is undefined: refine the surface or move the body)")
    if problems:
        raise ConfigError(problems)
    fr = obstacle.frames(points[face_nodes], tol) if isinstance(obstacle, Surface) else \
        obstacle.frames(points[face_nodes])
    return fr


def _fmt(x) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in np.asarray(x)) + ")"
