"""The foundation's reference mesh and its parts: a second body under the contact face (issue #22).

``[foundation]`` gives a mesh file (``mesh``, read as ``[body] mesh``) or a generated box
(``block``): the box [o1, o1+s1]×[o2, o2+s2]×[−s3, 0] on a structured grid of Q1 hexahedra (or
each split into six P1 tetrahedra), its top face on x3 = 0 and the foundation below it, with
the parts ``top`` (x3 = 0), ``bottom`` (x3 = −s3), ``left`` (x1 = o1), ``right`` (x1 = o1+s1),
``front`` (x2 = o2) and ``back`` (x2 = o2+s2).

Geometry only (this layer imports nothing from ``fem/``): the checks that need no stiffness —
the top face lies on x3 = 0 with the foundation below it (outward normal +e3), no foundation
node lies above x3 = 0 under the contact face (the bodies would overlap), the parts exist
(unknown names list the known ones) — and the clamped DOFs. Partners, stiffness and compliance
are computed in :mod:`contactopt.fem.foundation`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import ConfigError, MeshError
from .block import block_mesh
from .body import COMPONENTS, _check_rigid_modes
from .reference import FACE_CORNERS, HasParts, Part, ReferenceMesh, describe_part, part_selector
from .rigid import free_modes
from .tetsplit import hex_to_tets


@dataclass
class FoundationMesh(HasParts):
    """The foundation's reference mesh, its ``top`` part (faces outward +e3, nodes on x3 = 0),
    its clamped DOFs ``fixed_dofs`` (full DOF indices 3n + m) and absolute tolerance ``tol``."""

    reference: ReferenceMesh
    top: Part
    fixed_dofs: np.ndarray
    tol: float
    E: float
    nu: float
    loaded: np.ndarray | None = None     # control ≠ 'fixed': the nodes of the part `loaded` (all 3 DOFs fixed)
    rigid: object = None                 # a counterpart held only by its contacts: its free rigid motions


def foundation_block(size, cells, origin=(0.0, 0.0), element: str = "hexahedron") -> ReferenceMesh:
    """The generated box of ``[foundation] block`` (module docstring)."""
    (s1, s2, s3), (n1, n2, n3) = size, cells
    ref = block_mesh(s1, s2, s3, n1, n2, n3)
    points = ref.points + np.array([origin[0], origin[1], -s3])
    points[np.abs(points[:, 2]) <= 1e-14 * s3, 2] = 0.0
    cells_ = ref.cells
    ctype = "hexahedron"
    if element == "tetra":
        cells_, ctype = hex_to_tets(ref.cells, points), "tetra"
    mesh = ReferenceMesh(points, cells_, ctype, source=f"foundation block {n1}×{n2}×{n3} ({ctype})")
    x, lo, hi = points, points.min(axis=0), points.max(axis=0)
    h = min(s1 / n1, s2 / n2, s3 / n3) * 1e-6
    for name, on in (("top", np.abs(x[:, 2] - hi[2]) <= h), ("bottom", np.abs(x[:, 2] - lo[2]) <= h),
                     ("left", np.abs(x[:, 0] - lo[0]) <= h), ("right", np.abs(x[:, 0] - hi[0]) <= h),
                     ("front", np.abs(x[:, 1] - lo[1]) <= h), ("back", np.abs(x[:, 1] - hi[1]) <= h)):
        nodes = np.flatnonzero(on)
        mesh.parts[name] = Part(name, nodes, mesh.faces_within(nodes), "block")
    return mesh


def build_foundation_mesh(spec, contact_xy: np.ndarray, source: str, curved: bool = False,
                          floating: bool = False) -> FoundationMesh:
    """Resolve ``[foundation]`` (``spec``, of the configuration read from ``source``) against the
    body's contact face, given by the (x1, x2) of its nodes ``contact_xy`` (p, 2). ConfigError
    names every problem. ``curved``: the contact face lies on a chart other than x3 = 0 and the top
    face may be any boundary face (its partners and gaps are found along the contact normals)."""
    where = f"{source}: foundation"
    try:
        if spec.mesh:
            from .reader import read_mesh
            ref = read_mesh(spec.mesh)
        else:
            b = spec.block
            ref = foundation_block(b.size, b.cells, b.origin, b.element)
    except MeshError as exc:
        raise ConfigError([f"{where}: {exc}"]) from None
    bad = ref.inverted_cells()
    if bad.size:
        raise ConfigError([f"{where}: {ref.source}: the mesh is inverted as given: {bad.size} of {ref.n_cells} "
                           f"cell(s) have a negative orientation, first cell {int(bad[0])}"])
    tol = float(spec.tolerance) * ref.typical_size()
    problems = []
    part = part_selector(ref, tol, where, problems)

    top = part("top", spec.top)
    fixed = np.zeros((ref.n_nodes, 3), bool)
    for clamp in spec.clamped:
        p = part("clamped", clamp.on)
        if p is not None:
            fixed[np.ix_(p.nodes, sorted({COMPONENTS[c] for c in clamp.components}))] = True
    loaded = None
    direction = spec.translation
    if direction is not None:
        p = part("loaded", spec.loaded)
        if p is not None:
            loaded = np.asarray(p.nodes, np.int64)
    if problems:
        raise ConfigError(problems)
    if loaded is not None:
        _check_translation(ref, fixed, loaded, np.asarray(direction, float), where, spec)
        fixed[loaded] = True
    top = _checked_top(ref, top, spec.top, tol, contact_xy, where, curved)
    rigid = None
    if floating:                        # a counterpart of several pairs may be held by its contacts alone
        rigid = free_modes(ref.points, fixed)
        rigid = rigid if rigid.count else None
    else:
        try:
            _check_rigid_modes(ref, fixed, source, key="foundation.clamped")
        except ConfigError as exc:
            raise ConfigError([f"{p}; a counterpart body is held in place by its own clamps (one held only by its "
                               "contacts is solved in a model of several [[contacts]])" for p in exc.problems]) from None
    mat = spec.material
    return FoundationMesh(ref, top, np.flatnonzero(fixed.ravel()), tol, float(mat.E), float(mat.nu), loaded, rigid)


def other_top(fm: FoundationMesh, top, contact_xy: np.ndarray, source: str, curved: bool = False) -> FoundationMesh:
    """The foundation mesh ``fm`` with the part ``top`` as its top face, checked as
    :func:`build_foundation_mesh` checks ``[foundation] top`` against the contact face of the
    nodes ``contact_xy``: another pair's face on a counterpart body shared by several pairs
    (fem.counterparts), whose partners are searched on it alone."""
    where = f"{source}: foundation"
    problems = []
    part = part_selector(fm.reference, fm.tol, where, problems)
    found = part("top", top)
    if problems:
        raise ConfigError(problems)
    return replace(fm, top=_checked_top(fm.reference, found, top, fm.tol, contact_xy, where, curved))


def _checked_top(ref: ReferenceMesh, top: Part, spec, tol: float, contact_xy, where: str, curved: bool) -> Part:
    """The top face ``top`` (the part ``spec``): any boundary faces on a curved contact face, else
    the face on x3 = 0 with the foundation below it and under the contact face (``contact_xy``)."""
    if curved:
        if top.faces.shape[0] == 0:
            raise ConfigError([f"{where}.top = {describe_part(spec)}: has no boundary faces (it must be the "
                               "foundation's face the contact face touches)"])
        return Part(top.name, np.unique(top.faces), top.faces, top.origin)
    top = _check_top(ref, top, tol, describe_part(spec), where)
    _check_overlap(ref, contact_xy, tol, where)
    return top


def _check_translation(ref: ReferenceMesh, fixed: np.ndarray, loaded: np.ndarray, direction: np.ndarray, where: str,
                       spec) -> None:
    """With control = 'displacement' or 'force' the part ``loaded`` (node numbers) translates along
    ``direction`` and the foundation with it, rigidly: a clamped component of a node outside the
    part must be one the translation leaves at zero (a symmetry plane), and the part must have nodes."""
    if loaded.size == 0:
        raise ConfigError([f"{where}.loaded = {describe_part(spec.loaded)}: has no nodes"])
    held = fixed.copy()
    held[loaded] = False
    node, comp = np.nonzero(held & (np.abs(direction) > 0)[None, :])
    if node.size:
        what = "displacement" if spec.control == "displacement" else "force"
        raise ConfigError([f"{where}.clamped: {node.size} clamped component(s) of nodes outside foundation.loaded "
                           f"lie along the {what} {list(map(float, getattr(spec, what)))}, first u{int(comp[0]) + 1} "
                           f"of node {int(node[0])} at {_fmt(ref.points[node[0]])}: the foundation translates "
                           "rigidly with its loaded part, so elsewhere it may be held only across the translation "
                           "(a symmetry plane containing it)"])


def _check_top(ref: ReferenceMesh, top: Part, tol: float, name: str, where: str) -> Part:
    """The top face: boundary faces, every node on x3 = 0 (snapped there), outward normal +e3."""
    if top.faces.shape[0] == 0:
        raise ConfigError([f"{where}.top = {name}: has no boundary faces (it must be the foundation's face on "
                           "x3 = 0 under the contact face)"])
    nodes = np.unique(top.faces)
    off = np.abs(ref.points[nodes, 2]) > tol
    if np.any(off):
        first = ", ".join(f"node {n} at {_fmt(ref.points[n])}" for n in nodes[off][:5])
        raise ConfigError([f"{where}.top = {name}: {int(off.sum())} node(s) do not lie on x3 = 0 "
                           f"(tolerance {tol:.3g}), first: {first}"])
    ref.points[nodes, 2] = 0.0
    nc = FACE_CORNERS[ref.face_type]
    X = ref.points[top.faces[:, :nc]]
    n3 = np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])[:, 2]
    if np.any(n3 <= 0):
        raise ConfigError([f"{where}.top = {name}: {int(np.sum(n3 <= 0))} face(s) have the foundation above "
                           "them (outward normal not +x3; the foundation must lie in x3 ≤ 0 below the body)"])
    return Part(top.name, nodes, top.faces, top.origin)


def _check_overlap(ref: ReferenceMesh, contact_xy: np.ndarray, tol: float, where: str) -> None:
    """No foundation node above x3 = 0 within the bounding rectangle of the contact face."""
    lo, hi = contact_xy.min(axis=0) - tol, contact_xy.max(axis=0) + tol
    used = ref.used_nodes()
    x = ref.points[used]
    above = (x[:, 2] > tol) & np.all((x[:, :2] >= lo) & (x[:, :2] <= hi), axis=1)
    if np.any(above):
        first = ", ".join(f"node {n} at {_fmt(ref.points[n])}" for n in used[above][:5])
        raise ConfigError([f"{where}: the bodies overlap: {int(above.sum())} node(s) of the foundation lie above "
                           f"x3 = 0 under the contact face (tolerance {tol:.3g}), first: {first}"])


def _fmt(x) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in np.asarray(x)) + ")"
