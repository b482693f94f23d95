"""Hertz on tetrahedra: a rigid sphere pressed into a quarter block meshed by Gmsh, frictionless.

The quarter block [0, L]³ (L = 10 a, a the target contact radius 0.5 of
:mod:`contactopt.verification.hertz`) of unstructured linear (``tetra``) or quadratic (``tetra10``)
tetrahedra, of size h up to the distance 1.6 a from the axis (by default) and growing away from it, clamped on
its top x3 = L, symmetry rollers on x1 = 0 and x2 = 0; the sphere of radius R = 10 under the face
x3 = 0 pressed by the quarter of the force P of contact radius a (``control = "force"``). The
contact face is flat and the sphere curved, so the gap is curved on every face and a node's
dual-weighted gap (``[obstacle] weighting = "mortar"``) differs from its nodal one.

Measured: the nodal pressures p_m = λ_m / a_m (a_m = ∫ N_m dA; on six-node triangles the pressure
of :func:`contactopt.io.pressure.contact_pressure`) against p_Hertz(r) = p0 √(1 − r²/a²), a and p0
from the force P = 4 Σ λ_m n3_m the state carries: the rms and the largest error over the nodes
within 1.5 a of the axis, relative to p0. :func:`error_parts` splits that error into the error of
the forces λ (against the consistent forces of the exact pressure, :func:`hertz_forces`) and the
error of reading forces as a pressure, for three readings (:func:`read_pressure`).

Sign convention: λ_m ≥ 0 the normal force of the sphere on the body at node m, along the sphere's
normal n_m (from the sphere to the body); per contact node the frame (t1, t2, n).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import meshio
import numpy as np
import scipy.sparse.linalg as spla

from contactopt.config import load_config, validate
from contactopt.fem.elements import face_for, tri_rule
from contactopt.io.pressure import contact_areas, contact_pressure, face_mass
from contactopt.mesh.tetsplit import hex_to_tets, tet_boundary_faces
from contactopt.problem import ShapeProblem

from .hertz import A_TARGET, NU, E, R, common, graded_axis, resultant

L = 10 * A_TARGET


def _force(E: float, nu: float) -> float:
    """The force P of contact radius a: P = 4 E* a³ / (3 R), E* = E / (1 − ν²)."""
    return 4 * (E / (1 - nu ** 2)) * A_TARGET ** 3 / (3 * R)


def quarter_mesh(path: str | Path, h: float, order: int = 1, growth: float = 0.25, seed: int = 1,
                 fine: float = 1.6) -> str:
    """A Gmsh file of the quarter block (module docstring): element size h within ``fine``·a of the
    origin, h + growth·(distance − fine·a) beyond; groups ``contact`` (x3 = 0), ``top`` and ``body``.
    Gmsh is imported here: an optional dependency (the ``mesh`` extra)."""
    import gmsh

    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("quarter")
        gmsh.model.occ.addBox(0, 0, 0, L, L, L)
        gmsh.model.occ.synchronize()
        for dim, tag in gmsh.model.getBoundary([(3, 1)], oriented=False):
            z = gmsh.model.occ.getCenterOfMass(dim, tag)[2]
            if abs(z) < 1e-9:
                gmsh.model.addPhysicalGroup(2, [tag], name="contact")
            elif abs(z - L) < 1e-9:
                gmsh.model.addPhysicalGroup(2, [tag], name="top")
        gmsh.model.addPhysicalGroup(3, [1], name="body")
        f = gmsh.model.mesh.field.add("MathEval")
        gmsh.model.mesh.field.setString(f, "F", f"{h}+{growth}*Max(0,Sqrt(x*x+y*y+z*z)-{fine * A_TARGET})")
        gmsh.model.mesh.field.setAsBackgroundMesh(f)
        for key, value in (("Mesh.MeshSizeExtendFromBoundary", 0), ("Mesh.MeshSizeFromPoints", 0),
                           ("Mesh.MeshSizeFromCurvature", 0), ("Mesh.Algorithm", 6),
                           ("Mesh.RandomSeed", seed), ("Mesh.MshFileVersion", 2.2)):
            gmsh.option.setNumber(key, value)
        gmsh.model.mesh.generate(3)
        if order == 2:
            gmsh.model.mesh.setOrder(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return str(path)


def split_mesh(path: str | Path, h: float) -> str:
    """The quarter block as the graded grid of :func:`contactopt.verification.hertz.graded_axis`
    (h up to 1.6 a, then growing by 1.25) with every hexahedron split into six linear tetrahedra:
    a structured contact face of equal node areas in the fine zone. Groups as :func:`quarter_mesh`."""
    x = np.asarray(graded_axis(h, 1.6 * A_TARGET, L))
    n = x.size
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    pts = np.c_[X.ravel(), Y.ravel(), Z.ravel()]
    idx = np.arange(n ** 3).reshape(n, n, n)

    def corner(i, j, k):
        return idx[i:n - 1 + i, j:n - 1 + j, k:n - 1 + k].ravel()
    hexes = np.stack([corner(*o) for o in ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
                                            (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1))], axis=1)
    tets = hex_to_tets(hexes, pts)
    bf = tet_boundary_faces(tets)
    bottom, top = bf[np.all(pts[bf, 2] == 0.0, axis=1)], bf[np.all(pts[bf, 2] == x[-1], axis=1)]
    cells = [("tetra", tets), ("triangle", bottom), ("triangle", top)]
    tags = [np.full(len(c), t) for (_, c), t in zip(cells, (3, 1, 2))]
    meshio.write(path, meshio.Mesh(pts, cells, cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                                   field_data={"contact": np.array([1, 2]), "top": np.array([2, 2]),
                                               "body": np.array([3, 3])}), file_format="gmsh22", binary=True)
    return str(path)


def quarter_problem(mesh: str, weighting: str = "node", nu: float = NU) -> ShapeProblem:
    """The sphere pressed by P/4 into the quarter block of the Gmsh file ``mesh``, frictionless;
    P the force of contact radius a for the Poisson ratio ``nu``."""
    data = load_config("example1").to_dict()
    for key in ("geometry", "mesh"):
        data.pop(key, None)
    for sec, vals in common(0.0).items():
        data[sec] = {**data.get(sec, {}), **vals}
    data["material"]["nu"] = nu
    data["loads"] = {"body_force": [0.0, 0.0, 0.0]}
    data["body"] = {"mesh": str(mesh), "contact": "contact",
                    "clamped": ["top", {"on": {"x1": 0.0}, "components": [1]}, {"on": {"x2": 0.0}, "components": [2]}]}
    data["obstacle"] = {"shape": "sphere", "center": [0.0, 0.0, -R], "radius": R, "control": "force",
                        "force": [0.0, 0.0, _force(E, nu) / 4], "weighting": weighting}
    return ShapeProblem(validate(data, f"hertz on {Path(mesh).name}"))


def hertz_errors(problem: ShapeProblem, state, within: float = 1.5) -> dict:
    """rms and max of (p − p_Hertz)/p0 over the contact nodes within ``within``·a of the axis
    (module docstring), with the radius r, p and p_Hertz of every contact node."""
    m = problem.model
    x = m.body.reference.points[m.contact_nodes]
    r = np.hypot(x[:, 0], x[:, 1])
    p = contact_pressure(m, state.lam, state.coords)
    P = 4.0 * float(resultant(problem, state)[2])
    e_star = problem.model.config.material.E / (1 - problem.model.config.material.nu ** 2)
    a = (3 * P * R / (4 * e_star)) ** (1 / 3)
    p0 = 3 * P / (2 * math.pi * a * a)
    ph = p0 * np.sqrt(np.clip(1 - (r / a) ** 2, 0.0, None))
    use = r < within * a
    e = (p[use] - ph[use]) / p0
    return {"rms": float(np.sqrt(np.mean(e * e))), "max": float(np.abs(e).max()), "a": a, "p0": p0,
            "r": r, "p": p, "p_hertz": ph, "nodes": int(use.sum())}


def measure(mesh: str, weighting: str = "node", nu: float = NU) -> dict:
    t0 = time.perf_counter()
    pr = quarter_problem(mesh, weighting, nu)
    st = pr.solve_state(np.zeros(pr.model.n_design))
    out = hertz_errors(pr, st)
    out.update(time=time.perf_counter() - t0, contact_nodes=pr.model.n_contact, problem=pr, state=st)
    return out


def hertz_forces(model, coords, a: float, p0: float, degree: int = 10) -> np.ndarray:
    """The consistent nodal forces of the exact Hertz pressure, λ_H,m = ∫ N_m p_Hertz dA over the
    contact face at ``coords`` (contact-node order; a rule exact to ``degree`` on each face): the
    forces a perfect displacement field would give, to be read as the computed λ is read. Sign
    convention as λ: ≥ 0 pushing the body off the sphere."""
    faces = np.asarray(model.body.contact_face.faces, np.int64)
    pts = np.asarray(coords, float)
    q, w = tri_rule(degree)
    N, dN = face_for(faces).shape(q)
    X = pts[faces]
    T1, T2 = np.einsum("fam,qa->fqm", X, dN[:, :, 0]), np.einsum("fam,qa->fqm", X, dN[:, :, 1])
    dA = np.linalg.norm(np.cross(T1, T2), axis=2) * w
    xq = np.einsum("qa,fam->fqm", N, X)
    pq = p0 * np.sqrt(np.clip(1 - (np.hypot(xq[..., 0], xq[..., 1]) / a) ** 2, 0.0, None))
    f = np.bincount(faces.ravel(), weights=np.einsum("fq,qa,fq->fa", dA, N, pq).ravel(), minlength=pts.shape[0])
    return f[np.asarray(model.contact_nodes, np.int64)]


def face_stress_pressure(model, state) -> np.ndarray:
    """The pressure read from the body's stress instead of its nodal forces: −σ33 of the
    tetrahedron under each face of the flat contact face x3 = 0 (constant on a linear tetrahedron),
    averaged over a node's faces with their areas (contact-node order). Four-node tetrahedra only."""
    cells = np.asarray(model.assembler.elements, np.int64)
    faces = np.asarray(model.body.contact_face.faces, np.int64)
    if cells.shape[1] != 4 or faces.shape[1] != 3:
        raise ValueError("the stress reading takes four-node tetrahedra with three-node contact faces")
    pts = np.asarray(state.coords, float)
    sig = model.assembler.cell_stresses(pts, np.asarray(state.u, float))
    owner = {}
    for e, c in enumerate(cells):
        for f in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
            owner[tuple(sorted(c[list(f)]))] = e
    fe = np.array([owner[tuple(sorted(f))] for f in faces])
    X = pts[faces]
    A = 0.5 * np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1)
    num = np.bincount(faces.ravel(), weights=np.repeat(-A * sig[fe, 2], 3), minlength=pts.shape[0])
    den = np.bincount(faces.ravel(), weights=np.repeat(A, 3), minlength=pts.shape[0])
    nodes = np.asarray(model.contact_nodes, np.int64)
    return num[nodes] / den[nodes]


