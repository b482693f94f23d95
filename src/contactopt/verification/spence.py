"""The rigid flat circular punch and the rigid paraboloid pressed with Coulomb friction into an
elastic half-space: the punch's stick radius c/a, and the monotonic frictional Hertz indentation
solved step by step (``indent``), the references for the FE's frictional Hertz figures
(docs/obstacles.md, "Friction").

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

The paraboloid (``indent``): the same kernels on uniform rings of the final contact radius, the
contact growing ring by ring, with the history (u_r of each step) carried from step to step; it
does not use the punch. Its checks: without friction Hertz; with friction the punch's c/a and
P = (4/3)E* k aδ, k the punch's P/(2aE*δ) (each increment is the punch's, dP = 2aE*k dδ, and
δ ∝ a² by self-similarity), bonded k = ln(3 − 4ν)/(2β).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.integrate import quad
from scipy.special import ellipe, ellipkm1

log = logging.getLogger(__name__)


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


def punch_load_ratio(system: PunchSystem, friction: float) -> float:
    """P/(2aE*δ) of the punch pressed with friction F, its stick disc out to ``stick_ratio``'s c_lo."""
    k = int(np.searchsorted(system.edges, stick_ratio(system, friction)[0]))
    p, _ = solve_punch(system, k, friction)
    return float(p @ system.area) / (2 * system.e_star)


@dataclass(frozen=True)
class Indentation:
    """The monotonic indentation by the paraboloid gap r²/(2R), one entry per step (contact radius
    ``a``, approach ``delta``, force ``load``, centre pressure ``p0``), and the last step's ring
    pressures ``p``, radial shears ``q`` (> 0 outward on the body) and ``stick`` (the rings whose u_r
    did not change in it); ``c`` the outer edge of its stick disc; ``min_gap`` the least gap
    w − (δ_k − r²/(2R)) over the rings outside the contact, in every step, over δ_k (≥ 0: the gap
    closes only inside the contact)."""

    system: PunchSystem
    friction: float
    radius: float
    a: np.ndarray
    delta: np.ndarray
    load: np.ndarray
    p0: np.ndarray
    p: np.ndarray
    q: np.ndarray
    stick: np.ndarray
    min_gap: float

    @property
    def c(self) -> float:
        k = int(np.argmin(self.stick)) if not self.stick.all() else self.stick.size
        return float(self.system.edges[k])

    def fitted(self) -> tuple[float, float]:
        """(a, p0) of p² = p0²(1 − r²/a²) fitted by least squares to the last step's ring pressures at
        the rings' middles, weighted by the rings' areas (as a mesh's nodes are spread over the face),
        the outermost ring left out: what a fit of a Hertz profile to a computed pressure reads."""
        m = int(np.searchsorted(self.system.edges, self.a[-1]))
        r = 0.5 * (self.system.edges[1:m] + self.system.edges[:m - 1])
        c = np.polyfit(r ** 2, self.p[:m - 1] ** 2, 1, w=np.sqrt(self.system.area[:m - 1]))
        return float(np.sqrt(-c[1] / c[0])), float(np.sqrt(c[1]))

    def hertz(self) -> dict:
        """Each of P, δ, p0 at the last step's a over the frictionless Hertz value at that a
        (P = 4E*a³/(3R), δ = a²/R, p0 = 2E*a/(πR)), and P/(aδ) over (4/3)E*."""
        a, R, E = self.a[-1], self.radius, self.system.e_star
        return {"P": self.load[-1] / (4 * E * a ** 3 / (3 * R)), "delta": self.delta[-1] / (a * a / R),
                "p0": self.p0[-1] / (2 * E * a / (np.pi * R)),
                "P/(a delta)": self.load[-1] / (a * self.delta[-1]) / (4 * E / 3)}


def _edge_ratio(edges: np.ndarray, m: int) -> float:
    """The mean of √(a² − r²) over ring m − 1 over that over ring m − 2, a = edges[m]: the pressure's
    square-root fall to zero at the contact's edge, with no 1/√ part (a smooth indenter's contact)."""
    a2 = edges[m] ** 2

    def mean(j):
        e0, e1 = edges[j], edges[j + 1]
        return ((a2 - e0 * e0) ** 1.5 - max(a2 - e1 * e1, 0.0) ** 1.5) / (e1 * e1 - e0 * e0)

    return mean(m - 1) / mean(m - 2)


