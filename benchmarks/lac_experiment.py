"""Patch-averaged (LAC-style) frictionless contact on linear tetrahedra: does it fix the Hertz pressure?

An experiment beside contactopt, not a feature: it changes nothing in the library's behaviour.

What. On the Gmsh quarter blocks of :mod:`contactopt.verification.hertz_tets` (linear tetrahedra of
size a/6, a/8, a/10 under the contact, the rigid sphere R = 10 pressed by the force P of contact
radius a, frictionless) the node-wise contact gives a pressure 5.2 / 3.4 / 3.2 % rms of p0 from
Hertz, almost all of it in the nodal forces λ. Here the multiplier space changes: the contact face's
triangles are grouped into patches P of a few triangles, the pressure p_P is constant on each
patch, and the gap is averaged over it (one constraint per patch, as Code_Aster's "local average
contact" does on its macro-elements):

    ∫_P (g(x) + u_ν(x) − s f̂·n(x)) dA ≥ 0,   p_P ≥ 0,   complementary,

u_ν(x) = Σ_m N_m(x) n_m·u_m (the nodal normals n_m of the sphere, from the sphere to the body),
g(x) = |x − c| − R the exact distance to the sphere (integrated by a rule of degree 10), s the
sphere's rise along f̂ = e3. The nodal forces are those of the patch pressures,
λ_m = Σ_P p_P ∫_P N_m dA ≥ 0 along n_m (they push the body off the sphere), so the constraint and
the force are work-conjugate. Force control, as the library's test: Σ_m λ_m n_m·e3 = P/4 (the
quarter of the force), so a and p0 are those of the same P and compare with the library's run.

How. The model (stiffness K on the free DOFs after the Dirichlet conditions and the symmetry
rollers, frames, nodal gaps) comes from ``hertz_tets.quarter_problem``; K is condensed onto the
contact nodes' normal displacements, D = B K⁻¹ Bᵀ (B the rows n_mᵀ), and the patch problem is the
small dense QP

    min ½ pᵀ (W D Wᵀ) p + Gᵀ p   subject to p ≥ 0, (W n3)ᵀ p = P/4,

W_Pm = ∫_P N_m dA, G_P = ∫_P g dA (its multiplier of the force row is s). Clarabel solves it and
a principal-pivoting loop polishes the active set until the equality-constrained system on it is
solved exactly and the signs hold; the KKT residual (relative) is printed. The node-wise
constraint is the same QP with W = I and G = the nodal gaps: it must reproduce the library's
λ (printed: the largest difference relative to max λ) and its 5.16 / 3.41 / 3.22 %.

Readings, rms of (p − p_Hertz)/p0, a and p0 from the resultant P of the forces (4 Σ λ_m n_m·e3):
``patch`` p_P against p_Hertz at the patch's centroid, over patches with centroid within 1.5 a;
``node-mean`` p_m the area-weighted mean of the patches at node m, against p_Hertz(x_m);
``node λ/a`` the outputs' nodal reading λ_m / ∫N_m of the patch forces (a hat-weighted mean of
the patches), both over the nodes within 1.5 a. Controls: ``floor`` the exact Hertz pressure
averaged over each patch against its centroid value (the patch reading's own error), and
``node-wise, averaged`` the node-wise solution's pressure averaged over the same patches (so that
the effect of the constraint is told from the smoothing of the patch reading).

Patch rules: ``pairs`` — greedy matching of each triangle with the unmatched neighbour across its
longest edge (triangles left alone join the neighbour patch across their longest edge: patches of
2, some of 3); ``quads`` — the pairs paired again the same way (patches of about 4); ``stars`` — the stars of a greedy maximal independent set of face vertices (each
triangle has at most one such vertex; triangles with none join a neighbour patch: patches of
about 5–7 triangles).

Run (about 11 s)::

    python benchmarks/lac_experiment.py [--sizes 6 8 10] [--rules pairs quads stars cells] [--gap exact|nodal]
                                        [--mesh gmsh|split] [--detail]

``--gap nodal`` replaces ∫_P g dA by Σ_m W_Pm g_m (the nodal gaps interpolated).

``--rules cells`` adds a third space, not patches of triangles: the nodes' median dual cells (one
pressure per node, the gap averaged over the cell). ``--mesh split`` takes the graded grid split
into six tetrahedra per hexahedron instead (slow: minutes per size).

Found (docs/mortar.md, "A patch-averaged experiment"): no patch space reaches 1 % rms at a/6, a/8,
a/10 or a/16. Pairs are not stable (σ_min 0.19 → 0.07, patch pressures 17, 11, 10, 11 %); quads,
stars and dual cells keep σ_min up but their patch pressures miss by 6.4, 6.3 and 6.5 % at a/10,
and their best nodal reading (2.2 %, cells) is what averaging the node-wise solution over the same
patches gives too (2.2 %). The node-wise constraint through this solver reproduces the library's λ (1e-12) and its
5.16 / 3.41 / 3.22 %.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import clarabel
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from contactopt.fem.elements import tri_rule
from contactopt.io.pressure import contact_areas, contact_pressure
from contactopt.verification import hertz_tets as ht
from contactopt.verification.hertz import R


# ---------------------------------------------------------------- the model, condensed
def condensed(mesh: str) -> dict:
    """The library's problem on ``mesh`` solved node-wise (its reference λ), and what the
    experiment needs: the Delassus matrix D of the contact nodes' normal displacements, the nodal
    gaps g and normal parts n3, the force P/4, the face's triangles in contact-node numbering."""
    pr = ht.quarter_problem(mesh)
    st = pr.solve_state(np.zeros(pr.model.n_design))
    m = pr.model
    asm = m.assemble(np.zeros(m.n_design))
    p = m.contact_nodes.size
    n = m.frames[:, :, 2]                                   # (p, 3) from the sphere to the body
    cols = m.contact_dofs.reshape(p, 3)
    vals = n.copy()
    vals[np.isin(cols, m.pinned_free)] = 0.0                # symmetry rollers: n has no part there
    B = sp.csr_matrix((vals.ravel(), (np.repeat(np.arange(p), 3), cols.ravel())), shape=(p, asm.A.shape[0]))
    lu = spla.splu(sp.csc_matrix(asm.A))
    D = B @ lu.solve(B.T.toarray())
    D = 0.5 * (D + D.T)
    local = np.full(m.body.reference.points.shape[0], -1)
    local[m.contact_nodes] = np.arange(p)
    faces = local[np.asarray(m.body.contact_face.faces, np.int64)]
    assert np.all(faces >= 0)
    of = m.obstacle_force
    return {"problem": pr, "state": st, "model": m, "D": D, "g": np.asarray(asm.gap, float),
            "n3": np.asarray(of.gap_rate, float), "force": float(of.magnitude), "faces": faces,
            "x": m.body.reference.points[m.contact_nodes], "coords": st.coords}


