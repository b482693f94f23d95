"""The body of a configuration: its reference mesh and the parts its conditions are given on.

``[body] mesh`` names a mesh file (:mod:`contactopt.mesh.reader`); without it the body is the
paper's block of ``[geometry]`` and ``[mesh]`` (:mod:`contactopt.mesh.block`): two sources of
one :class:`~contactopt.mesh.reference.ReferenceMesh`, after which everything is the same.

Conventions (docs/theory.md): the foundation is the half-space x3 ≤ 0 with outward normal e3;
the contact face lies on x3 = 0 in the reference mesh with the body above it (the outward normal
of the body on the face is −e3) and is a graph over (x1, x2). With ``[body] initial_gap = "mesh"``
the face may lie above the plane (an exported optimal body, :mod:`contactopt.io.export`): its
height x3 in the mesh is an initial gap, to which the design surface ϑ_α adds. Its nodes whose
normal component u3 is not clamped are the contact nodes, ordered by node number; contact node m
owns the condensed DOFs (u1, u2, u3) = (t1, t2, ν).

Partly clamped contact nodes (a symmetry plane through the contact face): a clamped tangential
component u1 or u2 of a contact node stays a contact DOF, *pinned* (``Body.pinned_dofs``): it is a
free DOF of A(α) whose row and column are replaced by the diagonal entry, with no load
(:meth:`contactopt.fem.model.ElasticModel.assemble`). The Coulomb law of the node then forces
u = 0 and a zero contact force there (a decoupled spring cannot balance a friction force opposed
to its own displacement), so the node keeps the normal law and Coulomb friction in its other
tangential direction (|τ_free| ≤ Fλ), or the normal law alone when both are clamped; the clamp
carries the reaction. A clamped normal component u3 takes the node out of the contact set (with a
warning when the node is not clamped in every component); u3 clamped on more than half of the
face is a ConfigError.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from types import SimpleNamespace

import numpy as np
from scipy.spatial import cKDTree

from ..design.chart import face_normals, resolve_chart
from ..errors import ConfigError, MeshError
from .block import block_axes, block_mesh, graded_block_mesh
from .reader import read_mesh
from .reference import FACE_CORNERS, HasParts, Part, ReferenceMesh, describe_part, part_selector, select_part
from .rigid import free_modes

log = logging.getLogger(__name__)

COMPONENTS = {"x1": 0, "x2": 1, "x3": 2, 1: 0, 2: 1, 3: 2}


@dataclass
class Body(HasParts):
    """A reference mesh with its resolved parts (see the module docstring)."""

    reference: ReferenceMesh
    tol: float                    # absolute geometric tolerance
    fixed_dofs: np.ndarray        # full DOF indices 3n + m with u = 0, eliminated from A
    clamped: list                 # [(Part, components)]
    contact_face: Part
    contact_nodes: np.ndarray
    fixed_shape: dict             # name → nodes with morph weight 0
    domain: tuple                 # ((x1lo, x1hi), (x2lo, x2hi)) of the design rectangle
    warnings: list = field(default_factory=list)
    pinned_dofs: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    # full DOF indices of the clamped tangential components of contact nodes: free DOFs of A
    # with u = 0 held by the contact law (module docstring)
    rigid: object = None          # mesh.rigid.RigidModes the clamps leave free (held by contact), or None
    chart: object = None          # design.chart.PlaneChart | CylinderChart of the face; None: ξ = (x1, x2)
    penetration_tol: float = 0.0  # absolute depth a node may lie inside the counterpart (no interference)
    sizes: tuple | None = field(default=None, compare=False, repr=False)
    # (free DOFs, entries of the stiffness on them), counted once by contactopt.fem.memory
    pair_faces: tuple = ()        # several contact pairs: each pair's face (Part); the contact nodes are theirs
    pair_of: np.ndarray | None = None   # (p,) the pair of each contact node, in [[contacts]] order
    pair_charts: tuple = ()       # several pairs, some off the designed face's chart: each pair's face's chart
    designs: tuple = ()           # several designs: every designed face (DesignedFace), the first the contact face
    owner: tuple | None = None    # a pair's face on a counterpart body (fem.faces): (that body, its counterpart)

    @property
    def contact_faces(self) -> np.ndarray:
        """The faces of the contact nodes: the contact face's, and with several pairs those of the
        pairs' faces off it as well (the tributary areas, the pressure)."""
        if not self.pair_faces:
            return self.contact_face.faces
        return np.unique(np.vstack([self.contact_face.faces] + [pf.faces for pf in self.pair_faces]), axis=0)

    def contact_outward(self) -> np.ndarray:
        """(p, 3) the outward unit normal of the face at each contact node, from the chart of the
        contact face or, where the pairs' faces have no common chart, from each pair's."""
        if not self.pair_charts:
            if self.chart is None:        # the paper's face: ξ = (x1, x2), the counterpart below it
                return np.tile([0.0, 0.0, -1.0], (self.contact_nodes.size, 1))
            return self.chart.outward(self.reference.points[self.contact_nodes])
        return _pair_outward(self.reference.points, self.contact_nodes, self.pair_faces, self.pair_charts)

    def pair_view(self, k: int) -> "Body":
        """The body as pair k's counterpart sees it: its contact face and nodes those of the pair
        (the partners and compliance of one pair are built on it, fem.counterparts)."""
        mine = self.pair_of == k
        nodes = self.contact_nodes[mine]
        node = self.pinned_dofs // 3
        chart = self.pair_charts[k] if self.pair_charts else self.chart
        return replace(self, contact_face=self.pair_faces[k], contact_nodes=nodes, chart=chart,
                       pinned_dofs=self.pinned_dofs[np.isin(node, nodes)], pair_faces=(), pair_of=None,
                       pair_charts=())


