"""Charts of a contact face: the coordinates ξ = (ξ1, ξ2) the design surface ϑ_α(ξ) lives on.

The paper's face is a piece of the plane x3 = 0 with the chart ξ = (x1, x2). A face of a real part
may be an inclined plane or a piece of a circular cylinder (a bore, a shaft, a roller). A chart
gives every point x of the body

- its chart coordinates ξ(x): on a plane through ``origin`` with unit outward normal n,
  ξ = ((x − origin)·e1, (x − origin)·e2), e1 the unit projection of the x1 axis on the plane (of
  the x2 axis where the plane is nearly normal to x1), e2 = (−n) × e1, so that the plane x3 = 0
  with the body above it has ξ = (x1, x2); on a cylinder of radius ρ around the line through
  ``origin`` along the unit ``axis`` a, ξ = (ρ·θ, (x − origin)·a), θ ∈ (−π, π) the angle about a
  from the mean radial direction of the face (ξ1 is the arc length on the fitted cylinder, so that
  slopes of ϑ_α are slopes on the face);
- the face's *outward* unit normal of the chart surface at x (plane: n; cylinder: ± the radial
  direction, + where the body lies inside the cylinder, a shaft; − where it lies outside, a bore);
- the names of its coordinates (:class:`ChartAxes`, ``chart.axes``), which the maps and plots of the
  face are labelled with (:func:`chart_axes`: (x1, x2) on the paper's map, where there is no chart).
  The configuration has no length unit, so a name carries none: ξ is in the mesh's units.

Sign convention of a design: ϑ_α > 0 moves the face *into* the body (along −n, the inward normal):
material is removed and the gap to the counterpart grows by (n_c·(−n)) ϑ_α, n_c the counterpart's
normal pointing to the body. On the plane x3 = 0 that is the paper's lift ϑ_α e3.

:func:`resolve_chart` fits the chart of ``[design] chart`` to a face (best-fit plane or best-fit
cylinder) and refuses a face that is neither, naming it. Geometry only: nothing here assembles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..errors import ConfigError
from ..mesh.reference import FACE_CORNERS


@dataclass(frozen=True)
class ChartAxes:
    """The names of a chart's coordinates (ξ1, ξ2): ``labels`` label the axes of a figure
    (matplotlib mathtext), ``names`` say the same in plain text (state.json, summary.json)."""

    labels: tuple[str, str]
    names: tuple[str, str]


# the paper's map ξ = (x1, x2) of a face on the plane x3 = 0 (no chart object)
PAPER_AXES = ChartAxes(("$x_1$", "$x_2$"), ("x1", "x2"))


def chart_axes(chart) -> ChartAxes:
    """The names of the coordinates of ``chart``; of the paper's (x1, x2) when ``chart`` is None."""
    return PAPER_AXES if chart is None else chart.axes


def chart_summary(chart) -> dict:
    """The chart of a face in a result file: {"description", "axes"} (the plain names of ξ1, ξ2)."""
    return {"description": "the paper's map xi = (x1, x2)" if chart is None else chart.describe(),
            "axes": list(chart_axes(chart).names)}


@dataclass(frozen=True)
class PlaneChart:
    """A plane through ``origin`` with the face's outward unit ``normal`` and in-plane axes e1, e2."""

    origin: np.ndarray
    normal: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    kind: str = "plane"

    def parameters(self, x) -> np.ndarray:
        """(k, 2) chart coordinates ξ of points x (k, 3)."""
        v = np.asarray(x, float) - self.origin
        return np.c_[v @ self.e1, v @ self.e2]

    def outward(self, x) -> np.ndarray:
        """(k, 3) the chart surface's outward unit normal at the points x."""
        return np.tile(self.normal, (np.asarray(x).shape[0], 1))

    def describe(self) -> str:
        return f"plane through {_fmt(self.origin)} with outward normal {_fmt(self.normal)}"

    @property
    def axes(self) -> ChartAxes:
        """ξk = (x − origin)·ek: ξk = ±xj − c where ek is the axis ±ej (the face on x3 = 0: ξ = (x1 − o1,
        x2 − o2)), else ξk along ek."""
        labels, names = [], []
        for k, e in enumerate((self.e1, self.e2), start=1):
            j = int(np.argmax(np.abs(e)))
            if abs(abs(e[j]) - 1.0) <= 1e-12:
                c = float(self.origin @ e)
                x = ("-" if e[j] < 0 else "") + f"x_{j + 1}"
                shift = "" if abs(c) <= 1e-12 * max(1.0, float(np.abs(self.origin).max())) else \
                    f" {'-' if c > 0 else '+'} {_num(abs(c))}"
                labels.append(f"$\\xi_{k} = {x}{shift}$")
                names.append(f"xi{k} = {x.replace('_', '')}{shift}")
            else:
                labels.append(f"$\\xi_{k}$ along {_vec(e, 4)}")
                names.append(f"xi{k} = (x - o).e{k}: along e{k} = {_vec(e)} from o = {_vec(self.origin)}")
        return ChartAxes(tuple(labels), tuple(names))


