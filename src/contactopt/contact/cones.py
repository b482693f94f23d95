"""Friction cones, their projections and the error measure of the local contact problem.

Convention (FCLIB / Siconos), used by every solver in :mod:`contactopt.contact`:
the unknowns are stacked contact by contact, each contact ordered (normal, tangent1, tangent2);
``u = W r + q``; the reaction lies in the Coulomb cone ``K_mu = {||r_T|| <= mu r_N}``; the
modified velocity ``u~ = u + mu ||u_T|| e_N`` lies in the dual cone ``K_mu* = {mu ||u_T|| <= u_N}``;
and ``r . u~ = 0``.  In the shape problem ``r`` is the contact force acting on the body and
``u`` is the displacement plus the initial gap in the normal component, so ``r_N`` is the
normal contact force ``lambda`` of the paper and ``r_T`` the friction force ``tau``.

The error measure is the one of Siconos 4.4,
``||r - P_K(r - u~)|| / max(||q||, ||r||, ||u||)``, which is zero exactly at solutions.
"""

from __future__ import annotations

import numpy as np

from .state import CLASS_NAMES, classify_nodes

__all__ = [
    "as_contacts",
    "project_cone",
    "project_tresca_set",
    "modified_velocity",
    "siconos_error",
    "complementarity_violations",
    "node_class",
]


def as_contacts(x: np.ndarray) -> np.ndarray:
    """View a stacked vector of length ``3p`` as a ``(p, 3)`` array (normal, t1, t2)."""
    x = np.asarray(x)
    if x.ndim != 1 or x.size % 3:
        raise ValueError(f"expected a vector of length 3p, got shape {x.shape}")
    return x.reshape(-1, 3)


def project_cone(x: np.ndarray, mu) -> np.ndarray:
    """Euclidean projection of a stacked vector onto the product of cones ``K_mu``.

    ``mu`` is a scalar or one coefficient per contact; ``mu = 0`` gives the half-line
    ``{r_T = 0, r_N >= 0}`` (frictionless contact).
    """
    X = as_contacts(np.asarray(x, dtype=float))
    mu = np.broadcast_to(np.asarray(mu, dtype=float), (X.shape[0],))
    xn = X[:, 0]
    xt = X[:, 1:]
    nt = np.hypot(xt[:, 0], xt[:, 1])
    # x_N >= 0 too: with mu = 0 the cone is the half-line, and a point (x_N < 0, x_T = 0) lies in
    # its polar cone (it projects to 0), not in the cone
    inside = (nt <= mu * xn) & (xn >= 0.0)
    polar = mu * nt <= -xn
    # On the boundary part: a = (x_N + mu ||x_T||) / (1 + mu^2), result (a, mu a x_T/||x_T||).
    a = (xn + mu * nt) / (1.0 + mu * mu)
    safe = np.where(nt > 0, nt, 1.0)
    out = np.empty_like(X)
    out[:, 0] = a
    out[:, 1:] = (mu * a / safe)[:, None] * xt
    out[inside] = X[inside]
    out[polar & ~inside] = 0.0
    return out.reshape(-1)


def project_tresca_set(x: np.ndarray, g) -> np.ndarray:
    """Projection onto ``{r_N >= 0, ||r_T|| <= g}`` (Tresca: cylinder of radius ``g``)."""
    X = as_contacts(np.asarray(x, dtype=float))
    g = np.broadcast_to(np.asarray(g, dtype=float), (X.shape[0],))
    out = np.empty_like(X)
    out[:, 0] = np.maximum(X[:, 0], 0.0)
    nt = np.hypot(X[:, 1], X[:, 2])
    scale = np.where(nt > g, g / np.where(nt > 0, nt, 1.0), 1.0)
    out[:, 1:] = X[:, 1:] * scale[:, None]
    return out.reshape(-1)