# ---------------------------------------------------------------- patches
def _neighbours(faces: np.ndarray):
    """Per triangle its (neighbour, shared edge length) across each edge (−1 on the boundary)."""
    edges = {}
    for t, f in enumerate(faces):
        for k in range(3):
            e = tuple(sorted((f[k], f[(k + 1) % 3])))
            edges.setdefault(e, []).append(t)
    nb = [[] for _ in faces]
    for e, ts in edges.items():
        if len(ts) == 2:
            nb[ts[0]].append((ts[1], e))
            nb[ts[1]].append((ts[0], e))
    return nb


def _absorb(patch: np.ndarray, faces, x, nb) -> np.ndarray:
    """Triangles without a patch (−1) join the patch across their longest shared edge."""
    while np.any(patch < 0):
        for t in np.flatnonzero(patch < 0):
            cand = [(np.linalg.norm(x[e[0]] - x[e[1]]), patch[s]) for s, e in nb[t] if patch[s] >= 0]
            if cand:
                patch[t] = max(cand)[1]
    return patch


def pairs(faces: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Patch index per triangle: greedy pairs across the longest edge (module docstring)."""
    nb = _neighbours(faces)
    patch = np.full(len(faces), -1)
    k = 0
    for t in range(len(faces)):
        if patch[t] >= 0:
            continue
        cand = [(np.linalg.norm(x[e[0]] - x[e[1]]), s) for s, e in nb[t] if patch[s] < 0]
        if cand:
            patch[t] = patch[max(cand)[1]] = k
            k += 1
    left = patch < 0
    patch = _absorb(patch, faces, x, nb)
    return patch, int(left.sum())


def quads(faces: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Patch index per triangle: the pairs of :func:`pairs` paired again across their longest
    shared edge (patches of about 4 triangles; a pair left alone joins a neighbour patch)."""
    first, alone = pairs(faces, x)
    nb = _neighbours(faces)
    n = first.max() + 1
    border = {}                                  # (pair, pair) → shared edge length
    for t, lst in enumerate(nb):
        for s_, e in lst:
            if first[s_] != first[t]:
                key = (first[t], first[s_])
                border[key] = border.get(key, 0.0) + np.linalg.norm(x[e[0]] - x[e[1]])
    adj = [[] for _ in range(n)]
    for (p_, q_), length in border.items():
        adj[p_].append((length, q_))
    second = np.full(n, -1)
    k = 0
    for p_ in range(n):
        if second[p_] >= 0:
            continue
        cand = [(length, q_) for length, q_ in adj[p_] if second[q_] < 0]
        if cand:
            second[p_] = second[max(cand)[1]] = k
            k += 1
    left = second < 0
    for p_ in np.flatnonzero(left):
        second[p_] = second[max(adj[p_])[1]] if adj[p_] else k
        k += 0 if adj[p_] else 1
    return np.unique(second[first], return_inverse=True)[1], alone + int(left.sum())


def stars(faces: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Patch index per triangle: stars of a greedy maximal independent set of vertices."""
    nv = x.shape[0]
    adj = [set() for _ in range(nv)]
    for f in faces:
        for a in f:
            adj[a].update(f)
    chosen = np.zeros(nv, bool)
    blocked = np.zeros(nv, bool)
    for v in np.argsort(np.hypot(x[:, 0], x[:, 1]), kind="stable"):
        if not blocked[v]:
            chosen[v] = True
            blocked[list(adj[v])] = True
    ids = np.cumsum(chosen) - 1
    patch = np.full(len(faces), -1)
    for t, f in enumerate(faces):
        c = f[chosen[f]]
        assert c.size <= 1
        if c.size:
            patch[t] = ids[c[0]]
    left = patch < 0
    patch = _absorb(patch, faces, x, _neighbours(faces))
    return np.unique(patch, return_inverse=True)[1], int(left.sum())


RULES = {"pairs": pairs, "quads": quads, "stars": stars}


# ---------------------------------------------------------------- integrals on the face
def dual_cells(faces: np.ndarray, x: np.ndarray):
    """Not a patch of triangles: the median dual cell of every face node (the quadrilaterals
    node, edge midpoints, centroid of each triangle at it), one pressure per node, the gap averaged
    over the cell. Returns (pieces (n, 3, 3), parent triangle, cell) as :func:`pieces` does."""
    X = x[faces]
    cen = X.mean(axis=1)
    out, parent, pid = [], [], []
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        mij, mik = 0.5 * (X[:, i] + X[:, j]), 0.5 * (X[:, i] + X[:, k])
        for tri in ((X[:, i], mij, cen), (X[:, i], cen, mik)):
            out.append(np.stack(tri, axis=1))
            parent.append(np.arange(len(faces)))
            pid.append(faces[:, i])
    return np.concatenate(out), np.concatenate(parent), np.concatenate(pid)


def pieces(c: dict, rule: str):
    """The face cut into pieces, each a triangle in one patch: (pieces (n, 3, 3), the face triangle
    each lies in, its patch) and the number of triangles a patch rule left alone."""
    faces, x = c["faces"], np.asarray(c["coords"], float)[c["model"].contact_nodes]
    if rule == "cells":
        return (*dual_cells(faces, x), 0)
    patch, alone = RULES[rule](faces, x)
    return x[faces], np.arange(len(faces)), patch, alone


def face_integrals(c: dict, Xp: np.ndarray, parent: np.ndarray, pid: np.ndarray, a: float | None = None,
                   p0: float | None = None) -> dict:
    """On the pieces Xp (in face triangles ``parent``, patches ``pid``): W (patches × nodes) =
    ∫_P N_m dA, |P|, centroids, ∫_P g dA (g the exact distance to the sphere) and, with a and p0,
    ∫_P p_Hertz dA; the face flat (x3 = 0), one rule of degree 10 on each piece."""
    faces, x = c["faces"], np.asarray(c["coords"], float)[c["model"].contact_nodes]
    q, w = tri_rule(10)
    N = np.c_[1 - q[:, 0] - q[:, 1], q[:, 0], q[:, 1]]
    area = 0.5 * np.linalg.norm(np.cross(Xp[:, 1] - Xp[:, 0], Xp[:, 2] - Xp[:, 0]), axis=1)
    dA = np.outer(area * 2, w)                                  # reference triangle of area 1/2
    xq = np.einsum("qa,fam->fqm", N, Xp)
    # the parent triangle's functions at the pieces' points (barycentric coordinates, flat face)
    T = x[faces[parent]]
    J = np.stack([T[:, 1, :2] - T[:, 0, :2], T[:, 2, :2] - T[:, 0, :2]], axis=2)
    lam12 = np.linalg.solve(J[:, None], (xq[..., :2] - T[:, None, 0, :2])[..., None])[..., 0]
    Nq = np.concatenate([1 - lam12.sum(axis=2, keepdims=True), lam12], axis=2)      # (n, q, 3)
    npatch = pid.max() + 1
    W = sp.csr_matrix((np.einsum("fq,fqa->fa", dA, Nq).ravel(), (np.repeat(pid, 3), faces[parent].ravel())),
                      shape=(npatch, x.shape[0])).toarray()
    gq = np.linalg.norm(xq - np.array([0.0, 0.0, -R]), axis=2) - R
    out = {"W": W, "area": np.bincount(pid, area, npatch), "G": np.bincount(pid, (gq * dA).sum(axis=1), npatch)}
    out["centroid"] = np.stack([np.bincount(pid, area * Xp[:, :, k].mean(axis=1), npatch) for k in range(2)],
                               axis=1) / out["area"][:, None]
    if a is not None:
        pq = p0 * np.sqrt(np.clip(1 - (np.hypot(xq[..., 0], xq[..., 1]) / a) ** 2, 0.0, None))
        out["PH"] = np.bincount(pid, (pq * dA).sum(axis=1), npatch)
    return out


# ---------------------------------------------------------------- the QP, solved exactly
def solve_qp(H: np.ndarray, q: np.ndarray, c: np.ndarray, F: float) -> tuple[np.ndarray, float, float, int]:
    """min ½pᵀHp + qᵀp subject to p ≥ 0, cᵀp = F: (p, s, KKT residual, polishing steps).

    s is the multiplier of the force row: w = Hp + q − s c ≥ 0 the averaged gaps after the
    deformation, p·w = 0. Clarabel gives the active set, principal pivoting makes it exact."""
    n = q.size
    P = sp.csc_matrix(np.triu(H))
    A = sp.vstack([sp.csr_matrix(c[None, :]), -sp.identity(n)]).tocsc()
    b = np.r_[F, np.zeros(n)]
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-12
    sol = clarabel.DefaultSolver(P, q, A, b, [clarabel.ZeroConeT(1), clarabel.NonnegativeConeT(n)], settings)
    p0 = np.array(sol.solve().x)
    act = p0 > 1e-6 * p0.max()
    it = 0
    while True:
        i = np.flatnonzero(act)
        K = np.block([[H[np.ix_(i, i)], -c[i, None]], [c[None, i], np.zeros((1, 1))]])
        z = sla.solve(K, np.r_[-q[i], F])
        p = np.zeros(n)
        p[i], s = z[:-1], z[-1]
        wgap = H @ p + q - s * c
        neg = i[p[i] < 0]
        viol = np.flatnonzero(~act & (wgap < 0))
        if neg.size == 0 and viol.size == 0:
            break
        it += 1
        if it > 200:
            raise RuntimeError("principal pivoting did not settle in 200 steps")
        act[neg] = False
        act[viol] = True
    scale_p, scale_w = np.abs(p).max(), np.abs(H @ p).max()
    kkt = max(np.abs(np.minimum(p / scale_p, wgap / scale_w)).max(), abs(c @ p - F) / F)
    return p, s, float(kkt), it


# ---------------------------------------------------------------- Hertz
def hertz_of(P: float, nu: float = ht.NU) -> tuple[float, float]:
    """a and p0 of the whole force P (E* = E/(1 − ν²), the sphere's R)."""
    e_star = ht.E / (1 - nu ** 2)
    a = (3 * P * R / (4 * e_star)) ** (1 / 3)
    return a, 3 * P / (2 * math.pi * a * a)


def rms(v: np.ndarray, sel: np.ndarray, p0: float) -> float:
    return float(np.sqrt(np.mean(v[sel] ** 2)) / p0)


def sigma_min(W: np.ndarray, area: np.ndarray, nodal_area: np.ndarray, sel: np.ndarray) -> float:
    """The least singular value of M_P^(−1/2) W M_N^(−1/2) on the patches ``sel`` and the nodes they
    touch (M_P the patches' areas, M_N the nodes' lumped areas): how well the patch pressures are
    seen by the nodal forces, 1 for a pressure the forces carry fully, 0 for a patch pattern that
    puts no force on any node (a checkerboard): an L² stand-in for the inf-sup constant."""
    nodes = np.flatnonzero((W[sel] > 0).any(axis=0))
    S = W[np.ix_(sel, nodes)] / np.sqrt(area[sel])[:, None] / np.sqrt(nodal_area[nodes])[None, :]
    return float(np.linalg.svd(S, compute_uv=False).min())


def tets_per_triangle(model) -> np.ndarray:
    """Per contact node, the tetrahedra at it per face triangle at it (contact-node order)."""
    n = model.body.reference.points.shape[0]
    tets = np.bincount(np.asarray(model.assembler.elements).ravel(), minlength=n)
    tris = np.bincount(np.asarray(model.body.contact_face.faces).ravel(), minlength=n)
    return (tets / np.maximum(tris, 1))[model.contact_nodes]


def experiment(sizes, rules, gap: str, kind: str = "gmsh", detail: bool = False) -> None:
    print(f"{kind} meshes; force control (P/4 on the quarter, as the library's test); a, p0 from the computed "
          f"resultant; patch gap {gap}.")
    print("rms of (p − p_Hertz)/p0 in %, within 1.5 a (within 0.8 a):")
    print("| h | rule | patches (triangles per patch: mean, range) | p_P | p_P − mean of p_Hertz over P "
          "| floor: mean over P of p_Hertz | node-mean | node λ/a | node-wise λ, averaged alike | σ_min "
          "| KKT (pivots) | time |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")

    def both(v, r, a, p0):
        return f"{100 * rms(v, r < 1.5 * a, p0):.2f} ({100 * rms(v, r < 0.8 * a, p0):.2f})"

    lines = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in sizes:
            t0 = time.perf_counter()
            path = Path(tmp) / f"q{k}.msh"
            mesh = (ht.split_mesh(path, ht.A_TARGET / k) if kind == "split" else
                    ht.quarter_mesh(path, ht.A_TARGET / k))
            c = condensed(mesh)
            m, D, g, n3, F = c["model"], c["D"], c["g"], c["n3"], c["force"]
            x = c["x"]
            r = np.hypot(x[:, 0], x[:, 1])
            # node-wise, through this solver: must reproduce the library
            lam, s, kkt, its = solve_qp(D, g, n3, F)
            ref = np.asarray(c["state"].lam, float)
            dif = np.abs(lam - ref).max() / ref.max()
            a_n, p0_n = hertz_of(4 * float(n3 @ lam))
            ph = ph_n = p0_n * np.sqrt(np.clip(1 - (r / a_n) ** 2, 0.0, None))
            pn = contact_pressure(m, lam, c["coords"])
            lib = ht.hertz_errors(c["problem"], c["state"])["rms"]
            print(f"| a/{k} | node-wise | {r.size} nodes (λ vs the library's: {dif:.1e}; library {100 * lib:.2f}) "
                  f"| – | – | – | – | {both(pn - ph, r, a_n, p0_n)} | – | – | {kkt:.1e} ({its}) "
                  f"| {time.perf_counter() - t0:.1f} s |", flush=True)
            areas = contact_areas(np.asarray(c["coords"], float), m.body.contact_face.faces, m.contact_nodes)
            for rule in rules:
                t1 = time.perf_counter()
                Xp, parent, pid, alone = pieces(c, rule)
                fi = face_integrals(c, Xp, parent, pid)
                W = fi["W"]
                G = fi["G"] if gap == "exact" else W @ g
                pp, s, kkt, its = solve_qp(W @ D @ W.T, G, W @ n3, F)
                lam_p = W.T @ pp
                a, p0 = hertz_of(4 * float(n3 @ lam_p))
                fi = face_integrals(c, Xp, parent, pid, a, p0)
                ph = p0 * np.sqrt(np.clip(1 - (r / a) ** 2, 0.0, None))
                rc = np.hypot(fi["centroid"][:, 0], fi["centroid"][:, 1])
                phc = p0 * np.sqrt(np.clip(1 - (rc / a) ** 2, 0.0, None))
                mean_h = fi["PH"] / fi["area"]
                touch = (W > 0).astype(float) * fi["area"][:, None]
                pmean = (touch.T @ pp) / touch.sum(axis=0)           # area-weighted mean of a node's patches
                # the node-wise solution's pressure (linear on the face) averaged over the same patches
                pnw = (W @ pn) / fi["area"]
                phc_n = p0_n * np.sqrt(np.clip(1 - (rc / a_n) ** 2, 0.0, None))
                sm = sigma_min(W, fi["area"], areas, np.flatnonzero(rc < 0.8 * a))
                nt = np.bincount(np.unique(np.c_[pid, parent], axis=0)[:, 0])     # triangles per patch
                print(f"| a/{k} | {rule} | {pp.size} ({nt.mean():.2f}, {nt.min()}–{nt.max()}; {alone} joined) "
                      f"| {both(pp - phc, rc, a, p0)} | {both(pp - mean_h, rc, a, p0)} | {both(mean_h - phc, rc, a, p0)} "
                      f"| {both(pmean - ph, r, a, p0)} | {both(lam_p / areas - ph, r, a, p0)} "
                      f"| {both(pnw - phc_n, rc, a_n, p0_n)} | {sm:.2f} | {kkt:.1e} ({its}) "
                      f"| {time.perf_counter() - t1:.1f} s |", flush=True)
                if detail:
                    # within 0.8 a: the nodal gaps a patch leaves (relative to the approach s), their
                    # correlation with the tetrahedra per triangle, and that of the patch pressures' own
                    # error with the patch's mean tetrahedra per triangle
                    tpt = tets_per_triangle(m)
                    inner, pin = r < 0.8 * a, rc < 0.8 * a
                    wn = g + D @ lam_p - s * n3
                    tp = (W @ tpt) / W.sum(axis=1)
                    lines.append(f"a/{k} {rule}: nodal gaps within 0.8 a {wn[inner].min() / s:+.4f} to "
                                 f"{wn[inner].max() / s:+.4f} of the approach, correlation with tetrahedra per "
                                 f"triangle {np.corrcoef(wn[inner], tpt[inner])[0, 1]:+.2f}; p_P − mean p_Hertz "
                                 f"against the patch's tetrahedra per triangle "
                                 f"{np.corrcoef((pp - mean_h)[pin], tp[pin])[0, 1]:+.2f}")
            if detail:
                inner = r < 0.8 * a_n
                lines.append(f"a/{k} node-wise: p − p_Hertz against tetrahedra per triangle within 0.8 a "
                             f"{np.corrcoef((pn - ph_n)[inner], tets_per_triangle(m)[inner])[0, 1]:+.2f}")
    print("\n".join(lines))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[6, 8, 10], help="element sizes a/k")
    ap.add_argument("--rules", nargs="+", default=[*RULES, "cells"], choices=[*RULES, "cells"],
                    help="patch rules (cells: the nodes' median dual cells, one pressure per node)")
    ap.add_argument("--gap", default="exact", choices=["exact", "nodal"], help="the patch gap: ∫_P g dA or Σ W_Pm g_m")
    ap.add_argument("--mesh", default="gmsh", choices=["gmsh", "split"],
                    help="Gmsh's quarter block, or the graded grid split into six tetrahedra per hexahedron")
    ap.add_argument("--detail", action="store_true",
                    help="the nodal gaps a patch leaves and the errors' correlation with the tetrahedra per triangle")
    args = ap.parse_args()
    experiment(args.sizes, args.rules, args.gap, args.mesh, args.detail)


if __name__ == "__main__":
    main()
