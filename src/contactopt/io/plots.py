"""Figures of a state and of a run (PNG, matplotlib Agg; nothing is ever shown on screen).

Figures are built with the object API (``matplotlib.figure.Figure`` on an Agg canvas), never
through ``pyplot``: no global figure registry, nothing to leak, safe to call from worker threads.
Every file is written atomically (temporary file + rename, :mod:`contactopt.io.atomic`).

Contact-surface maps draw a per-contact-node field over the contact face. On the paper's block
(:class:`~contactopt.mesh.hexmesh.HexMesh`) the contact nodes form a grid: contact node
m = i−1 + nx·j (i = 1..nx along x1, j = 0..ny along x2), a per-contact-node array reshapes to
(ny+1, nx), and each node is drawn as its dual cell (the points closer to it than to any other
node) clipped to the rectangle [0,a]×[0,b], as in the paper's figures; the strip next to the
clamped edge x1 = 0 belongs to the clamped nodes and stays empty. On any other face (a disc, an
L, an unstructured mesh) the field is drawn on the face's triangulation (quadrilaterals split in
two; triangles touching a clamped node are left out): :func:`face_triangulation`.

A map of the face is drawn in its chart's coordinates ξ = (ξ1, ξ2) (:mod:`contactopt.design.chart`)
and its axes carry the chart's names (:func:`~contactopt.design.chart.chart_axes`): x1, x2 on the
paper's map; on a cylinder the arc length ρθ and the axial position; on a plane chart its in-plane
axes. The configuration has no length unit: the axes are in the mesh's units.

Sign conventions of the plotted fields (see :mod:`contactopt.contact.state`): λ_m = (S u_c − ℓ)_ν ≥ 0
is the normal contact force on the body; τ_m = −(S u_c − ℓ)_t with ‖τ_m‖ ≤ F λ_m; the gap is
g_m = ϑ_α(x'_m) ≥ 0 above the foundation x3 ≤ 0.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.tri import Triangulation

from ..contact.state import CLASS_NAMES
from ..design.chart import chart_axes
from ..design.several import split_design, surfaces_of
from ..fem.stress import quadrature_points, von_mises_points
from .atomic import atomic_output

log = logging.getLogger(__name__)

__all__ = ["contact_grid", "face_triangulation", "plot_contact_field", "plot_force_and_pressure", "plot_node_classes",
           "plot_stress_comparison", "plot_contact_response", "plot_peak_stress",
           "plot_surface", "plot_history", "CLASS_LABELS", "CLASS_COLORS"]

# display names (typographic minus) and colours of Table 4.1's classes, in CLASS_NAMES order
CLASS_LABELS = ("L", "M1", "M2", "M3+", "M3\u2212", "M4")
CLASS_COLORS = ("#d9d9d9", "#1f77b4", "#9ecae1", "#d62728", "#ff9896", "#ff7f0e")
CLASS_DESCRIPTIONS = ("no contact", "sliding, contact", "sliding, weak contact", "sticking",
                      "weak sticking", "weak sticking, weak contact")
DPI = 120


# zlib level of the PNG files: 1 encodes several times faster than the default 6, the pixels are
# the same and the files about a third larger
PNG_COMPRESSION = 1


def _new_figure(figsize, layout="constrained") -> Figure:
    """A figure on an Agg canvas. ``layout=None`` for figures placed by hand (the 3D plots: the
    constrained layout measures every tick label of a 3D axes twice more per figure)."""
    fig = Figure(figsize=figsize, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, path) -> Path:
    path = Path(path)
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format="png", dpi=DPI, pil_kwargs={"compress_level": PNG_COMPRESSION})
    log.info("wrote %s", path)
    return path


def _bars(ax, x0, y0, dx, dy, dz, colors) -> None:
    """3D bars from (x0, y0, 0) to (x0 + dx, y0 + dy, dz), shaded like ``Axes3D.bar3d``, drawn with
    the faces that the view of :func:`plot_stress_comparison` (azimuth −60°, from above) can see:
    the top, the face at x1 = x0 + dx and the face at x2 = y0 (half of bar3d's six faces; a bar
    of height 0 its top only). The colours are one RGBA row per bar."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection
    x1, y1, z0 = x0 + dx, y0 + dy, np.zeros_like(dz)
    top = np.stack([np.stack(c, axis=-1) for c in ((x0, y0, dz), (x1, y0, dz), (x1, y1, dz), (x0, y1, dz))], axis=1)
    east = np.stack([np.stack(c, axis=-1) for c in ((x1, y0, z0), (x1, y1, z0), (x1, y1, dz), (x1, y0, dz))], axis=1)
    south = np.stack([np.stack(c, axis=-1) for c in ((x0, y0, z0), (x1, y0, z0), (x1, y0, dz), (x0, y0, dz))], axis=1)
    polys = np.stack([top, east, south], axis=1)
    facecolors = np.repeat(np.asarray(colors, float)[:, None, :], 3, axis=1)
    # a bar of height 0 (a node out of contact) has side faces of no area: its top alone is drawn
    keep = np.ones(polys.shape[:2], bool)
    keep[:, 1:] = (dz != 0)[:, None]
    polys, facecolors = polys[keep], facecolors[keep]
    ax.add_collection(Poly3DCollection(polys, facecolors=facecolors, shade=True, linewidth=0.0))


