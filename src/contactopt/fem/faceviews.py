"""A pair's face on a counterpart body of another pair, seen as a body's contact face (fem.faces).

The face's contact nodes (those not clamped along its normal), their clamped tangential components
(pinned, as on the face body), its chart, normals from the counterpart to the face, frames (t1, t2,
n) and nodal areas: what the partner search of :class:`~contactopt.fem.foundation.Foundation` reads
of a face body, for a face whose nodes belong to a counterpart body's mesh.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ..design.chart import resolve_chart
from ..errors import ConfigError, MeshError
from ..mesh.body import Body, _contact_nodes
from ..mesh.obstacle import tangent_frames
from ..mesh.reference import select_part
from .elements import face_type
from .loads import face_areas_nodal


def face_view(fm, part, k: int, source: str):
    """Pair k's face, the part ``part`` of the counterpart body of mesh ``fm``, as a body's contact
    face (:class:`~contactopt.mesh.body.Body`): its contact nodes (those not clamped along the face's
    normal), their clamped tangential components (pinned), the face's chart, outward normals and
    nodal areas. ConfigError naming the pair where the part is no face."""
    ref = fm.reference
    where = f"{source}: contacts[{k}].face"
    try:
        face = select_part(ref, part, fm.tol)
    except MeshError as exc:
        raise ConfigError([f"{where}: {exc}"]) from None
    if face.faces.shape[0] == 0:
        raise ConfigError([f"{where}: has no boundary faces of its body (it must be the face that touches the "
                           "counterpart)"])
    auto = SimpleNamespace(chart="auto", axis=None, origin=None)
    chart = resolve_chart(auto, ref.points, face, ref.face_type, fm.tol, where)
    fixed = np.zeros(3 * ref.n_nodes, bool)
    fixed[fm.fixed_dofs] = True
    fixed = fixed.reshape(-1, 3)
    normal_comp = np.abs(chart.outward(ref.points[face.nodes])) > 1e-9
    nodes, pinned, _ = _contact_nodes(face, fixed, part, where, normal_comp)
    if face_type(ref.face_type).degree != 1:
        raise ConfigError([f"{where}: a face off the face body takes linear faces so far (it has "
                           f"{ref.face_type} faces)"])
    view = Body(ref, fm.tol, np.asarray(fm.fixed_dofs), [], face, nodes, {}, ((0.0, 0.0), (0.0, 0.0)),
                pinned_dofs=pinned, chart=chart)
    view.areas = face_areas_nodal(ref.points, face.faces)[nodes]
    view.normals = -chart.outward(ref.points[nodes])            # from the counterpart to the face
    return view


def check_apart(support: np.ndarray, views: dict, source: str) -> None:
    """No partner of a pair on a face node of another pair's face on the same body (a node carries
    one pair's contact force, and a face's DOFs are the law's own)."""
    problems = []
    for k, v in views.items():
        both = np.intersect1d(support, v.contact_nodes)
        if both.size:
            problems.append(f"{source}: contacts[{k}].face: {both.size} of its node(s) carry partners of another "
                            f"pair on the same body, first node {int(both[0])}; a body's face and the part it is "
                            "the counterpart on must not share nodes")
    if problems:
        raise ConfigError(problems)


def face_frames(view) -> tuple[np.ndarray, np.ndarray]:
    """(R (p_k, 3, 3) with columns (t1, t2, n), pinned (p_k, 3) per frame column) of a face's
    contact nodes: n = its normal from the counterpart, the tangents those of
    :func:`~contactopt.mesh.obstacle.tangent_frames`; a clamped component must be one of the node's
    tangents (a symmetry plane containing the normal), else ConfigError."""
    R = tangent_frames(view.normals)
    pinned = np.zeros((view.contact_nodes.size, 3), bool)
    node, comp = np.divmod(view.pinned_dofs, 3)
    m = np.searchsorted(view.contact_nodes, node)
    for mm, c in zip(m, comp):
        col = np.flatnonzero(np.abs(np.abs(R[mm, c, :2]) - 1.0) < 1e-9)
        if col.size != 1:
            raise ConfigError([f"contact node {int(view.contact_nodes[mm])} of {view.contact_face.name}: its "
                               f"component u{int(c) + 1} is clamped and is not a tangent of its frame (the symmetry "
                               "plane must contain the contact normal)"])
        pinned[mm, col[0]] = True
    return R, pinned