def indent(system: PunchSystem, friction: float, radius: float = 1.0, rings_per_step: int = 1,
           max_sweeps: int = 100) -> Indentation:
    """The rigid paraboloid pressed monotonically with Coulomb friction F into the half-space, in steps
    of growing contact radius: step k has the rings below a_k = edges[m_k] in contact, m_k growing by
    ``rings_per_step``, and the approach δ_k an unknown fixed by the edge condition (``_edge_ratio``).

    Per step, on the contact rings (totals p, q; sign conventions of the module docstring):
    w = δ_k − r²/(2R); on a sticking ring u_r is that of the step before (no slip relative to the
    rigid indenter in the step); on a slipping ring q = s F p, s = +1 if the body's surface moved
    inward in the step (Δu_r < 0), −1 if outward. The rings' states are found by a fixed point per
    step (a stick ring whose |q| exceeds F p slips with the sense of q; a slip ring moving against
    its sense sticks), started from the step before, a ring entering the contact slipping inward.
    ``friction`` 0: frictionless (q = 0); ``np.inf``: bonded (every ring in contact sticks)."""
    if not friction >= 0 or rings_per_step < 1 or system.area.size < 2:
        raise ValueError(f"indent: friction {friction} must be ≥ 0, rings_per_step {rings_per_step} ≥ 1, "
                         f"and at least 2 rings ({system.area.size})")
    n, edges, mid = system.area.size, system.edges, 0.5 * (system.edges[1:] + system.edges[:-1])
    p_all, q_all = np.zeros(n), np.zeros(n)
    sense = np.ones(n)                       # +1 slip inward, −1 slip outward, 0 stick
    if np.isinf(friction):
        sense[:] = 0.0
    out = {"a": [], "delta": [], "load": [], "p0": []}
    ms = list(range(max(2, rings_per_step), n + 1, rings_per_step))
    if ms[-1] != n:
        ms.append(n)
    stick, min_gap = np.zeros(0, bool), np.inf
    for m in ms:
        u_old = system.C[:m] @ p_all + system.D[:m] @ q_all
        rho = _edge_ratio(edges, m)
        for _ in range(max_sweeps):
            M, rhs = np.zeros((2 * m + 1, 2 * m + 1)), np.zeros(2 * m + 1)
            M[:m, :m], M[:m, m:2 * m], M[:m, 2 * m] = system.A[:m, :m], system.B[:m, :m], -1.0
            rhs[:m] = -mid[:m] ** 2 / (2 * radius)
            st = sense[:m] == 0 if friction > 0 else np.zeros(m, bool)
            rows = m + np.flatnonzero(st)
            M[rows, :m], M[rows, m:2 * m], rhs[rows] = system.C[:m, :m][st], system.D[:m, :m][st], u_old[st]
            sl = np.flatnonzero(~st)
            M[m + sl, m + sl] = 1.0
            if friction > 0:
                M[m + sl, sl] = -sense[sl] * friction
            M[2 * m, m - 1], M[2 * m, m - 2] = 1.0, -rho
            x = np.linalg.solve(M, rhs)
            p, q = x[:m], x[m:2 * m]
            if friction == 0 or np.isinf(friction):
                break
            du = system.C[:m, :m] @ p + system.D[:m, :m] @ q - u_old
            tol = 1e-12 * (np.abs(u_old).max() + np.abs(du).max())
            new = sense[:m].copy()
            over = (sense[:m] == 0) & (np.abs(q) > friction * p * (1 + 1e-12))
            new[over] = np.sign(q[over])
            new[(sense[:m] != 0) & (sense[:m] * du > tol)] = 0.0
            if np.array_equal(new, sense[:m]):
                break
            sense[:m] = new
        else:
            log.warning("indent: the stick/slip states at a = %.4f did not settle in %d sweeps", edges[m], max_sweeps)
        if np.any(p < 0):
            log.warning("indent: a negative ring pressure at a = %.4f (%.2e)", edges[m], p.min())
        stick = sense[:m] == 0
        p_all[:m], q_all[:m] = p, q
        if m < n:
            gap = system.A[m:, :m] @ p + system.B[m:, :m] @ q - x[2 * m] + mid[m:] ** 2 / (2 * radius)
            min_gap = min(min_gap, float(gap.min()) / x[2 * m])
        out["a"].append(edges[m])
        out["delta"].append(x[2 * m])
        out["load"].append(float(p @ system.area[:m]))
        out["p0"].append(p[0])
    return Indentation(system, friction, radius, *(np.array(out[k]) for k in ("a", "delta", "load", "p0")),
                       p=p_all.copy(), q=q_all.copy(), stick=stick, min_gap=min_gap)