def contact_grid(model, values=None):
    """Node coordinates X1, X2 of the contact grid, each (ny+1, nx), and ``values`` reshaped alike.

    Raises ``ValueError`` if ``values`` is not one number per contact node, or if the contact nodes
    of the mesh are not the structured grid this module assumes.
    """
    mesh = model.mesh
    nx, ny = mesh.nx, mesh.ny
    pts = np.asarray(mesh.contact_points(), float)
    if pts.shape != ((ny + 1) * nx, 2):
        raise ValueError(f"expected {(ny + 1) * nx} contact nodes on an {nx}×{ny + 1} grid, got {pts.shape[0]}")
    X1 = pts[:, 0].reshape(ny + 1, nx)
    X2 = pts[:, 1].reshape(ny + 1, nx)
    if not (np.allclose(X1, X1[:1]) and np.allclose(X2, X2[:, :1])):
        raise ValueError("contact nodes are not ordered i fastest, then j")
    if values is None:
        return X1, X2, None
    v = np.asarray(values)
    if v.shape != (pts.shape[0],):
        raise ValueError(f"expected one value per contact node ({pts.shape[0]},), got shape {v.shape}")
    return X1, X2, v.reshape(ny + 1, nx)



def _categories(ax, model, codes, cmap, norm) -> None:
    """A per-node category (node class, stick/slip) on the contact face: cells on a grid face,
    coloured nodes on the triangulation of any other face."""
    codes = _face_rows(model, codes)
    if _has_grid(model):
        _pcolor(ax, model, contact_grid(model, codes)[2], cmap=cmap, norm=norm, edgecolors="white", linewidth=0.3)
    else:
        tri = face_triangulation(model)
        ax.triplot(tri, color="0.8", linewidth=0.4)
        ax.scatter(tri.x, tri.y, c=codes, cmap=cmap, norm=norm, s=14, edgecolors="0.3", linewidths=0.3)

def _has_grid(model) -> bool:
    if not hasattr(model.mesh, "nx"):
        return False
    try:
        contact_grid(model)
    except ValueError:
        return False
    return True


def face_triangulation(model):
    """The contact face as a ``matplotlib.tri.Triangulation`` over the contact nodes.

    Vertices are the contact nodes in contact-node order at their (x1, x2); the triangles are the
    face's triangles (a quadrilateral split in two, a six-node triangle by its corners) whose
    vertices are all contact nodes.
    """
    faces = np.asarray(model.body.contact_face.faces)
    corners = faces[:, :4] if faces.shape[1] == 4 else faces[:, :3]
    tris = np.vstack([corners[:, [0, 1, 2]], corners[:, [0, 2, 3]]]) if corners.shape[1] == 4 else corners
    index = np.full(model.mesh.n_nodes, -1)
    index[model.contact_nodes] = np.arange(model.contact_nodes.size)
    tris = index[tris]
    tris = tris[np.all(tris >= 0, axis=1)]
    xy = np.asarray(model.mesh.contact_points(), float)
    return Triangulation(xy[:, 0], xy[:, 1], tris)


def _contact_values(model, values, what="values"):
    v = np.asarray(values)
    if v.shape != (model.n_contact,):
        raise ValueError(f"expected one value per contact node ({model.n_contact},), got shape {v.shape}")
    return v


def _dual_edges(nodes: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Cell edges around sorted node positions: midpoints inside, half a spacing outside, clipped."""
    if nodes.size == 1:
        return np.array([lo, hi])
    mid = 0.5 * (nodes[1:] + nodes[:-1])
    first = nodes[0] - 0.5 * (nodes[1] - nodes[0])
    last = nodes[-1] + 0.5 * (nodes[-1] - nodes[-2])
    return np.clip(np.concatenate([[first], mid, [last]]), lo, hi)


def _rectangle(model):
    """(x1lo, x1hi, x2lo, x2hi) of the design rectangle; several designs: the bounding rectangle of
    the contact nodes' chart coordinates (each node on its design's chart)."""
    s = model.face_surface
    if len(surfaces_of(s)) > 1:
        xy = np.asarray(model.mesh.contact_points(), float)
        return float(xy[:, 0].min()), float(xy[:, 0].max()), float(xy[:, 1].min()), float(xy[:, 1].max())
    return s.x1lo, s.x1lo + s.a, s.x2lo, s.x2lo + s.b


def _unit(model, label: str) -> str:
    """``label`` of a length with the configuration's ``length_unit``, "label [mm]"; as it is without one."""
    unit = getattr(model.config, "length_unit", "")
    return f"{label} [{unit}]" if unit else label