@dataclass(frozen=True)
class CylinderChart:
    """A circular cylinder of ``radius`` around the line through ``origin`` along the unit ``axis``;
    ``ref`` the radial direction of θ = 0, ``sign`` +1 when the body lies inside (outward normal
    along the radius), −1 when outside."""

    origin: np.ndarray
    axis: np.ndarray
    radius: float
    ref: np.ndarray
    sign: float
    kind: str = "cylinder"

    def _radial(self, x):
        v = np.asarray(x, float) - self.origin
        along = v @ self.axis
        return v - along[:, None] * self.axis, along

    def parameters(self, x) -> np.ndarray:
        w, along = self._radial(x)
        theta = np.arctan2(w @ np.cross(self.axis, self.ref), w @ self.ref)
        return np.c_[self.radius * theta, along]

    def outward(self, x) -> np.ndarray:
        w, _ = self._radial(x)
        r = np.linalg.norm(w, axis=1)
        if np.any(r <= 1e-12 * self.radius):
            raise ConfigError([f"design.chart: a node of the body lies on the axis of the {self.describe()}, "
                               "where its radial direction is undefined"])
        return self.sign * w / r[:, None]

    def describe(self) -> str:
        return (f"cylinder of radius {self.radius:.6g} around the axis {_fmt(self.axis)} through "
                f"{_fmt(self.origin)}")

    @property
    def axes(self) -> ChartAxes:
        """ξ1 = ρθ, the arc length on the cylinder, ξ2 = (x − origin)·axis, the axial position."""
        return ChartAxes(
            (f"$\\xi_1 = \\rho\\theta$, arc length ($\\rho$ = {_num(self.radius)})",
             f"$\\xi_2$, axial position along {_vec(self.axis, 4)}"),
            (f"xi1 = rho*theta: arc length on the cylinder of radius rho = {self.radius:.6g}, theta the angle "
             f"about the axis from the direction {_vec(self.ref)}",
             f"xi2 = (x - o).a: axial position along a = {_vec(self.axis)} from o = {_vec(self.origin)}"))


def face_normals(points: np.ndarray, faces: np.ndarray, face_type: str) -> tuple[np.ndarray, np.ndarray]:
    """(unit outward normals (F, 3), centroids (F, 3)) of boundary faces (outward by their cell)."""
    nc = FACE_CORNERS[face_type]
    X = points[faces[:, :nc]]
    if nc == 4:
        n = np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 1])
    else:
        n = np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])
    return n / np.linalg.norm(n, axis=1)[:, None], X.mean(axis=1)


def nodal_normals(points: np.ndarray, faces: np.ndarray, face_type: str, nodes: np.ndarray) -> np.ndarray:
    """(k, 3) outward unit normals of the face at ``nodes``: the area-weighted mean of the normals of
    the faces around each node (exact on a plane; radial on a cylinder meshed evenly around it)."""
    nc = FACE_CORNERS[face_type]
    X = points[faces[:, :nc]]
    if nc == 4:
        n = 0.5 * np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 1])
    else:
        n = 0.5 * np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])
    acc = np.zeros((points.shape[0], 3))
    for k in range(faces.shape[1]):
        np.add.at(acc, faces[:, k], n)
    out = acc[nodes]
    return out / np.linalg.norm(out, axis=1)[:, None]


def _plane_axes(normal):
    inward = -normal
    ref = np.array([0.0, 1.0, 0.0]) if abs(normal[0]) > 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = ref - (ref @ normal) * normal
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(inward, e1)


