"""Several designed faces on the face body: their surfaces, harmonic weights and one morph.

For D ≥ 2 designs (``[[designs]]``; :class:`~contactopt.mesh.body.DesignedFace` per face) the body
moves by one displacement field

    x(α) = x_ref + Σ_d ϑ_d(ξ_d(x_ref))·w_d(x_ref)·d_d(x_ref),

with a harmonic weight w_d per designed face: 1 on its face, 0 on the other designed faces, the
clamped parts fixed in shape and the pairs' faces no design moves
(:func:`contactopt.fem.weight.harmonic_weight`). α = (α_1, …, α_D) concatenates the faces' control
points (:class:`~contactopt.design.several.DesignSurfaces`), U is the product of the designs'
admissible sets (:class:`~contactopt.design.several.ProductAdmissible`). ∂A/∂α_d touches only the
elements whose nodes design d moves (w_d ≠ 0). A model of one design does not come here.
"""

from __future__ import annotations

import numpy as np

from ..design.bezier import BezierSurface
from ..design.chart import motion_directions
from ..design.several import DesignSurfaces
from ..mesh.morph import MorphedMesh, SeveralMorphs
from .weight import harmonic_weight


def design_surfaces(cfg, body) -> DesignSurfaces:
    """The Bézier surface of each designed face on its design rectangle, in ``[[designs]]`` order."""
    out = []
    for dsg, df in zip(cfg.designs, body.designs):
        (x1lo, x1hi), (x2lo, x2hi) = df.domain
        out.append(BezierSurface(*dsg.degree, x1hi - x1lo, x2hi - x2lo, x1lo, x2lo))
    return DesignSurfaces(tuple(out))


def design_weights(assembler, body, zero: np.ndarray) -> np.ndarray:
    """(D, n_nodes) the harmonic weight of each designed face: 1 on it, 0 on ``zero`` (the parts
    fixed in shape) and on the other designed faces."""
    faces = [df.face.nodes for df in body.designs]
    ref = body.reference
    return np.array([harmonic_weight(assembler, ref.points, faces[d],
                                     np.concatenate([zero] + [f for e, f in enumerate(faces) if e != d]))
                     for d in range(len(faces))])


def several_morphs(cfg, body, surface: DesignSurfaces, weights: np.ndarray) -> SeveralMorphs:
    """One :class:`~contactopt.mesh.morph.MorphedMesh` per design (its chart, and with
    ``motion = "normal"`` its face's normals as directions), joined in one morph."""
    ref = body.reference
    morphs = []
    for dsg, df, s, w in zip(cfg.designs, body.designs, surface.surfaces, weights):
        chart = {}
        if df.chart is not None:
            chart["chart"] = df.chart
        if dsg.motion == "normal":
            chart["directions"] = motion_directions(ref.points, df.face, ref.face_type, df.chart)
        morphs.append(MorphedMesh(ref, s, w, body.contact_nodes, fixed_shape=tuple(body.fixed_shape), **chart))
    return SeveralMorphs(morphs, surface)


def initial_designs(cfg, surface: DesignSurfaces) -> np.ndarray:
    """α0: each design's ``initial`` (a scalar fills its control points), concatenated."""
    return np.concatenate([np.full(s.size, float(d.initial)) if np.isscalar(d.initial) else s.as_vector(d.initial)
                           for d, s in zip(cfg.designs, surface.surfaces)])