def _axis_labels(model) -> tuple[str, str]:
    """The labels of the chart coordinates ξ1, ξ2 of the face (x1, x2 on the paper's map), with the
    length unit where the configuration names one."""
    return tuple(_unit(model, label) for label in chart_axes(model.mesh.chart).labels)


def _lift_label(model, mesh=None) -> str:
    """The label of ϑ_α in a plot of the surface: x3 on the paper's map (the face lies at x3 = ϑ_α),
    else ϑ_α along the direction the design moves the face (``[design] motion``)."""
    mesh = model.mesh if mesh is None else mesh
    if mesh.directions is not None:
        return _unit(model, "$\\vartheta_\\alpha$ along the inward normal")
    return _unit(model, "$x_3$" if mesh.chart is None else "$\\vartheta_\\alpha$ along $x_3$")


def _label_pad(axis, pad: float = 4.0, chars: int = 5) -> float:
    """The label pad of a 3D plot's axis that keeps its label clear of its tick labels: the default
    ``pad`` (points) for tick labels of up to ``chars`` characters ("0.025"), 5 points more for every
    further one ("−0.0001")."""
    labels = axis.get_major_formatter().format_ticks(axis.get_majorticklocs())
    return pad + 5.0 * max(0, max((len(t) for t in labels), default=0) - chars)


def _map_axes(fig, model, pos=None):
    x1lo, x1hi, x2lo, x2hi = _rectangle(model)
    ax = fig.add_subplot() if pos is None else fig.add_subplot(*pos)
    ax.set_xlim(x1lo, x1hi)
    ax.set_ylim(x2lo, x2hi)
    ax.set_aspect("equal")
    xlabel, ylabel = _axis_labels(model)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    return ax


def _pcolor(ax, model, grid, **kw):
    X1, X2, _ = contact_grid(model)
    e1 = _dual_edges(X1[0], 0.0, model.face_surface.a)
    e2 = _dual_edges(X2[:, 0], 0.0, model.face_surface.b)
    return ax.pcolormesh(e1, e2, grid, shading="flat", **kw)


def _figsize_map(model, extra_width=1.6):
    x1lo, x1hi, x2lo, x2hi = _rectangle(model)
    ratio = (x2hi - x2lo) / (x1hi - x1lo)
    w = 6.0
    return (w + extra_width, max(2.6, w * ratio + 1.1))


def _face_rows(model, values):
    """The values of the face body's contact nodes: a map of the face body's face leaves out the
    rows of faces on other bodies (fem.faces), which follow them."""
    return np.asarray(values)[:model.contact_nodes.size]


def _field(ax, model, values, **kw):
    """Draw a per-contact-node field: dual cells on the block's grid, else the face triangulation."""
    values = _face_rows(model, values)
    if _has_grid(model):
        return _pcolor(ax, model, contact_grid(model, values)[2], **kw)
    return ax.tripcolor(face_triangulation(model), np.asarray(values, float), shading="gouraud", **kw)


def plot_contact_field(path, model, values, title, cmap="viridis", label=None, *,
                       vmin=None, vmax=None) -> Path:
    """Map of a per-contact-node field over the contact surface [0,a]×[0,b] (one cell per node).

    ``values``: (p,) in contact-node order (e.g. λ, ‖τ‖, the gap). ``label`` names the colour bar.
    Non-finite values are refused (``ValueError``). Returns the path of the PNG.
    """
    grid = np.asarray(_contact_values(model, values), float)
    if not np.all(np.isfinite(grid)):
        raise ValueError(f"plot_contact_field({title!r}): the field has non-finite values")
    if model.body.pair_faces:
        return _pair_maps(path, model, grid, title, cmap, label, vmin, vmax)
    fig = _new_figure(_figsize_map(model))
    ax = _map_axes(fig, model)
    mesh = _field(ax, model, grid, cmap=cmap, vmin=vmin, vmax=vmax)
    fig.colorbar(mesh, ax=ax, label=label or "", shrink=0.9)
    ax.set_title(f"{title}\nmin {grid.min():.4g}, max {grid.max():.4g}", fontsize=10)
    return _save(fig, path)