@dataclass(frozen=True)
class DesignedFace:
    """One of several designed faces (``[[designs]]``): its part of the body, its chart (None: the
    paper's ξ = (x1, x2)) and its design rectangle ((x1lo, x1hi), (x2lo, x2hi)) on the chart."""

    face: Part
    chart: object
    domain: tuple


def reference_mesh(cfg):
    """The reference mesh of a configuration: the file of ``[body] mesh`` or the block."""
    path = cfg.body.mesh
    if path:
        return read_mesh(path)
    g, m = cfg.geometry, cfg.mesh
    if not m.graded:
        return block_mesh(g.a, g.b, g.c, m.nx, m.ny, m.nz)
    return graded_block_mesh(*block_axes(g, m))


def build_body(cfg) -> Body:
    """Resolve ``[body]`` of a validated configuration; ConfigError/MeshError name the problem."""
    spec = cfg.body
    try:
        ref = reference_mesh(cfg)
    except MeshError as exc:
        raise ConfigError([f"{cfg.source}: body.mesh: {exc}"]) from None
    bad = ref.inverted_cells()
    if bad.size:
        e = int(bad[0])
        raise ConfigError([f"{cfg.source}: body.mesh: {ref.source}: the mesh is inverted as given: {bad.size} of "
                           f"{ref.n_cells} cell(s) have a negative orientation, first cell {e} at "
                           f"{_fmt(ref.points[ref.cells[e]].mean(axis=0))} (node order of the cells: meshio/VTK)"])
    h = ref.typical_size()
    tol = float(spec.tolerance) * h
    gtol = float(spec.graph_tolerance or spec.tolerance) * h
    ptol = float(spec.penetration_tolerance or spec.tolerance) * h
    problems = []
    part = part_selector(ref, tol, "body", problems)

    clamped = []
    for clamp in spec.clamped:
        p = part("clamped", clamp.on)
        if p is not None:
            clamped.append((p, sorted({COMPONENTS[c] for c in clamp.components})))
    face = _union([part("contact", c) for c in _as_list(spec.contact)])
    off = cfg.off_faces                   # pairs whose face lies on another body (fem.faces): no part here
    pair_faces = [Part(f"contacts[{k}].face", np.zeros(0, np.int64), np.zeros((0, FACE_CORNERS[ref.face_type]),
                                                                              np.int64), "elsewhere")
                  if k in off else part("contact", pr.contact) for k, pr in enumerate(cfg.pairs)]
    if problems:
        raise ConfigError([f"{cfg.source}: {p}" for p in problems])
    _check_pair_faces(pair_faces, cfg.source)
    more = _more_design_faces(cfg, ref, tol, face)
    fixed = np.zeros((ref.n_nodes, 3), bool)
    for p, comps in clamped:
        fixed[np.ix_(p.nodes, comps)] = True
    pair_charts = ()
    outside = [k for k, pf in enumerate(pair_faces) if not np.all(np.isin(pf.nodes, face.nodes))]
    designed = [face] + more            # every designed face (one but for several [[designs]])
    try:
        chart = _chart(cfg, ref, face, gtol)
    except ConfigError:
        if not pair_faces or cfg.assembly.designs:
            raise
        chart, outside = None, list(range(len(pair_faces)))   # no design, and the faces share no chart
    if outside:
        # pairs off the designed face (or, without a design, faces that share no chart: a block
        # between two others): each pair's face its own chart, which gives the frames of its nodes
        auto = SimpleNamespace(chart="auto", axis=None, origin=None)
        pair_charts = tuple(resolve_chart(auto, ref.points, pf, ref.face_type, gtol, cfg.source)
                            if pf.nodes.size else None for pf in pair_faces)
    if pair_charts and not cfg.assembly.designs:
        face = Part(face.name, np.unique(face.faces), face.faces, face.origin)
    elif chart is None:
        face = _check_contact_face(ref, face, ptol, on_plane=spec.initial_gap == "zero", graph_tol=gtol,
                                   interference=spec.interference, plane=_plane_name(cfg))
    else:
        face = Part(face.name, np.unique(face.faces), face.faces, face.origin)
    normal_comp = None
    faces_all = face
    if outside and cfg.assembly.designs:   # the contact nodes are the pairs', on and off the designed face
        faces_all = _union([face] + [pair_faces[k] for k in outside])
    if pair_charts:
        normal_comp = np.abs(_pair_outward(ref.points, faces_all.nodes, pair_faces, pair_charts)) > 1e-9
    elif chart is not None:
        # on a chart the components clamped along the face's normal take a node out, those in its
        # tangent plane (a symmetry plane or an end face through the face) are pinned tangents
        normal_comp = np.abs(chart.outward(ref.points[face.nodes])) > 1e-9
    contact_nodes, pinned, warnings = _contact_nodes(faces_all, fixed, spec.contact, cfg.source, normal_comp)
    pair_of = None
    if pair_faces:                        # several pairs: their nodes are the contact nodes
        pair_of = np.full(ref.n_nodes, -1)
        for k, pf in enumerate(pair_faces):
            pair_of[pf.nodes] = k
        contact_nodes = contact_nodes[pair_of[contact_nodes] >= 0]
        pinned = pinned[np.isin(pinned // 3, contact_nodes)]
        pair_of = pair_of[contact_nodes]
    rigid = free_modes(ref.points, fixed)
    if rigid.count:
        log.info("body.clamped leaves %d rigid-body motion(s) free: %s; contact must hold them", rigid.count,
                 ", ".join(rigid.names()))
    fixed_shape = _fixed_shape(ref, spec.fixed_shape, _union(designed), tol, cfg.source)
    for k in outside if cfg.assembly.designs else ():
        within = False
        for n, f in enumerate(designed):
            shared = np.intersect1d(pair_faces[k].nodes, f.nodes)
            within |= shared.size == pair_faces[k].nodes.size
            if shared.size and shared.size < pair_faces[k].nodes.size:
                what = f"designs[{n}].face" if more else "the designed face"
                raise ConfigError([f"{cfg.source}: contacts[{k}].face: shares {shared.size} node(s) with {what} "
                                   f"{f.name!r} without lying within it, first node {int(shared[0])}: a pair's face "
                                   "lies on the designed face or apart from it"])
        if not within:
            fixed_shape[f"contacts[{k}].face"] = pair_faces[k].nodes      # off the designs: the morph leaves it
    xi = ref.points[face.nodes, :2] if chart is None else chart.parameters(ref.points[face.nodes])
    domain = _domain(cfg.design.domain, xi, face, tol, cfg.source)
    designs = ()
    if more:
        designs = (DesignedFace(face, chart, domain),) + tuple(
            _designed_face(cfg, n, ref, f, gtol, ptol, tol) for n, f in enumerate(more, start=1))
    eliminated = fixed.copy()
    eliminated.ravel()[pinned] = False
    body = Body(ref, tol, np.flatnonzero(eliminated.ravel()), clamped, face, contact_nodes, fixed_shape, domain,
                pinned_dofs=pinned, rigid=rigid if rigid.count else None, chart=chart, penetration_tol=ptol,
                pair_faces=tuple(pair_faces), pair_of=pair_of, pair_charts=pair_charts, designs=designs)
    body.warnings += warnings + _thin_tetrahedra(ref) + _poor_cells(ref)
    for w in body.warnings:
        log.warning("%s", w)
    return body


def _more_design_faces(cfg, ref: ReferenceMesh, tol: float, face: Part) -> list:
    """The parts of the designs after the first (``cfg.more_designs``); ConfigError naming a face
    that is no part of the body, or two designed faces that share nodes (a node is moved by one
    design: each face's harmonic weight is 1 on it and 0 on the others)."""
    problems, parts = [], []
    for n, d in enumerate(cfg.more_designs, start=1):
        try:
            parts.append(select_part(ref, d.face, tol))
        except MeshError as exc:
            problems.append(f"designs[{n}].face = {describe_part(d.face)}: {exc}")
    if problems:
        raise ConfigError([f"{cfg.source}: {p}" for p in problems])
    for n, p in enumerate(parts, start=1):
        if p.faces.shape[0] == 0:
            problems.append(f"designs[{n}].face = {p.name}: has no boundary faces (a designed face is a surface "
                            "of the body)")
        for m, q in enumerate([face] + parts[:n - 1]):
            both = np.intersect1d(p.nodes, q.nodes)
            if both.size:
                problems.append(f"designs[{n}].face and designs[{m}].face: share {both.size} node(s), first node "
                                f"{int(both[0])} at {_fmt(ref.points[both[0]])}; designed faces must not share "
                                "nodes (a node is moved by one design): split the faces")
    if problems:
        raise ConfigError([f"{cfg.source}: {p}" for p in problems])
    return parts


def _designed_face(cfg, n: int, ref: ReferenceMesh, face: Part, gtol: float, ptol: float, tol: float):
    """Design n ≥ 1 of several: its face, chart and design rectangle, as the first design's."""
    dsg = cfg.more_designs[n - 1].design
    chart = _chart(cfg, ref, face, gtol, dsg)
    if chart is None:
        face = _check_contact_face(ref, face, ptol, on_plane=cfg.body.initial_gap == "zero", graph_tol=gtol,
                                   interference=cfg.body.interference, plane=_plane_name(cfg))
    else:
        face = Part(face.name, np.unique(face.faces), face.faces, face.origin)
    xi = ref.points[face.nodes, :2] if chart is None else chart.parameters(ref.points[face.nodes])
    try:
        domain = _domain(dsg.domain, xi, face, tol, cfg.source)
    except ConfigError as exc:
        raise ConfigError([p.replace("design.", f"designs[{n}].").replace("body.contact", f"designs[{n}].face")
                           for p in exc.problems]) from None
    return DesignedFace(face, chart, domain)


def _contact_nodes(face: Part, fixed: np.ndarray, contact, source: str, normal_comp=None):
    """(contact nodes, pinned DOFs, warnings) of the contact face (the part ``contact``) under the
    clamps ``fixed``.

    A node whose normal component u3 is clamped is no contact node (a warning names those clamped
    in u3 but not in every component); a clamped u1 or u2 of a contact node is pinned (module
    docstring). ConfigError when no node is left, or when u3 is clamped on more than half of the face.
    ``normal_comp`` (face nodes × 3, on a chart): the global components with a part along the face's
    normal; a clamp of one of them takes the node out, the other clamped components are pinned."""
    name = describe_part(contact)
    f = fixed[face.nodes]
    normal = f[:, 2] if normal_comp is None else np.any(f & normal_comp, axis=1)
    contact_nodes = face.nodes[~normal]
    if contact_nodes.size == 0:
        raise ConfigError([f"{source}: body.contact = {name}: every node of the contact face is clamped in its "
                           f"normal component u3 ({face.nodes.size} nodes); no node is left to touch the foundation"])
    if 2 * int(normal.sum()) > face.nodes.size:
        raise ConfigError([f"{source}: body.clamped: the normal component u3 is clamped on {int(normal.sum())} of the "
                           f"{face.nodes.size} nodes of the contact face {name} (more than half); those nodes "
                           "cannot touch the foundation. Clamp only tangential components (u1, u2) on a symmetry "
                           "plane through the contact face"])
    warnings = []
    partly = face.nodes[normal & ~np.all(f, axis=1)]
    if partly.size:
        warnings.append(f"body.clamped: {partly.size} node(s) of the contact face {name} have their normal "
                        f"component u3 clamped and are no contact nodes: nodes "
                        + ", ".join(str(int(n)) for n in partly[:10]) + (", …" if partly.size > 10 else ""))
    if normal_comp is None:
        tangential = fixed[contact_nodes, :2]
        pinned = (3 * contact_nodes[:, None] + np.arange(2))[tangential].astype(np.int64)
    else:
        pinned = (3 * contact_nodes[:, None] + np.arange(3))[fixed[contact_nodes]].astype(np.int64)
    return contact_nodes, np.sort(pinned), warnings


def _as_list(x):
    return x if isinstance(x, list) else [x]


def _pair_outward(points, nodes, pair_faces, charts) -> np.ndarray:
    """(len(nodes), 3) outward normals at ``nodes`` from the chart of the pair each lies in."""
    out = np.zeros((nodes.size, 3))
    for pf, c in zip(pair_faces, charts):
        if c is None:             # a pair whose face lies on another body
            continue
        mine = np.isin(nodes, pf.nodes)
        out[mine] = c.outward(points[nodes[mine]])
    return out


def _union(parts: list) -> Part | None:
    """One part of several (the faces of several pairs): their nodes and faces together."""
    if any(p is None for p in parts):
        return None
    if len(parts) == 1:
        return parts[0]
    faces = np.unique(np.vstack([np.sort(p.faces, axis=1) for p in parts]), axis=0, return_index=True)[1]
    allf = np.vstack([p.faces for p in parts])
    return Part(" + ".join(p.name for p in parts), np.unique(np.concatenate([p.nodes for p in parts])),
                allf[np.sort(faces)], parts[0].origin)


def _check_pair_faces(pair_faces: list, source: str) -> None:
    """The faces of several pairs: no node in two of them (a node carries one pair's contact force)."""
    problems = []
    seen = {}
    for k, pf in enumerate(pair_faces):
        for j, nodes in seen.items():
            both = np.intersect1d(nodes, pf.nodes)
            if both.size:
                problems.append(f"contacts[{k}].face and contacts[{j}].face: {both.size} node(s) are claimed by both "
                                f"pairs, first node {int(both[0])}; a node belongs to one pair (split the faces)")
        seen[k] = pf.nodes
    if problems:
        raise ConfigError([f"{source}: {p}" for p in problems])


def _chart(cfg, ref: ReferenceMesh, face: Part, gtol: float, design=None):
    """The chart of the contact face (:mod:`contactopt.design.chart`), or None for the paper's
    ξ = (x1, x2): ``design.chart = "auto"`` on a face whose outward normals all point down (−x3),
    or whose counterpart is the plane x3 = 0, which :func:`_check_contact_face` then checks as before.

    A chart other than a plane with outward normal −e3 needs a counterpart that gives each contact
    node its frame: a rigid ``[obstacle]`` other than the plane x3 = 0. ``design``: the design of
    the face (default ``[design]``)."""
    d = cfg.design if design is None else design
    if face.faces.shape[0] == 0:
        return None                       # _check_contact_face names it
    obstacle = cfg.obstacle
    if d.chart == "auto" and not d.axis and not d.origin:
        nf, _ = face_normals(ref.points, face.faces, ref.face_type)
        rigid_plane = obstacle is None or obstacle.shape == "plane"
        if np.all(nf[:, 2] < 0) or (rigid_plane and cfg.foundation is None and not cfg.pairs):
            return None
    chart = resolve_chart(d, ref.points, face, ref.face_type, gtol, cfg.source)
    flat = chart.kind == "plane" and np.abs(chart.normal - [0.0, 0.0, -1.0]).max() <= 1e-12
    foundation = cfg.foundation is not None or bool(cfg.pairs)
    if not flat and (obstacle is None or obstacle.shape == "plane") and not foundation:
        raise ConfigError([f"{cfg.source}: body.contact = {face.name}: the face lies on a {chart.describe()}, "
                           "not on the foundation plane x3 = 0: its counterpart must be a rigid [obstacle] "
                           "(sphere, cylinder or surface) or an elastic [foundation] whose top face it touches"])
    return chart


def _plane_name(cfg) -> str:
    """The plane x3 = 0 of the paper's map in the words of messages: the foundation plane, the
    plane of a rigid obstacle or of an elastic foundation's top face, or only the plane the face
    is designed on (an obstacle's gap is the distance to its sphere, cylinder or surface)."""
    if cfg.foundation is not None:
        return "the plane x3 = 0 of the elastic foundation's top face"
    if cfg.obstacle is None:
        return "the foundation plane x3 = 0"
    if cfg.obstacle.shape == "plane":
        return "the obstacle's plane x3 = 0"
    return "the plane x3 = 0 the face is designed on"


def _check_contact_face(ref: ReferenceMesh, face: Part, tol: float, on_plane: bool = True, graph_tol=None,
                        interference: bool = False, plane: str = "the foundation plane x3 = 0") -> Part:
    """The contact face lies on x3 = 0 (snapped there), the body above it, and is a graph over (x1, x2).

    ``on_plane=False`` (``initial_gap = "mesh"``): the face may lie above the plane, x3 ≥ 0, and
    keeps its coordinates as they are (they are its initial gap); with ``interference`` also below
    it (a negative initial gap). ``tol`` is the penetration tolerance, ``graph_tol`` (default
    ``tol``) that of the graph check; ``plane`` names x3 = 0 in messages (:func:`_plane_name`)."""
    graph_tol = tol if graph_tol is None else graph_tol
    name = face.name
    if face.faces.shape[0] == 0:
        raise ConfigError([f"body.contact = {name}: has no boundary faces (it must be a surface of the body "
                           f"lying on {plane})"])
    nodes = np.unique(face.faces)
    off = np.abs(ref.points[nodes, 2]) > tol if on_plane else ref.points[nodes, 2] < (-np.inf if interference else -tol)
    if np.any(off):
        bad = nodes[off][:5]
        where = f"do not lie on {plane}" if on_plane else f"lie below {plane}"
        raise ConfigError([f"body.contact = {name}: {int(off.sum())} node(s) {where} (tolerance {tol:.3g}), first: "
                           + ", ".join(f"node {n} at {_fmt(ref.points[n])}" for n in bad)])
    if on_plane:
        ref.points[nodes, 2] = 0.0          # rounded coordinates of the file: exactly on the plane
    elif not interference:
        ref.points[nodes, 2] = np.maximum(ref.points[nodes, 2], 0.0)
    nc = FACE_CORNERS[ref.face_type]
    X = ref.points[face.faces[:, :nc]]
    n3 = np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])[:, 2]
    if np.any(n3 >= 0):
        up = face.faces[n3 >= 0][:3, :nc]
        raise ConfigError([f"body.contact = {name}: {int(np.sum(n3 >= 0))} face(s) have the body below them "
                           f"(outward normal +x3; the body must lie in x3 ≥ 0 above {plane}), first with "
                           f"nodes {up.tolist()}"])
    pairs = cKDTree(ref.points[nodes, :2]).query_pairs(graph_tol, output_type="ndarray")
    if len(pairs):
        a, b = nodes[pairs[0, 0]], nodes[pairs[0, 1]]
        raise ConfigError([f"body.contact = {name}: is not a graph over (x1, x2): {len(pairs)} pair(s) of nodes "
                           f"share the same (x1, x2), first nodes {a} and {b} at {_fmt(ref.points[a, :2])}"])
    return Part(name, nodes, face.faces, face.origin)