READINGS = ("nodal", "l2", "mean")


def read_pressure(model, lam, coords, reading: str = "nodal") -> np.ndarray:
    """The nodal pressure of the forces ``lam`` (contact-node order) read three ways:

    - ``nodal``: :func:`contactopt.io.pressure.contact_pressure` (λ_m / a_m on linear faces);
    - ``l2``: the L²-projection onto the face's functions, M p = λ (M the face mass matrix);
    - ``mean``: the hat-weighted mean of the nodal reading, p_m = Σ_n M_mn p_n / a_m, a smoothing
      (linear faces: on six-node triangles a_m = 0 at the corners).

    All three recover a uniform pressure exactly (M 1 = a, the lumped areas)."""
    faces = np.asarray(model.body.contact_face.faces, np.int64)
    nodes = np.asarray(model.contact_nodes, np.int64)
    p = contact_pressure(model, lam, coords)
    if reading == "nodal":
        return p
    M = face_mass(np.asarray(coords, float), faces, nodes)
    if reading == "l2":
        return spla.spsolve(M.tocsc(), np.asarray(lam, float))
    if reading == "mean":
        if face_for(faces).degree != 1:
            raise ValueError("the hat-weighted mean reading takes linear faces (∫ N_m dA = 0 at six-node corners)")
        return (M @ p) / contact_areas(np.asarray(coords, float), faces, nodes)
    raise ValueError(f"unknown pressure reading {reading!r}; expected one of {', '.join(READINGS)}")