def _pair_maps(path, model, values, title, cmap, label, vmin, vmax) -> Path:
    """Several contact pairs: one panel per pair over its own face, in the chart's coordinates
    (each pair's extent), one colour scale for all."""
    pairs = model.config.assembly.contacts
    xy = np.asarray(model.mesh.contact_points(), float)
    lo = float(values.min()) if vmin is None else vmin
    hi = float(values.max()) if vmax is None else vmax
    fig = _new_figure((3.2 * len(pairs) + 1.6, 5.0))
    xlabel, ylabel = _axis_labels(model)
    off = model.config.off_faces
    if off:         # the rows of faces on other bodies (fem.faces): at their nodes' (x1, x2)
        xy = np.vstack([xy, model.foundation.off_points[:, :2]])
    for k, pair in enumerate(pairs):
        rows = np.flatnonzero(model.pair_of == k)
        if k in off:
            view = model.foundation.off_views[k]
            index = np.full(view.reference.n_nodes, -1)
            index[view.contact_nodes] = np.arange(rows.size)
            faces = np.asarray(view.contact_face.faces)
        else:
            index = np.full(model.mesh.n_nodes, -1)
            index[model.contact_nodes[rows]] = np.arange(rows.size)
            faces = np.asarray(model.body.pair_faces[k].faces)
        corners = faces[:, :4] if faces.shape[1] == 4 else faces[:, :3]
        tris = np.vstack([corners[:, [0, 1, 2]], corners[:, [0, 2, 3]]]) if corners.shape[1] == 4 else corners
        tris = index[tris]
        tris = tris[np.all(tris >= 0, axis=1)]
        ax = fig.add_subplot(1, len(pairs), k + 1)
        tri = Triangulation(xy[rows, 0], xy[rows, 1], tris)
        mesh = ax.tripcolor(tri, values[rows], shading="gouraud", cmap=cmap, vmin=lo, vmax=hi)
        ax.set_xlabel(xlabel, fontsize=8)
        ax.set_ylabel(ylabel if k == 0 else "", fontsize=8)
        ax.set_title(f"{pair.name}: {pair.face} on {pair.counterpart}\nmax {values[rows].max():.4g}", fontsize=8)
    fig.colorbar(mesh, ax=fig.axes, label=label or "", shrink=0.9)
    fig.suptitle(f"{title}, min {values.min():.4g}, max {values.max():.4g}", fontsize=10)
    return _save(fig, path)


def plot_node_classes(path, model, classes, title="Contact node classes (Table 4.1)") -> Path:
    """Categorical map of the node classes (codes 0..5 into L, M1, M2, M3+, M3−, M4) with a legend.

    The legend names every class with its count, including the classes that do not occur.
    """
    codes = np.asarray(_contact_values(model, classes))
    if codes.dtype.kind not in "iu" and not np.all(np.equal(np.mod(codes, 1), 0)):
        raise ValueError("node classes must be integer codes")
    codes = codes.astype(int)
    if codes.size and (codes.min() < 0 or codes.max() >= len(CLASS_NAMES)):
        raise ValueError(f"node class codes must lie in 0..{len(CLASS_NAMES) - 1}, "
                         f"got {codes.min()}..{codes.max()}")
    cmap = ListedColormap(CLASS_COLORS, name="node_classes")
    norm = BoundaryNorm(np.arange(-0.5, len(CLASS_NAMES) + 0.5), cmap.N)
    size = _figsize_map(model, extra_width=2.6)
    fig = _new_figure(size, layout=None)
    fig.subplots_adjust(left=0.9 / size[0], right=1.0 - 2.9 / size[0], bottom=0.6 / size[1], top=1.0 - 0.5 / size[1])
    ax = _map_axes(fig, model)
    _categories(ax, model, codes, cmap, norm)
    handles = [Patch(facecolor=CLASS_COLORS[k], edgecolor="0.4",
                     label=f"{CLASS_LABELS[k]} ({int(np.sum(codes == k))}): {CLASS_DESCRIPTIONS[k]}")
               for k in range(len(CLASS_NAMES))]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8,
              title="class (count)", title_fontsize=8, frameon=False)
    ax.set_title(title, fontsize=10)
    return _save(fig, path)


