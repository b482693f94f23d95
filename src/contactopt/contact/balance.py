"""Can contact hold a body? The loads on the free rigid motions against the admissible contact forces.

A body held only by contact (:mod:`contactopt.mesh.rigid`) is in equilibrium only if contact forces
admissible on the contact face (per node λ ≥ 0 along the obstacle's normal, |τ| ≤ Fλ) balance the
load on every free rigid motion: −Rᵀf ∈ K = {Σ_m G_mᵀ r_m : r_m in node m's friction cone}, G_m the
motions at node m. Otherwise there is a motion y with yᵀk ≥ 0 for every k ∈ K (no admissible
contact force resists it) along which the load does positive work, fᵀR y > 0: the body would
move off, or slide. That y is found by a linear program (scipy's HiGHS) over the friction cones
replaced by circumscribed 64-gons, a superset: a refusal is never wrong, and a load closer to the
friction limit than 0.12 % passes on to the solver. A motion that the contact cannot resist at
all (frictionless contact and a motion with no normal component at any contact node) cannot be
held by any load either.

With a force-controlled obstacle the contact forces have a prescribed resultant along its force as
well; a load that, with it, no admissible contact force balances on the free motions (for example
no load at all on a body that nothing but the contact holds along the obstacle's force) is refused
too: "the load has a component along a rigid motion that nothing holds: the translation along x3 …".

The message names the motion. On a flat contact face (every contact normal the same n) the
translations are named by the resultants: the normal load N = −P·n (P the load's resultant), the
tangential load T = |P − (P·n)n| against F·N.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

from ..errors import ConfigError
from ..mesh.rigid import AXES, mode_name

SIDES = 64


def check_held(rigid, points, contact_nodes, frames, friction, loads: list, source: str,
               obstacle_force=None) -> None:
    """ConfigError naming the first free rigid motion of ``rigid`` that no admissible contact
    force holds, for the load vectors ``loads`` (full length 3n, named: [(name, f)]); ``friction``
    F, a scalar or (p,) per contact node (each node's cone its own).

    ``obstacle_force``: a force-controlled obstacle's (``contactopt.fem.model.ObstacleForce``: its
    magnitude |f| and b_m = R_mᵀ f̂ per node frame (t1, t2, n)): the contact forces then also have
    the resultant Σ_m b_m·r_m = |f| along f̂, and a load that does not balance it along a free
    motion is refused by name (:func:`_check_force`)."""
    k = rigid.count
    p = contact_nodes.size
    R = np.broadcast_to(np.eye(3), (p, 3, 3)) if frames is None else frames        # columns (t1, t2, n)
    V = rigid.vectors(points)                                                    # (n, 3, k)
    G = np.einsum("mij,mik->mjk", R, V[contact_nodes])                          # (p, 3, k) per node frame
    scale = np.linalg.norm(V.reshape(-1, k), axis=0)
    mu = np.asarray(friction, dtype=float)
    mu = np.broadcast_to(mu[:p] if mu.ndim else mu, (p,))     # (rows of faces on other bodies follow: fem.faces)
    if np.any(mu > 0):       # per node the polygon's generators (all at the node's normal where F_m = 0)
        th = 2 * np.pi * np.arange(SIDES) / SIDES
        Fo = mu[:, None] / np.cos(np.pi / SIDES)
        gen = np.stack([Fo * np.cos(th), Fo * np.sin(th), np.ones((p, SIDES))], axis=2)
    else:
        gen = np.broadcast_to([[[0.0, 0.0, 1.0]]], (p, 1, 3))
    work = np.einsum("mjc,mck->mjk", gen, G).reshape(-1, k) / scale            # generator j at node m on y
    normal = G[:, 2, :] / scale
    if not np.any(mu > 0):
        _, s, Vt = np.linalg.svd(normal, full_matrices=True)
        rank = int(np.sum(s > 1e-9 * max(s.max(initial=0.0), 1e-300)))
        if rank < k:
            names = " and ".join(sorted((_named(rigid, y / scale, points) for y in Vt[rank:]),
                                        key=lambda n: ("rotation" in n, n)))
            one = k - rank == 1
            raise ConfigError([f"{source}: body.clamped: {names} {'is' if one else 'are'} not held: without "
                               f"friction the contact forces (along the obstacle's normals) have no component "
                               f"along {'it' if one else 'them'}; clamp {'it' if one else 'them'}, or give "
                               "friction.coefficient > 0"])
    for name, f in loads:
        b = V.reshape(-1, k).T @ np.asarray(f, float) / scale                  # the load's work on y
        if obstacle_force is not None:
            _check_force(rigid, points, R, gen, work, b, f, obstacle_force, f"{source}: {name}")
            continue
        if not np.any(b):
            continue
        res = linprog(-b, A_ub=-work, b_ub=np.zeros(work.shape[0]), bounds=[(-1.0, 1.0)] * k, method="highs")
        if res.status != 0 or -res.fun <= 1e-9 * np.abs(b).sum():
            continue
        y = res.x / scale
        raise ConfigError([f"{source}: {name}: " + _message(rigid, y, points, contact_nodes, R, f, friction)])


def _check_force(rigid, points, R, gen, work, b, f, force, where: str) -> None:
    """ConfigError when no admissible contact forces (generator weights w ≥ 0 of the cones'
    polygons, a superset: a refusal is never wrong) both balance the load on the free motions
    (Σ w_j work_j = −b) and have the force-controlled obstacle's resultant Σ_m b_m·r_m = |f|:
    then the load has a component along a rigid motion that nothing holds."""
    along = np.einsum("mjc,mc->mj", gen, np.asarray(force.b, float)).ravel() / force.magnitude
    res = linprog(np.zeros(work.shape[0]), A_eq=np.vstack([work.T, along]), b_eq=np.r_[-b, 1.0],
                  bounds=(0, None), method="highs")
    if res.status != 2:                    # feasible (or undecided): the solver goes on
        return
    P = np.asarray(f, float).reshape(-1, 3).sum(axis=0)
    fhat = R[0] @ np.asarray(force.b, float)[0]                                 # f̂ in the world frame
    free_t = _free_translations(rigid)
    if free_t.size and np.linalg.norm(free_t.T @ fhat) >= 1 - 1e-9:
        along_f = float(P @ fhat)
        raise ConfigError([f"{where}: the load has a component along a rigid motion that nothing holds: the "
                           f"translation along {_axis(fhat)} — the force-controlled obstacle pushes the body by "
                           f"{force.magnitude:.6g} along {_axis(fhat)}, the load's resultant along it is {along_f:.6g} "
                           f"(it would have to be {-force.magnitude:.6g}) and no clamp takes the difference; clamp the "
                           f"body along {_axis(fhat)} (body.clamped) or load it against the obstacle's force"])
    names = ", ".join(rigid.names())
    raise ConfigError([f"{where}: the load has a component along a rigid motion that nothing holds: with the "
                       f"force-controlled obstacle's {force.magnitude:.6g} along {_axis(fhat)}, no contact force "
                       f"admissible on the contact face balances the load's resultant {_fmt(P)} on the free motions "
                       f"({names}); clamp them (body.clamped) or change the loads"])


def _named(rigid, y, points) -> str:
    """The name of the canonical motion dominant in y (coefficients of ``rigid``), or of y itself."""
    c = rigid.coefficients @ y
    size = max(np.ptp(points, axis=0).max(), 1e-300)
    w = np.abs(c) * np.r_[np.ones(3), size * np.ones(3)]
    k = int(np.argmax(w))
    if w[k] >= 0.999 * np.linalg.norm(w):
        return mode_name(np.eye(6)[k] * np.sign(c[k]), rigid.centroid).replace("−", "")
    return mode_name(c, rigid.centroid)


def _message(rigid, y, points, contact_nodes, R, f, friction) -> str:
    """Why the motion y is not held (module docstring); with F per node the largest is named."""
    n = R[:, :, 2]
    uniform = np.ndim(friction) == 0
    friction = float(np.max(friction))
    P = np.asarray(f, float).reshape(-1, 3).sum(axis=0)
    free_t = _free_translations(rigid)
    if np.allclose(n, n[0], atol=1e-12) and free_t.size:
        nn = n[0]
        N = -float(P @ nn)
        if np.linalg.norm(free_t.T @ nn) > 1e-9 and N <= 0:
            return (f"the translation along {_axis(nn)} is not held: the load pulls the body away from the obstacle "
                    f"(its resultant along {_axis(nn)} is {-N:.6g} ≥ 0, away from the contact face)")
        Pt = P - (P @ nn) * nn
        Pt_free = free_t @ (free_t.T @ Pt)
        T = float(np.linalg.norm(Pt_free))
        if T > friction * N and T > 1e-12 * np.linalg.norm(P):
            return (f"the translation along {_axis(Pt_free)} is not held: the tangential load {T:.6g} exceeds "
                    f"{'' if uniform else 'the largest '}F × the normal load {friction:g} × {N:.6g} = "
                    f"{friction * N:.6g}")
    name = _named(rigid, y, points)
    return (f"{name} is not held: no contact force admissible on the contact face (λ ≥ 0, |τ| ≤ Fλ, "
            f"F {'=' if uniform else '≤'} {friction:g}) balances the load along it (the load's resultant {_fmt(P)} and its moment "
            "cannot both be taken by the contact face)")


def _free_translations(rigid) -> np.ndarray:
    """(3, j): an orthonormal basis of the translations among the free motions."""
    C = rigid.coefficients
    T = [C[:3, i] for i in range(C.shape[1]) if np.allclose(C[3:, i], 0.0)]
    if not T:
        return np.zeros((3, 0))
    Q, s, _ = np.linalg.svd(np.array(T).T, full_matrices=False)
    return Q[:, s > 1e-9]


def _axis(v) -> str:
    v = np.asarray(v, float) / np.linalg.norm(v)
    k = int(np.argmax(np.abs(v)))
    return AXES[k] if abs(abs(v[k]) - 1) <= 1e-9 else "(" + ", ".join(f"{x:.4g}" for x in v) + ")"


def _fmt(x) -> str:
    return "(" + ", ".join(f"{v:.4g}" for v in np.asarray(x)) + ")"