def fit_plane(x: np.ndarray, n_faces: np.ndarray, origin=None, normal=None) -> tuple[PlaneChart, float]:
    """The best-fit plane of points x (least squares, through ``origin`` when given, normal to
    ``normal`` when given), its normal oriented along the mean outward face normal; returns
    (chart, largest distance of a point)."""
    c = x.mean(axis=0) if origin is None else np.asarray(origin, float)
    if normal is None:
        _, _, vt = np.linalg.svd(x - x.mean(axis=0), full_matrices=False)
        n = vt[-1]
    else:
        n = np.asarray(normal, float) / np.linalg.norm(normal)
    if n @ n_faces.mean(axis=0) < 0:
        n = -n
    e1, e2 = _plane_axes(n)
    return PlaneChart(c, n, e1, e2), float(np.abs((x - c) @ n).max())


def fit_cylinder(x: np.ndarray, n_faces: np.ndarray, axis=None, origin=None) -> tuple[CylinderChart | None, float]:
    """The best-fit circular cylinder of points x with outward face normals ``n_faces``: the axis is
    the direction the normals are orthogonal to (smallest singular vector of the normals) unless
    given, the circle of the points projected on the plane ⟂ axis a least-squares (Kåsa) fit, the
    axis point ``origin`` when given; returns (chart, largest |distance − radius|), (None, inf)
    when the points are collinear in projection."""
    if axis is None:
        _, _, vt = np.linalg.svd(n_faces, full_matrices=False)
        a = vt[-1]
        # a singular vector's sign is LAPACK's choice (it differs between BLAS kernels): fix it, so
        # that the chart's coordinates (and a design on them) are the same on every CPU
        a = a if a[np.argmax(np.abs(a))] > 0 else -a
    else:
        a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    u = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = u - (u @ a) * a
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    p = np.c_[x @ u, x @ v]
    if origin is None:
        M = np.c_[p, np.ones(p.shape[0])]
        sol, *_ = np.linalg.lstsq(M, -(p ** 2).sum(axis=1), rcond=None)
        centre = -0.5 * sol[:2]
        if not np.all(np.isfinite(centre)) or np.linalg.matrix_rank(M) < 3:
            return None, np.inf
        o = centre[0] * u + centre[1] * v + (x.mean(axis=0) @ a) * a
    else:
        o = np.asarray(origin, float)
    w = x - o
    w -= np.outer(w @ a, a)
    r = np.linalg.norm(w, axis=1)
    rho = float(r.mean())
    mean_dir = w.sum(axis=0)
    if not rho > 0 or np.linalg.norm(mean_dir) <= 1e-12 * rho * x.shape[0]:
        return None, np.inf
    ref = mean_dir / np.linalg.norm(mean_dir)
    return CylinderChart(o, a, rho, ref, 1.0), float(np.abs(r - rho).max())


def _orient_cylinder(chart: CylinderChart, centroids, n_faces) -> CylinderChart:
    """The cylinder chart with ``sign`` from the face: + when the outward normals point away from the axis."""
    radial = CylinderChart(chart.origin, chart.axis, chart.radius, chart.ref, 1.0).outward(centroids)
    s = 1.0 if np.sum(np.einsum("ij,ij->i", radial, n_faces)) >= 0 else -1.0
    return CylinderChart(chart.origin, chart.axis, chart.radius, chart.ref, s)


def resolve_chart(spec, points: np.ndarray, face, face_type: str, tol: float, source: str = ""):
    """The chart of ``[design]`` (``spec``: its ``chart``, ``axis``, ``origin``) on the contact face
    ``face`` (a :class:`~contactopt.mesh.reference.Part`), ``tol`` the absolute graph tolerance.

    ``chart = "auto"``: the best-fit plane when the face is planar, else the best-fit cylinder when the
    face is cylindrical, else the best-fit plane when the face is a graph over it; a face that is
    none of these is refused by name. Every chart is checked: the face's outward normals keep one
    side of the chart (they do not flip across the design rectangle), no two nodes of the face share
    chart coordinates, and a cylindrical face does not wrap around its axis."""
    pre = f"{source}: " if source else ""
    nodes = np.unique(face.faces[:, :FACE_CORNERS[face_type]]) if face.faces.size else face.nodes
    if face.faces.shape[0] == 0:
        raise ConfigError([f"{pre}body.contact = {face.name}: has no boundary faces (it must be a surface of "
                           "the body)"])
    x = points[nodes]
    nf, cf = face_normals(points, face.faces, face_type)
    axis = None if not spec.axis else np.asarray(spec.axis, float)
    origin = None if not spec.origin else np.asarray(spec.origin, float)
    kind = spec.chart
    if kind == "plane":
        chart, _ = fit_plane(x, nf, origin, axis)
    elif kind == "cylinder":
        chart, res = fit_cylinder(x, nf, axis, origin)
        # a cylinder given by its axis and a point on it is the chart of any face that is a graph
        # over it (a designed bore); a fitted one must fit
        if chart is None or (res > tol and (axis is None or origin is None)):
            raise ConfigError([f"{pre}design.chart = 'cylinder': the contact face {face.name} is not a circular "
                               "cylinder" + ("" if chart is None else
                                             f" (best fit: {chart.describe()}, a node {res:.3g} off it, tolerance "
                                             f"{tol:.3g})")])
        chart = _orient_cylinder(chart, cf, nf)
    else:
        plane, res_p = fit_plane(x, nf, origin)
        cyl, res_c = fit_cylinder(x, nf, axis, origin)
        if res_p <= tol:
            chart = plane
        elif cyl is not None and res_c <= tol:
            chart = _orient_cylinder(cyl, cf, nf)
        elif np.all(nf @ plane.normal > 0):
            chart = plane
        else:
            raise ConfigError([f"{pre}design.chart = 'auto': the contact face {face.name} is neither a plane nor a "
                               f"circular cylinder nor a graph over its best-fit plane (a node lies {res_p:.3g} off "
                               f"the best-fit plane, " + (f"{res_c:.3g} off the best-fit cylinder" if cyl is not None
                                                           else "no cylinder fits") +
                               f"; tolerance {tol:.3g}); set design.chart, axis and origin, or split the face"])
    _check_graph(chart, points, face, nodes, nf, cf, tol, pre)
    return chart