def plot_stress_comparison(path, model, target, initial, optimal, *,
                           titles=("target", "initial design", "optimal design"),
                           zlabel="normal force $\\lambda$", suptitle=None) -> Path:
    """Three 3D bar plots side by side, as in the paper's Figures 5.2–5.10, with shared z-limits.

    ``target``, ``initial``, ``optimal``: one value per contact node (λ̄, λ(α0), λ(α_opt));
    each bar stands on the dual cell of its contact node. ``target`` None (an objective without a
    target): the initial and the optimal design alone.
    """
    if target is None:
        titles = titles[1:]
    fields = [np.asarray(_contact_values(model, v), float) for v in (target, initial, optimal) if v is not None]
    for name, g in zip(titles, fields):
        if not np.all(np.isfinite(g)):
            raise ValueError(f"plot_stress_comparison: {name!r} has non-finite values")
    fields = [_face_rows(model, g) for g in fields]      # the face body's face (the pair maps show every pair)
    if not _has_grid(model):
        return _stress_maps(path, model, fields, titles, zlabel, suptitle)
    grids = [contact_grid(model, g)[2] for g in fields]
    X1, X2, _ = contact_grid(model)
    e1 = _dual_edges(X1[0], 0.0, model.face_surface.a)
    e2 = _dual_edges(X2[:, 0], 0.0, model.face_surface.b)
    # each bar fills 80 % of its node's dual cell (clipped to the rectangle), centred in it
    dx, dy = 0.8 * np.diff(e1), 0.8 * np.diff(e2)
    c1, c2 = 0.5 * (e1[1:] + e1[:-1]), 0.5 * (e2[1:] + e2[:-1])
    x0, y0 = np.meshgrid(c1 - 0.5 * dx, c2 - 0.5 * dy)
    DX, DY = np.meshgrid(dx, dy)
    zmin = min(0.0, *(g.min() for g in grids))
    zmax = max(0.0, *(g.max() for g in grids))
    if zmax == zmin:
        zmax = zmin + 1.0
    pad = 0.05 * (zmax - zmin)
    cm = colormaps["viridis"]
    fig = _new_figure((15.5 * len(grids) / 3, 4.8), layout=None)
    fig.subplots_adjust(left=0.0, right=0.97, bottom=0.03, top=0.84 if suptitle else 0.9, wspace=0.08)
    for n, (g, title) in enumerate(zip(grids, titles)):
        ax = fig.add_subplot(1, len(grids), n + 1, projection="3d")
        colors = cm((g.ravel() - zmin) / (zmax - zmin))
        _bars(ax, x0.ravel(), y0.ravel(), DX.ravel(), DY.ravel(), g.ravel(), colors)
        ax.set_xlim(0.0, model.face_surface.a)
        ax.set_ylim(0.0, model.face_surface.b)
        ax.set_zlim(zmin - (pad if zmin < 0 else 0.0), zmax + pad)
        ax.set_box_aspect((model.face_surface.a, model.face_surface.b, 0.8 * max(model.face_surface.a, model.face_surface.b)))
        xlabel, ylabel = _axis_labels(model)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_zlabel(zlabel, fontsize=8, labelpad=8)
        ax.tick_params(labelsize=7)
        ax.tick_params(axis="z", pad=6)
        ax.set_title(f"{title}\nsum {g.sum():.4g}, max {g.max():.4g}", fontsize=10)
        ax.view_init(elev=28, azim=-60)
    if suptitle:
        fig.suptitle(suptitle)
    return _save(fig, path)


def _stress_maps(path, model, fields, titles, zlabel, suptitle) -> Path:
    """Maps of per-contact-node fields (two or three) over a face of any shape, on one colour scale."""
    lo = min(0.0, *(g.min() for g in fields))
    hi = max(0.0, *(g.max() for g in fields))
    if hi == lo:
        hi = lo + 1.0
    w, h = _figsize_map(model, extra_width=0.0)
    fig = _new_figure((len(fields) * w * 0.8 + 1.5, h * 0.8 + 0.6), layout=None)
    fig.subplots_adjust(left=0.05, right=0.98, bottom=0.12, top=0.78 if suptitle else 0.82, wspace=0.3)
    tri = face_triangulation(model)
    for n, (g, title) in enumerate(zip(fields, titles)):
        ax = _map_axes(fig, model, (1, len(fields), n + 1))
        m = ax.tripcolor(tri, g, shading="gouraud", cmap="viridis", vmin=lo, vmax=hi)
        ax.set_title(f"{title}\nsum {g.sum():.4g}, max {g.max():.4g}", fontsize=10)
    fig.colorbar(m, ax=fig.axes, label=zlabel, shrink=0.85)
    if suptitle:
        fig.suptitle(suptitle)
    return _save(fig, path)


def plot_force_and_pressure(path, model, lam, pressure, *, title=None) -> Path:
    """Nodal contact forces λ and the contact pressure p = λ/a side by side (each its own scale):
    on an unstructured face λ follows the nodal spacing, p the load."""
    fields = [np.asarray(_contact_values(model, v), float) for v in (lam, pressure)]
    if not all(np.all(np.isfinite(g)) for g in fields):
        raise ValueError("plot_force_and_pressure: a field has non-finite values")
    w, h = _figsize_map(model, extra_width=0.0)
    fig = _new_figure((2 * w * 0.8 + 2.4, h * 0.8 + 0.8))
    for n, (g, what, label) in enumerate(zip(fields, ("normal contact force", "contact pressure"),
                                             ("$\\lambda$", "$p = \\lambda / a$"))):
        ax = _map_axes(fig, model, (1, 2, n + 1))
        mesh = _field(ax, model, g, cmap="viridis")
        fig.colorbar(mesh, ax=ax, label=label, shrink=0.85)
        pos = g[g > 0]
        spread = f", spread (max/min over contact) {pos.max() / pos.min():.3g}" if pos.size else ""
        ax.set_title(f"{what}\nmin {g.min():.4g}, max {g.max():.4g}{spread}", fontsize=9)
    if title:
        fig.suptitle(title)
    return _save(fig, path)