def _check_rigid_modes(ref: ReferenceMesh, fixed: np.ndarray, source: str, key: str = "body.clamped") -> None:
    """The clamped components ``fixed`` (n, 3) of a body that must hold itself (an elastic
    foundation, a counterpart body) remove its six rigid-body motions, else its stiffness is
    singular; the error names the motions left free (:func:`~contactopt.mesh.rigid.free_modes`)."""
    free = free_modes(ref.points, fixed)
    if free.count:
        raise ConfigError([f"{source}: {key} leaves {free.count} rigid-body motion(s) free, "
                           f"{', '.join(free.names())} ({int(fixed.sum())} clamped DOFs): the stiffness would be "
                           "singular. Clamp a part that holds the body in place"])


def _fixed_shape(ref, spec, face: Part, tol: float, source: str) -> dict:
    """Parts with morph weight 0: ``"auto"`` = the named parts that share no node with the contact face."""
    out = {}
    if spec == "auto":
        for name, p in ref.parts.items():
            if p.origin in ("file", "block") and not np.any(np.isin(p.nodes, face.nodes)):
                out[name] = p.nodes
        return out
    problems = []
    for s in _as_list(spec):
        try:
            p = select_part(ref, s, tol)
        except MeshError as exc:
            problems.append(f"body.fixed_shape: {exc}")
            continue
        if np.any(np.isin(p.nodes, face.nodes)):
            problems.append(f"body.fixed_shape: part {describe_part(s)} shares nodes with the contact face, "
                            "which must move with the design")
        out[p.name] = p.nodes
    if problems:
        raise ConfigError([f"{source}: {p}" for p in problems])
    return out


