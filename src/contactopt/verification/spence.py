"""The rigid flat circular punch pressed with Coulomb friction into an elastic half-space: its stick
radius c/a, the reference for the monotonic frictional Hertz indentation (docs/obstacles.md,
"Friction").

An increment of the Hertz indentation at contact radius a is this punch's problem (the pressure's
increment is the flat punch's, a point of the slip annulus has slipped since it entered the contact),
so the monotonic Hertz stick ratio is the punch's, a function of β/F alone, β = (1 − 2ν)/(2(1 − ν))
(Spence's self-similar solution). Here it is computed from the half-space's axisymmetric surface
integral equations, not quoted.

Conventions: radius a = 1, E = 1; p ≥ 0 the pressure (pushing into the body), q the radial shear on
the body (> 0 outward), w the surface displacement into the body, u_r the radial one. With
κ = (1 − 2ν)(1 + ν)/E, from Boussinesq's and Cerruti's point-load solutions integrated over rings
(the θ-integrals in complete elliptic integrals of m = 4rρ/(r + ρ)²; the ν x_α x_β/ρ³ part of
Cerruti's kernel integrates to zero over a ring of radial shear):

    w(r)   = (1 − ν²)/(πE) ∫ p(ρ) 4ρ K(m)/(r + ρ) dρ − κ ∫_r^1 q(ρ) dρ,
    u_r(r) = −κ/r ∫_0^r p(ρ) ρ dρ + (1 − ν²)/(πE) ∫ q(ρ) [(r² + ρ²) 4K(m)/(r + ρ) − 4(r + ρ)E(m)]/(2r) dρ.

The punch: w = δ on r < 1; u_r = 0 on the stick disc r < c; q = F p on the slip annulus c < r < 1
(the body slides inward, u_r < 0, for ν < 1/2). Piecewise-constant p, q on n rings clustered at the
rim (ρ_j = sin(πj/2n)), collocation at the rings' middles. c is the largest ring edge at which the
stick disc's shear stays in the cone, |q| ≤ F p. Checks: without friction P = 2aE*δ; fully bonded
P = 2aE*δ ln(3 − 4ν)/(2β) (Mossakovskii).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PunchSystem:
    """The collocation matrices of one ν and n: ``A`` (w from p), ``B`` (w from q), ``C`` (u_r from
    p), ``D`` (u_r from q), each (n, n); ``edges`` (n + 1) and ``area`` (n) of the rings."""

    nu: float
    edges: np.ndarray
    area: np.ndarray
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray

    @property
    def beta(self) -> float:
        return (1 - 2 * self.nu) / (2 * (1 - self.nu))

    @property
    def e_star(self) -> float:
        return 1.0 / (1 - self.nu ** 2)


def punch_system(nu: float, n: int = 120) -> PunchSystem:
    """The punch's rings, clustered at the rim where its pressure is singular (ρ_j = sin(πj/2n))."""
    return ring_system(nu, np.sin(0.5 * np.pi * np.arange(n + 1) / n))


def ring_system(nu: float, edges: np.ndarray) -> PunchSystem:
    """The ring integrals of the kernels (module docstring) on the rings between ``edges`` (0 = edges[0]
    < … < edges[-1] = 1), collocated at the rings' middles, by adaptive quadrature split at the
    collocation point (the kernels' logarithmic singularity)."""
    from scipy.integrate import quad
    from scipy.special import ellipe, ellipkm1

    c0, kappa = (1 - nu ** 2) / np.pi, (1 - 2 * nu) * (1 + nu)

    def k_w(r, rho):            # w from a unit pressure ring
        m1 = ((r - rho) / (r + rho)) ** 2          # 1 − m, without cancellation
        return c0 * 4 * rho * ellipkm1(m1) / (r + rho)

    def k_u(r, rho):            # u_r from a unit radial-shear ring
        m1 = ((r - rho) / (r + rho)) ** 2
        return c0 * ((r * r + rho * rho) * 4 * ellipkm1(m1) / (r + rho) - 4 * (r + rho) * ellipe(1 - m1)) / (2 * r)

    def ring(k, r, lo, hi):
        return quad(lambda x: k(r, x), lo, hi, points=[r] if lo < r < hi else None, limit=200,
                    epsabs=1e-14, epsrel=1e-11)[0]

    edges = np.asarray(edges, dtype=float)
    mid = 0.5 * (edges[1:] + edges[:-1])
    lo, hi = edges[:-1], edges[1:]
    A = np.array([[ring(k_w, r, a, b) for a, b in zip(lo, hi)] for r in mid])
    D = np.array([[ring(k_u, r, a, b) for a, b in zip(lo, hi)] for r in mid])
    r = mid[:, None]
    C = -kappa * (np.minimum(r, hi) ** 2 - np.minimum(r, lo) ** 2) / (2 * r)
    B = -kappa * (np.maximum(r, hi) - np.maximum(r, lo))
    return PunchSystem(nu, edges, np.pi * (hi ** 2 - lo ** 2), A, B, C, D)


def solve_punch(system: PunchSystem, n_stick: int, friction: float | None) -> tuple:
    """(p, q) at δ = 1 with the first ``n_stick`` rings sticking (u_r = 0) and the others sliding,
    q = F p; ``friction`` None: the frictionless punch (q = 0)."""
    n = system.area.size
    M, rhs = np.zeros((2 * n, 2 * n)), np.zeros(2 * n)
    M[:n, :n], M[:n, n:], rhs[:n] = system.A, system.B, 1.0
    for i in range(n):
        if friction is not None and i < n_stick:
            M[n + i, :n], M[n + i, n:] = system.C[i], system.D[i]
        else:
            M[n + i, n + i] = 1.0
            if friction is not None:
                M[n + i, i] = -friction
    x = np.linalg.solve(M, rhs)
    return x[:n], x[n:]


def load_ratio(system: PunchSystem, bonded: bool) -> float:
    """P/(2aE*δ) of the frictionless (``bonded`` False) or the fully bonded punch."""
    p, _ = solve_punch(system, system.area.size, np.inf) if bonded else solve_punch(system, 0, None)
    return float(p @ system.area) / (2 * system.e_star)


def stick_ratio(system: PunchSystem, friction: float) -> tuple[float, float]:
    """(c_lo, c_hi): the ring edges between which the stick radius c/a lies (module docstring):
    with the stick disc out to c_lo the shear stays within F p, out to c_hi it does not."""
    n = system.area.size
    inside = []
    for k in range(1, n):
        p, q = solve_punch(system, k, friction)
        inside.append(np.all(np.abs(q[:k]) <= friction * p[:k]))
    k = max((j + 1 for j, ok in enumerate(inside) if ok), default=0)
    return float(system.edges[k]), float(system.edges[min(k + 1, n)])