def plot_load_cases(path, model, names, initial, optimal, values0=None, values1=None, *,
                    zlabel="normal force $\\lambda$") -> Path:
    """λ maps of every load case: one row per case, the initial and the optimal design side by
    side, all on one colour scale. ``initial``, ``optimal``: per case a (p,) array in contact-node
    order; ``values0``, ``values1``: Θ_k at the two designs (shown in the titles)."""
    fields = [[np.asarray(_contact_values(model, v), float) for v in pair] for pair in zip(initial, optimal)]
    if not all(np.all(np.isfinite(g)) for row in fields for g in row):
        raise ValueError("plot_load_cases: a λ field has non-finite values")
    lo = min(0.0, *(g.min() for row in fields for g in row))
    hi = max(0.0, *(g.max() for row in fields for g in row))
    hi = hi if hi > lo else lo + 1.0
    w, h = _figsize_map(model, extra_width=0.0)
    fig = _new_figure((2 * w * 0.75 + 1.5, len(names) * (h * 0.75 + 0.3) + 0.3))
    for i, (name, row) in enumerate(zip(names, fields)):
        for j, (g, what) in enumerate(zip(row, ("initial", "optimal"))):
            ax = _map_axes(fig, model, (len(names), 2, 2 * i + j + 1))
            mesh = _field(ax, model, g, cmap="viridis", vmin=lo, vmax=hi)
            vals = values0 if j == 0 else values1
            theta = f", $\\Theta$ = {vals[i]:.4g}" if vals is not None else ""
            ax.set_title(f"{name}: {what}{theta}\nsum {g.sum():.4g}, max {g.max():.4g}", fontsize=9)
    fig.colorbar(mesh, ax=fig.axes, label=zlabel, shrink=0.85)
    return _save(fig, path)


def plot_surface(path, model, alpha, *, resolution=(81, 41), title="Contact surface $\\vartheta_\\alpha$") -> Path:
    """The contact surface ϑ_α(ξ1, ξ2) as a 3D surface with the Bézier control points and net, over
    the chart coordinates of the face ((x1, x2) on the paper's map); several designs: one panel per
    designed face, each over its own chart.

    Control point α_ij is drawn at (a·i/d1, b·j/d2, α_ij), where the linear-precision property of
    Bernstein polynomials puts it (the surface of a planar control net is that plane).
    """
    surfaces = surfaces_of(model.surface)
    blocks = split_design(model.surface, alpha)
    if not all(np.all(np.isfinite(a)) for a in blocks):
        raise ValueError("plot_surface: the design has non-finite entries")
    D = len(surfaces)
    if D == 1:
        fig = _new_figure((9.0, 6.0), layout=None)
        ax = fig.add_axes((0.0, 0.02, 0.84, 0.9), projection="3d")
        sm = _surface_panel(ax, model, surfaces[0], blocks[0], model.body.contact_face.faces, model.mesh,
                            resolution, title, _has_grid(model))
        fig.colorbar(sm, cax=fig.add_axes((0.86, 0.22, 0.025, 0.56)), label="$\\vartheta_\\alpha$")
        return _save(fig, path)
    fig = _new_figure((6.0 * D, 5.5), layout=None)
    names = model.config.assembly.designs
    for k, (surf, a, (faces, morph, points)) in enumerate(zip(surfaces, blocks, model.design_faces())):
        ax = fig.add_subplot(1, D, k + 1, projection="3d")
        sm = _surface_panel(ax, model, surf, a, faces, morph, resolution, f"designs[{k}]: {names[k]}", False,
                            points)
        fig.colorbar(sm, ax=ax, shrink=0.6, label="$\\vartheta_\\alpha$")
    fig.suptitle(title, fontsize=11)
    return _save(fig, path)


def _surface_panel(ax, model, surf, alpha, faces, morph, resolution, title, grid, points=None):
    """One design's surface on ``ax``: ϑ over its design rectangle (over its face only unless the
    face is the block's whole grid), the control net, labels; returns the surface for a colour bar.
    ``points``: the reference nodes of the body the face lies on (None: the face body's)."""
    A = surf.as_matrix(alpha)
    x1lo, x1hi, x2lo, x2hi = surf.x1lo, surf.x1lo + surf.a, surf.x2lo, surf.x2lo + surf.b
    x1 = np.linspace(x1lo, x1hi, resolution[0])
    x2 = np.linspace(x2lo, x2hi, resolution[1])
    G1, G2 = np.meshgrid(x1, x2)
    Z = surf.evaluate(A, G1.ravel(), G2.ravel()).reshape(G1.shape)
    if not grid:
        # the surface over the contact face only (a disc, an L: the rectangle carries the net)
        corners = np.asarray(faces)
        corners = corners[:, :4] if corners.shape[1] == 4 else corners[:, :3]
        tris = np.vstack([corners[:, [0, 1, 2]], corners[:, [0, 2, 3]]]) if corners.shape[1] == 4 else corners
        xy = morph.chart_points(model.body.reference.points if points is None else points)   # unrolled on its chart
        inside = Triangulation(xy[:, 0], xy[:, 1], tris).get_trifinder()(G1, G2) >= 0
        Z = np.where(inside, Z, np.nan)
    c1 = x1lo + surf.a * np.arange(surf.d1 + 1) / max(surf.d1, 1)
    c2 = x2lo + surf.b * np.arange(surf.d2 + 1) / max(surf.d2, 1)
    C1, C2 = np.meshgrid(c1, c2, indexing="ij")
    sm = ax.plot_surface(G1, G2, Z, cmap="terrain", linewidth=0, antialiased=True, alpha=0.85)
    ax.plot_wireframe(C1, C2, A, color="0.25", linewidth=0.6)
    ax.scatter(C1.ravel(), C2.ravel(), A.ravel(), color="crimson", s=14, depthshade=False,
               label=f"control points ({A.shape[0]}×{A.shape[1]})")
    xlabel, ylabel = (_unit(model, label) for label in chart_axes(morph.chart).labels)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    lo, hi = min(0.0, np.nanmin(Z), A.min()), max(np.nanmax(Z), A.max())
    ax.set_zlim(lo, hi + 0.05 * (hi - lo) if hi > lo else lo + 1.0)
    ax.set_zlabel(_lift_label(model, morph), labelpad=_label_pad(ax.zaxis))
    ax.set_box_aspect((surf.a, surf.b, 0.6 * max(surf.a, surf.b)))
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(f"{title}\nmin {np.nanmin(Z):.4g}, max {np.nanmax(Z):.4g}", fontsize=10)
    ax.view_init(elev=25, azim=-60)
    return sm