def _check_graph(chart, points, face, nodes, nf, cf, tol, pre) -> None:
    """The face's outward normals stay on the chart's outward side; chart coordinates are unique."""
    dots = np.einsum("ij,ij->i", nf, chart.outward(cf))
    flip = dots <= 0
    if np.any(flip):
        k = int(np.argmin(dots))
        raise ConfigError([f"{pre}design.chart: the normals of the contact face {face.name} flip across the "
                           f"design rectangle: {int(flip.sum())} of its {flip.size} faces turn away from the "
                           f"{chart.describe()} (first at {_fmt(cf[k])}, normal {_fmt(nf[k])}); the face must be a "
                           "graph over its chart"])
    xi = chart.parameters(points[nodes])
    if chart.kind == "cylinder":
        theta = xi[:, 0] / chart.radius
        if np.ptp(theta) >= 2 * np.pi - 1e-6 or np.abs(theta).max() > np.pi - 1e-9:
            raise ConfigError([f"{pre}design.chart: the contact face {face.name} wraps around the axis of the "
                               f"{chart.describe()}: model a sector of it (with symmetry planes)"])
    pairs = cKDTree(xi).query_pairs(tol, output_type="ndarray")
    if len(pairs):
        a, b = nodes[pairs[0, 0]], nodes[pairs[0, 1]]
        raise ConfigError([f"{pre}body.contact = {face.name}: is not a graph over its chart ({chart.describe()}): "
                           f"{len(pairs)} pair(s) of nodes share chart coordinates, first nodes {a} and {b} at "
                           f"{_fmt(points[a])} and {_fmt(points[b])}"])


def _num(v: float, digits: int = 4) -> str:
    return f"{float(v) + 0.0:.{digits}g}"         # + 0.0: no "-0"


def _fmt(x) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in np.asarray(x, float)) + ")"


def _vec(x, digits: int = 6) -> str:
    """A vector in an axis name: as :func:`_fmt`, its round-off (an entry below 1e-12 of the
    largest) and "-0" written 0."""
    x = np.asarray(x, float)
    x = np.where(np.abs(x) <= 1e-12 * np.abs(x).max(initial=0.0), 0.0, x)
    return "(" + ", ".join(_num(v, digits) for v in x) + ")"


def motion_directions(points: np.ndarray, face, face_type: str, chart=None) -> np.ndarray:
    """(n_nodes, 3) unit directions of ``motion = "normal"``: the chart surface's inward unit normal
    at every node (a plane's normal; on a cylinder the radial direction through the node, so that a
    node on a symmetry plane through the axis stays on it); without a chart (the face a graph over
    x3 = 0) the face's inward unit normal (−:func:`nodal_normals`) at its nodes, elsewhere that of
    the nearest node of the face."""
    if chart is not None:
        return -chart.outward(points)
    nodes = np.unique(face.faces)
    inward = -nodal_normals(points, face.faces, face_type, nodes)
    _, near = cKDTree(points[nodes]).query(points)
    return inward[near]