def error_parts(res: dict) -> dict:
    """What the pressure error of a :func:`measure` result is made of, per reading of
    :func:`read_pressure`, as rms over the nodes within 1.5 a (and within 0.8 a: ``_in``), relative
    to p0: ``total`` p(λ) − p_Hertz; ``forces`` p(λ) − p(λ_H), the error of the forces alone
    (λ_H of :func:`hertz_forces`); ``reading`` p(λ_H) − p_Hertz, the error of the reading alone,
    with exact forces; ``min`` the least p(λ)/p0 and ``min_exact`` the least p(λ_H)/p0 (``mean``
    on linear faces only). The
    parts are rms of the two terms of one sum: they need not add up, and partly cancel."""
    pr, st = res["problem"], res["state"]
    m = pr.model
    p0, ph, r, a = res["p0"], res["p_hertz"], res["r"], res["a"]
    lam_h = hertz_forces(m, st.coords, a, p0)
    use, inner = r < 1.5 * a, r < 0.8 * a

    def rms(v, sel):
        return float(np.sqrt(np.mean(v[sel] ** 2)) / p0)

    out = {"lam_hertz": lam_h}
    linear = face_for(np.asarray(m.body.contact_face.faces)).degree == 1
    for reading in READINGS if linear else READINGS[:2]:
        p, p_h = read_pressure(m, st.lam, st.coords, reading), read_pressure(m, lam_h, st.coords, reading)
        parts = {}
        for name, v in (("total", p - ph), ("forces", p - p_h), ("reading", p_h - ph)):
            parts[name], parts[name + "_in"] = rms(v, use), rms(v, inner)
        parts.update(min=float(p.min() / p0), min_exact=float(p_h.min() / p0))
        out[reading] = parts
    return out