def plot_history(path, history_rows, *, title="Convergence history") -> Path:
    """Convergence of a bundle run: Θ per iteration (log axis), serious steps marked, stationarity.

    ``history_rows``: list of dicts with keys ``iteration``, ``f`` (Θ at the trial point),
    ``kind`` (``'serious'`` or ``'null'``) and optionally ``stationarity`` (None or missing on some
    rows is fine). The line joins the serious steps, i.e. the accepted iterates. Θ is drawn on a
    log axis when every value is positive, on a linear axis otherwise (logged).
    """
    rows = list(history_rows)
    fig = _new_figure((8.0, 4.8), layout=None)
    fig.subplots_adjust(left=0.11, right=0.88, bottom=0.11, top=0.93)
    ax = fig.add_subplot()
    ax.set_xlabel("iteration")
    ax.set_ylabel("$\\Theta$")
    ax.set_title(title, fontsize=10)
    if not rows:
        ax.text(0.5, 0.5, "no iterations recorded", ha="center", va="center", transform=ax.transAxes)
        log.warning("plot_history: empty history, writing an empty figure to %s", path)
        return _save(fig, path)
    missing = [n for n, r in enumerate(rows) if not {"iteration", "f", "kind"} <= set(r)]
    if missing:
        raise ValueError(f"plot_history: rows {missing[:5]} lack one of 'iteration', 'f', 'kind'")
    it = np.array([float(r["iteration"]) for r in rows])
    f = np.array([float(r["f"]) for r in rows])
    kind = np.array([str(r["kind"]) for r in rows])
    serious = kind == "serious"
    finite = np.isfinite(f)
    if not np.all(finite):
        log.warning("plot_history: %d non-finite objective value(s) left out", int(np.sum(~finite)))
    if np.all(f[finite] > 0):
        ax.set_yscale("log")
    else:
        log.info("plot_history: objective values ≤ 0, using a linear axis")
    ax.plot(it[serious & finite], f[serious & finite], "-o", color="C0", ms=3.5, lw=1.2,
            label=f"serious steps ({int(serious.sum())})")
    null = ~serious & finite
    if np.any(null):
        ax.plot(it[null], f[null], "x", color="0.55", ms=3.5, label=f"null steps ({int(null.sum())})")
    stat = np.array([np.nan if r.get("stationarity") is None else float(r["stationarity"]) for r in rows])
    has_stat = np.isfinite(stat)
    handles, labels = ax.get_legend_handles_labels()
    if np.any(has_stat):
        ax2 = ax.twinx()
        if np.all(stat[has_stat] > 0):
            ax2.set_yscale("log")
        ax2.plot(it[has_stat], stat[has_stat], "-", color="C3", lw=1.0, alpha=0.8, label="stationarity")
        ax2.set_ylabel("stationarity measure", color="C3")
        ax2.tick_params(axis="y", colors="C3")
        h2, l2 = ax2.get_legend_handles_labels()
        handles, labels = handles + h2, labels + l2
    ax.legend(handles, labels, loc="upper right", fontsize=8)
    ax.grid(True, which="major", alpha=0.3)
    return _save(fig, path)


# stick/slip status of a contact node, from its Table 4.1 class: 0 no contact (L), 1 sticking
# (M3+, M3−, M4: u_t = 0), 2 sliding (M1, M2: u_t ≠ 0)
SLIP_STATUS = np.array([0, 2, 2, 1, 1, 1])
SLIP_LABELS = ("no contact", "stick", "slip")
SLIP_COLORS = ("#d9d9d9", "#d62728", "#1f77b4")