def modified_velocity(u: np.ndarray, mu) -> np.ndarray:
    """De Saxcé's modified velocity ``u~ = u + mu ||u_T|| e_N``."""
    U = as_contacts(np.asarray(u, dtype=float)).copy()
    U[:, 0] += np.asarray(mu, dtype=float) * np.hypot(U[:, 1], U[:, 2])
    return U.reshape(-1)


def siconos_error(r: np.ndarray, u: np.ndarray, q: np.ndarray, mu) -> float:
    """Relative error ``||r - P_K(r - u~)|| / max(||q||, ||r||, ||u||)`` (Siconos 4.4).

    Returns the absolute value when all three norms vanish (the trivial problem ``q = 0``).
    """
    r = np.asarray(r, dtype=float)
    res = r - project_cone(r - modified_velocity(u, mu), mu)
    num = float(np.linalg.norm(res))
    den = max(float(np.linalg.norm(q)), float(np.linalg.norm(r)), float(np.linalg.norm(u)))
    return num / den if den > 0 else num


def complementarity_violations(r: np.ndarray, u: np.ndarray, mu) -> dict[str, float]:
    """Absolute violation of each Coulomb condition (all zero at an exact solution).

    Keys: ``r_N>=0``, ``u_N>=0``, ``r_N*u_N``, ``cone`` (``||r_T|| - mu r_N``), ``stick``
    (``(mu r_N - ||r_T||) ||u_T||``: strict sticking forces ``u_T = 0``) and ``slip``
    (``|| ||u_T|| r_T + mu r_N u_T ||``: sliding forces ``r_T = -mu r_N u_T/||u_T||``). The
    two last ones are written as products so that they stay meaningful when ``u_T -> 0``.
    """
    R = as_contacts(np.asarray(r, dtype=float))
    U = as_contacts(np.asarray(u, dtype=float))
    mu = np.broadcast_to(np.asarray(mu, dtype=float), (R.shape[0],))
    rt = np.hypot(R[:, 1], R[:, 2])
    ut = np.hypot(U[:, 1], U[:, 2])
    slip = ut[:, None] * R[:, 1:] + (mu * R[:, 0])[:, None] * U[:, 1:]

    def worst(v):
        return float(np.max(v, initial=0.0))

    return {
        "r_N>=0": worst(-R[:, 0]),
        "u_N>=0": worst(-U[:, 0]),
        "r_N*u_N": worst(np.abs(R[:, 0] * U[:, 0])),
        "cone": worst(rt - mu * R[:, 0]),
        "stick": worst(np.abs((mu * R[:, 0] - rt) * ut)),
        "slip": worst(np.hypot(slip[:, 0], slip[:, 1])),
    }


def node_class(r: np.ndarray, u: np.ndarray, mu, *, rtol: float = 1e-8) -> np.ndarray:
    """Classify every contact as in Table 4.1 of the paper.

    Returns an array of strings: ``"L"`` no contact, ``"M1"`` sliding with contact, ``"M2"``
    sliding with weak contact, ``"M3+"`` (strong) sticking, ``"M3-"`` weak sticking, ``"M4"``
    weak sticking with weak contact. "Weak" means that both members of a complementarity pair
    vanish up to ``rtol`` times the largest entry of ``r`` (forces) or ``u`` (displacements).
    """
    R = as_contacts(np.asarray(r, dtype=float))
    U = as_contacts(np.asarray(u, dtype=float))
    mu = np.broadcast_to(np.asarray(mu, dtype=float), (R.shape[0],))
    # local u_N already contains the gap: hand the state classifier (u_T, u_N) with zero gap
    u_c = np.column_stack([U[:, 1], U[:, 2], U[:, 0]])
    codes = classify_nodes(u_c, R[:, 0], -R[:, 1:], np.zeros(R.shape[0]), mu, rtol=rtol,
                           force_scale=max(float(np.abs(R).max(initial=0.0)), np.finfo(float).tiny))
    return np.array(CLASS_NAMES)[codes]