def _domain(given, xy, face: Part, tol: float, source: str):
    """The design rectangle: ``design.domain`` or the bounding rectangle of the contact face's chart
    coordinates ``xy`` (x1, x2 on the paper's plane)."""
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    if not given:
        if np.any(hi - lo <= tol):
            raise ConfigError([f"body.contact = {face.name}: the face has no extent in x{int(np.argmin(hi - lo)) + 1}"])
        return ((float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1])))
    (a0, a1), (b0, b1) = given
    out = (xy[:, 0] < a0 - tol) | (xy[:, 0] > a1 + tol) | (xy[:, 1] < b0 - tol) | (xy[:, 1] > b1 + tol)
    if np.any(out):
        n = face.nodes[out][0]
        raise ConfigError([f"{source}: design.domain = {given}: {int(out.sum())} node(s) of the contact face "
                           f"lie outside it, first node {n} at {_fmt(xy[out][0])}"])
    return ((float(a0), float(a1)), (float(b0), float(b1)))


def _thin_tetrahedra(ref: ReferenceMesh) -> list:
    """Linear tetrahedra are stiff in bending: warn when most of them touch the boundary with all
    their vertices (a part only one or two elements thick)."""
    if ref.cell_type != "tetra":
        return []
    on_bnd = np.zeros(ref.n_nodes, bool)
    on_bnd[ref.boundary_faces()] = True
    frac = float(np.mean(np.all(on_bnd[ref.cells], axis=1)))
    if frac < 0.5:
        return []
    return [f"{ref.source}: {100 * frac:.0f} % of the linear tetrahedra have every vertex on the boundary: parts "
            "of the body are only one or two elements thick, where linear tetrahedra are too stiff in bending "
            "(20–50 % too little deflection); refine there or use tetra10 (P2) elements"]


POOR_QUALITY = 0.1


def _poor_cells(ref: ReferenceMesh) -> list:
    """A valid mesh of poor quality still loads (element quality is judged relative to it), with a
    warning naming the worst cell."""
    q = ref.quality()
    bad = np.flatnonzero(q < POOR_QUALITY)
    if bad.size == 0:
        return []
    e = int(bad[np.argmin(q[bad])])
    return [f"{ref.source}: {bad.size} of {ref.n_cells} cells have a shape quality below {POOR_QUALITY} "
            f"(worst {q[e]:.3g}, cell {e} at {_fmt(ref.points[ref.cells[e]].mean(axis=0))}); results on them "
            "are less accurate"]


def _fmt(x) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in np.asarray(x)) + ")"