def plot_contact_response(path, model, pressure, tau, u_t, classes, *, title=None) -> Path:
    """Four maps of the contact face: the pressure p = λ/a, the tangential force ‖τ_m‖ (the
    friction force on the body is −τ_m), the slip ‖u_t,m‖ and the stick/slip status (from the
    node classes: L no contact; M3+, M3−, M4 stick; M1, M2 slip). ``tau``, ``u_t``: (p, 2) per
    contact node (t1, t2) = (x1, x2)."""
    tau_n = np.linalg.norm(np.asarray(tau, float).reshape(-1, 2), axis=1)
    slip = np.linalg.norm(np.asarray(u_t, float).reshape(-1, 2), axis=1)
    fields = [np.asarray(_contact_values(model, v), float) for v in (pressure, tau_n, slip)]
    if not all(np.all(np.isfinite(g)) for g in fields):
        raise ValueError("plot_contact_response: a field has non-finite values")
    status = SLIP_STATUS[np.asarray(_contact_values(model, classes), int)]
    w, h = _figsize_map(model, extra_width=0.0)
    fig = _new_figure((2 * w * 0.8 + 2.8, 2 * (h * 0.8 + 0.6)), layout=None)
    fig.subplots_adjust(left=0.07, right=0.84, bottom=0.07, top=0.86 if title else 0.9, wspace=0.3, hspace=0.45)
    names = ("contact pressure $p = \\lambda / a$", "tangential force $\\|\\tau\\|$", "slip $\\|u_t\\|$")
    for n, (g, what) in enumerate(zip(fields, names)):
        ax = _map_axes(fig, model, (2, 2, n + 1))
        mesh = _field(ax, model, g, cmap="viridis")
        fig.colorbar(mesh, ax=ax, shrink=0.85)
        ax.set_title(f"{what}\nmax {g.max():.4g}, sum {g.sum():.4g}", fontsize=9)
    ax = _map_axes(fig, model, (2, 2, 4))
    cmap = ListedColormap(SLIP_COLORS, name="stick_slip")
    norm = BoundaryNorm(np.arange(-0.5, 3.5), cmap.N)
    _categories(ax, model, status, cmap, norm)
    ax.legend(handles=[Patch(facecolor=SLIP_COLORS[k], edgecolor="0.4",
                             label=f"{SLIP_LABELS[k]} ({int(np.sum(status == k))})") for k in range(3)],
              loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8, frameon=False)
    ax.set_title("stick / slip", fontsize=9)
    if title:
        fig.suptitle(title)
    return _save(fig, path)


def plot_peak_stress(path, model, coords, u_full, *, cells=None, fraction: float = 0.5, title=None) -> Path:
    """Where the von Mises stress is largest: the quadrature points (of the stiffness rule) of the
    elements ``cells`` (all by default) whose σ_vM is at least ``fraction`` of the peak, seen from
    below (x1, x2) and from the side (x1, x3), coloured by σ_vM; the peak is marked ★ with its
    value and position (:mod:`contactopt.fem.stress`; the value peak_stress's 'max' takes)."""
    asm = model.assembler
    vm = von_mises_points(asm, coords, u_full, cells)
    x = quadrature_points(asm, coords, cells)
    if not np.all(np.isfinite(vm)):
        raise ValueError("plot_peak_stress: the stress has non-finite values")
    vm, x = vm.ravel(), x.reshape(-1, 3)
    top = int(np.argmax(vm))
    keep = vm >= fraction * vm[top]
    order = np.argsort(vm[keep])
    pts, vals = x[keep][order], vm[keep][order]
    lo, hi = coords.min(axis=0), coords.max(axis=0)
    span = hi - lo
    fig = _new_figure((12.5, 4.6), layout=None)
    fig.subplots_adjust(left=0.06, right=0.9, bottom=0.12, top=0.84, wspace=0.2)
    for n, (i, j, name) in enumerate(((0, 1, "from below: $x_1$, $x_2$"), (0, 2, "from the side: $x_1$, $x_3$"))):
        ax = fig.add_subplot(1, 2, n + 1)
        sc = ax.scatter(pts[:, i], pts[:, j], c=vals, cmap="inferno_r", s=10, vmin=fraction * vm[top], vmax=vm[top])
        ax.plot(x[top, i], x[top, j], marker="*", markersize=16, color="cyan", markeredgecolor="k")
        ax.set_xlim(lo[i] - 0.02 * span[i], hi[i] + 0.02 * span[i])
        ax.set_ylim(lo[j] - 0.02 * span[j], hi[j] + 0.02 * span[j])
        ax.set_aspect("equal")
        ax.set_xlabel(_unit(model, f"$x_{i + 1}$"))
        ax.set_ylabel(_unit(model, f"$x_{j + 1}$"))
        ax.set_title(name, fontsize=9)
    fig.colorbar(sc, ax=fig.axes, label="von Mises stress $\\sigma_{vM}$", shrink=0.85)
    p = ", ".join(f"{v:.4g}" for v in x[top])
    fig.suptitle((title + "\n" if title else "") + f"quadrature points with $\\sigma_{{vM}}$ ≥ {fraction:g}·peak; "
                 f"peak ★ {vm[top]:.4g} at ({p})", fontsize=10)
    return _save(fig, path)
