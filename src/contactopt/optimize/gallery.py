"""A gallery of nonsmooth test problems for the optimizers of ``contactopt.optimize``.

Like ``pyamg.gallery`` or ``scipy.optimize``'s test functions, the problems are built when
asked for, not when the module is imported:

* ``PROBLEMS`` — the collection of L. Lukšan, J. Vlček, *Test problems for nonsmooth
  unconstrained and linearly constrained optimization*, Technical report 798, ICS AS CR,
  Prague, 2000: its unconstrained problems 1–25 (``group == "unconstrained"``; TR48, problem
  21, is left out: its data are not part of the formulas) and its linearly constrained problems
  1–15 (``"linearly constrained"``), each with the report's starting point, and f* the best
  value the authors' codes reach (the published runs of ACM TOMS Algorithm 811), ``number``
  the problem's number in its chapter; :func:`get_problem` and :func:`problem_names` look
  them up.
* ``CONSTRAINED`` — problems min f(x) over U ∩ {c(x) ≤ 0} with nonlinear, nonsmooth
  constraints, for :func:`~contactopt.optimize.constrained.minimize_constrained`
  (:class:`ConstrainedProblem`).
* Families with a parameter: :func:`goffin_problem` (a maximum of n linear functions),
  :func:`max_linear_problem` (a polyhedral f with a known sharp minimum),
  :func:`max_quadratics_problem` over :func:`paper_admissible_set` (a design set with the
  structure of U in Beremlijski et al. 2009) and its reference optimum
  :func:`max_quadratics_reference`.

Every problem is a :class:`NonsmoothProblem`: calling it returns ``(f, g)`` with ``g`` one
Clarke subgradient (for a maximum the gradient of the first active piece, for ``|h|`` the
vector ``sign(h)·∇h`` with ``sign(0) = +1``, as the reference code chooses).  The linear
constraints use the keyword names of :func:`contactopt.optimize.minimize_bundle`
(``lb``, ``ub``, ``A_ub x <= b_ub``, ``A_eq x == b_eq``), see :meth:`NonsmoothProblem.constraints`.

Examples
--------
>>> from contactopt.optimize import minimize_bundle
>>> from contactopt.optimize.gallery import get_problem
>>> prob = get_problem("CB2")
>>> res = minimize_bundle(prob, prob.x0, **prob.constraints())
>>> bool(res.success), abs(res.fun - prob.f_star) < 1e-6 * max(1.0, abs(prob.f_star))
(True, True)
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["NonsmoothProblem", "ConstrainedProblem", "PROBLEMS", "CONSTRAINED", "get_problem",
           "problem_names", "paper_admissible_set", "max_quadratics_problem", "max_quadratics_reference",
           "goffin_problem", "max_linear_problem"]


@dataclass(frozen=True)
class NonsmoothProblem:
    """One test problem: ``oracle(x) -> (f, g)``, start ``x0``, optimal value ``f_star``."""

    name: str
    oracle: Callable[[np.ndarray], tuple[float, np.ndarray]] = field(repr=False)
    x0: np.ndarray = field(repr=False)
    f_star: float | None  # None when not tabulated (computed by the caller)
    f_x0: float | None    # f(x0) as tabulated in the report (checks the formula)
    convex: bool
    lb: np.ndarray | None = field(default=None, repr=False)
    ub: np.ndarray | None = field(default=None, repr=False)
    A_ub: np.ndarray | None = field(default=None, repr=False)
    b_ub: np.ndarray | None = field(default=None, repr=False)
    A_eq: np.ndarray | None = field(default=None, repr=False)
    b_eq: np.ndarray | None = field(default=None, repr=False)
    data: dict | None = field(default=None, repr=False)  # problem data, e.g. the quadratics
    number: int = 0       # the problem's number in its chapter of the report
    group: str = ""       # "unconstrained" or "linearly constrained" (the report's chapters)

    @property
    def n(self) -> int:
        return self.x0.size

    def __call__(self, x):
        f, g = self.oracle(np.asarray(x, dtype=float))
        return float(f), np.asarray(g, dtype=float)

    def constraints(self) -> dict:
        """Keyword arguments of the feasible set for ``minimize_bundle``."""
        names = ("lb", "ub", "A_ub", "b_ub", "A_eq", "b_eq")
        return {k: getattr(self, k) for k in names if getattr(self, k) is not None}

    def max_violation(self, x) -> float:
        """Largest violation of a constraint at ``x`` (0 when feasible)."""
        x = np.asarray(x, dtype=float)
        v = 0.0
        if self.lb is not None:
            v = max(v, float(np.max(self.lb - x, initial=0.0)))
        if self.ub is not None:
            v = max(v, float(np.max(x - self.ub, initial=0.0)))
        if self.A_ub is not None:
            v = max(v, float(np.max(self.A_ub @ x - self.b_ub, initial=0.0)))
        if self.A_eq is not None:
            v = max(v, float(np.max(np.abs(self.A_eq @ x - self.b_eq), initial=0.0)))
        return v


# The functions below take z of shape (..., n), real or complex, and the real point x at which
# every branch (sign of an absolute value, active piece of a maximum) is decided: f(x) is
# fun(x, x) and the subgradient of that branch is the complex-step derivative
# Im fun(x + ih e_k, x)/h, exact to round-off for the analytic pieces.
_H = 1e-30


def _cs_grad(fun, x):
    z = x[None, :] + 1j * _H * np.eye(x.size)
    return np.asarray(fun(z, x)).imag / _H


def _smooth_branch(fun):
    """oracle(x) = (fun(x, x), its complex-step gradient on the branch chosen at x)."""
    def oracle(x):
        return float(np.real(fun(x, x))), _cs_grad(fun, x)
    return oracle


def _first_max(v):
    """Index of the first maximiser (the reference code's choice on ties)."""
    return int(np.argmax(v))


def _minimax(pieces, absolute=False):
    """f = max_i p_i (or max_i |p_i|, sign + at 0); g = ± gradient of the first maximiser."""
    def oracle(x):
        p = np.real(pieces(x))
        vals = np.abs(p) if absolute else p
        k = _first_max(vals)
        sign = -1.0 if absolute and p[k] < 0 else 1.0
        z = x[None, :] + 1j * _H * np.eye(x.size)
        g = sign * np.asarray(pieces(z))[:, k].imag / _H
        return float(vals[k]), g
    return oracle


def _sg(v):
    """sign with sign(0) = +1 (Fortran SIGN(1, v))."""
    return 1.0 if v >= 0 else -1.0


def _c(z, i):
    return z[..., i - 1]


# ---------------------------------------------------------------- unconstrained (report ch. 2)
def _rosenbrock(z, x):
    return 100 * (_c(z, 2) - _c(z, 1) ** 2) ** 2 + (1 - _c(z, 1)) ** 2


def _crescent(z, x):
    def t(u):
        return _c(u, 1) ** 2 + (_c(u, 2) - 1) ** 2 - 1
    return _c(z, 2) + _sg(t(x)) * t(z)


def _cb2_pieces(z):
    x1, x2 = _c(z, 1), _c(z, 2)
    return np.stack([x1**2 + x2**4, (2 - x1) ** 2 + (2 - x2) ** 2, 2 * np.exp(-x1 + x2)], -1)


def _cb3_pieces(z):
    x1, x2 = _c(z, 1), _c(z, 2)
    return np.stack([x1**4 + x2**2, (2 - x1) ** 2 + (2 - x2) ** 2, 2 * np.exp(-x1 + x2)], -1)


def _dem_pieces(z):
    x1, x2 = _c(z, 1), _c(z, 2)
    return np.stack([5 * x1 + x2, -5 * x1 + x2, x1**2 + x2**2 + 4 * x2], -1)


def _ql_pieces(z):
    x1, x2 = _c(z, 1), _c(z, 2)
    q = x1**2 + x2**2
    return np.stack([q, q + 10 * (-4 * x1 - x2 + 4), q + 10 * (-x1 - 2 * x2 + 6)], -1)


def _lq_pieces(z):
    x1, x2 = _c(z, 1), _c(z, 2)
    return np.stack([-x1 - x2, -x1 - x2 + x1**2 + x2**2 - 1], -1)


def _mifflin1_pieces(z):
    x1, x2 = _c(z, 1), _c(z, 2)
    return np.stack([20 * (x1**2 + x2**2 - 1) - x1, -x1 + 0 * x2], -1)


def _mifflin2(z, x):
    def t(u):
        return _c(u, 1) ** 2 + _c(u, 2) ** 2 - 1
    return -_c(z, 1) + 2 * t(z) + 1.75 * _sg(t(x)) * t(z)


def _wolfe(z, x):
    x1, x2 = _c(z, 1), _c(z, 2)
    if x[0] > abs(x[1]):
        return 5 * np.sqrt(9 * x1**2 + 16 * x2**2)
    s = _sg(x[1]) if x[1] != 0 else 1.0
    val = 9 * x1 + 16 * s * x2
    return val - x1**9 if x[0] <= 0 else val


def _rosen_suzuki_pieces(z):
    x1, x2, x3, x4 = (_c(z, i) for i in range(1, 5))
    q = x1**2 + x2**2 + x3**2
    f1 = q + x3**2 + x4**2 - 5 * (x1 + x2) - 21 * x3 + 7 * x4
    f2 = q + x4**2 + x1 - x2 + x3 - x4 - 8
    f3 = q + x2**2 + 2 * x4**2 - x1 - x4 - 10
    f4 = q + 2 * x1 - x2 - x4 - 5
    return np.stack([f1, f1 + 10 * f2, f1 + 10 * f3, f1 + 10 * f4], -1)


_SHOR_A = np.array([[0, 0, 0, 0, 0], [2, 1, 1, 1, 3], [1, 2, 1, 1, 2], [1, 4, 1, 2, 2],
                    [3, 2, 1, 0, 1], [0, 2, 1, 0, 1], [1, 1, 1, 1, 1], [1, 0, 1, 2, 1],
                    [0, 0, 2, 1, 0], [1, 1, 2, 0, 0]], dtype=float)
_SHOR_B = np.array([1, 5, 10, 2, 4, 3, 1.7, 2.5, 6, 3.5])


def _shor_pieces(z):
    r = z[..., None, :] - _SHOR_A
    return _SHOR_B * np.sum(r * r, axis=-1)


def _colville_data():
    """Colville's first problem (and Shell Dual): A (10x5), b (10), C (5x5), d (5), e (5)."""
    cc = np.array([
        -16, 0, 0, 0, 0, 2, -1, -1, 1, 1, 2, -2, 0, -2, -9, 0, -1, -2, 2, 1, 0, 0, 2, 0, -2, -4,
        -1, -3, 3, 1, 1, 4, 0, -4, 1, 0, -1, -2, 4, 1, 0, 2, 0, -1, 0, 0, -1, -1, 5, 1, -40,
        -2, 0, -4, -4, -1, -40, -60, 5, 1, 30, -20, -10, 32, -10, -20, 39, -6, -31, 32,
        -10, -6, 10, -6, -10, 32, -31, -6, 39, -20, -10, 32, -10, -20, 30, 4, 8, 10, 6,
        2, -15, -27, -36, -18, -12], dtype=float)
    cc[2], cc[44], cc[52] = -3.5, -2.8, -0.25
    return cc[:50].reshape(5, 10).T, cc[50:60], cc[60:85].reshape(5, 5), cc[85:90], cc[90:95]


_CV_A, _CV_B, _CV_C, _CV_D, _CV_E = _colville_data()


def _colville1(z, x):
    xs = z[..., :5]
    tv = _CV_B - _CV_A @ x[:5]
    k = _first_max(np.r_[0.0, tv])
    pen = 0.0 if k == 0 else 50 * (_CV_B[k - 1] - xs @ _CV_A[k - 1])
    quad = np.sum((xs @ _CV_C.T) * xs, axis=-1)
    return pen + np.sum(_CV_D * xs**3 + _CV_E * xs, axis=-1) + quad


def _shell_dual(z, x):
    u, w = z[..., :5], z[..., 5:15]
    f1 = np.sum(_CV_D * x[:5] ** 3)
    val = _sg(f1) * 2 * np.sum(_CV_D * u**3, axis=-1)
    val = val + np.sum((u @ _CV_C.T) * u, axis=-1) - w @ _CV_B
    tx = -3 * _CV_D * x[:5] ** 2 - _CV_E - 2 * _CV_C @ x[:5] + _CV_A.T @ x[5:15]
    tz = -3 * _CV_D * u**2 - _CV_E - 2 * (u @ _CV_C.T) + w @ _CV_A
    val = val + 100 * np.sum(tz[..., tx > 0], axis=-1)
    return val - 100 * np.sum(z[..., x < 0], axis=-1)


def _hs78(z, x):
    x1, x2, x3, x4, x5 = (_c(z, i) for i in range(1, 6))

    def h(u):
        v = [_c(u, i) for i in range(1, 6)]
        return (sum(t**2 for t in v) - 10, v[1] * v[2] - 5 * v[3] * v[4], v[0] ** 3 + v[1] ** 3 + 1)
    signs = [1.0 if hv >= 0 else -1.0 for hv in h(x)]
    return x1 * x2 * x3 * x4 * x5 + 10 * sum(s * hz for s, hz in zip(signs, h(z)))


_EA_T = np.arange(51) / 10.0
_EA_Y = (0.5 * np.exp(-_EA_T) - np.exp(-2 * _EA_T) + 0.5 * np.exp(-3 * _EA_T)
         + 1.5 * np.exp(-1.5 * _EA_T) * np.sin(7 * _EA_T) + np.exp(-2.5 * _EA_T) * np.sin(5 * _EA_T))


def _el_attar(z, x):
    def r(u):
        t = _EA_T
        c = [u[..., i, None] for i in range(6)]
        return c[0] * np.exp(-c[1] * t) * np.cos(c[2] * t + c[3]) + c[4] * np.exp(-c[5] * t) - _EA_Y
    s = np.where(np.real(r(x)) >= 0, 1.0, -1.0)
    return np.sum(s * r(z), axis=-1)


def _maxquad_data():
    """Maxquad: f = max_k xᵀA_k x − b_kᵀx, k = 1..5, n = 10 (A_k symmetric, diagonally dominant)."""
    n = 10
    i = np.arange(1, n + 1, dtype=float)
    A, B = np.zeros((5, n, n)), np.zeros((5, n))
    for k in range(1, 6):
        M = np.exp(i[:, None] / i[None, :]) * np.cos(i[:, None] * i[None, :]) * np.sin(k)
        M = np.triu(M) + np.triu(M, 1).T           # the formula for i <= j, mirrored
        off = np.abs(M).sum(axis=1) - np.abs(np.diag(M))
        M[np.arange(n), np.arange(n)] = abs(np.sin(k)) * i / n + off
        A[k - 1], B[k - 1] = M, np.exp(i / k) * np.sin(i * k)
    return A, B


_MQ_A, _MQ_B = _maxquad_data()


def _maxquad_pieces(z):
    return np.einsum("...i,kij,...j->...k", z, _MQ_A, z) - z @ _MQ_B.T


def _gill_pieces(z):
    x = z[..., :10]
    s = np.sum(x * x, axis=-1)
    f1 = 1e-3 * (s - 0.25) ** 2 + np.sum((x - 1) ** 2, axis=-1)
    a = np.arange(1, 30) / 29.0
    pw = a[:, None] ** np.arange(10)[None, :]                     # (29, 10) a^(j-1)
    dpw = np.zeros_like(pw)
    dpw[:, 1:] = np.arange(1, 10)[None, :] * a[:, None] ** np.arange(9)[None, :]
    poly = x @ pw.T
    r = -poly * poly - 1 + x @ dpw.T
    f2 = np.sum(r * r, axis=-1) + x[..., 0] ** 2 + (x[..., 1] - x[..., 0] ** 2 - 1) ** 2
    f3 = np.sum(100 * (x[..., 1:] - x[..., :-1] ** 2) ** 2 + (1 - x[..., 1:]) ** 2, axis=-1)
    return np.stack([f1, f2, f3], -1)


_ST_P = np.array([0, 2, 3, 4, 5, 6, 2, 3, -1, -0.5, 2, 2, 2, 1, 1, 5, 1, 1, 1, 1, 2, 3, 2],
                 dtype=float)


def _steiner2(z, x):
    p = _ST_P
    u, v = z[..., :6], z[..., 6:12]
    f = np.sqrt(u[..., 0] ** 2 + v[..., 0] ** 2) + np.sqrt((5.5 - u[..., 5]) ** 2
                                                          + (1 + v[..., 5]) ** 2)
    f = f + np.sum(p[12:18] * np.sqrt((p[:6] - u) ** 2 + (p[6:12] - v) ** 2), axis=-1)
    return f + np.sum(p[18:23] * np.sqrt((u[..., :-1] - u[..., 1:]) ** 2
                                         + (v[..., :-1] - v[..., 1:]) ** 2), axis=-1)


def _maxq_pieces(z):
    return z * z


def _identity(z):
    return z


def _hilbert(n):
    i = np.arange(1, n + 1)
    return 1.0 / (i[:, None] + i[None, :] - 1.0)


_HILB50 = _hilbert(50)


def _mxhilb_pieces(z):
    return z @ _HILB50.T


def _l1hilb(x):
    r = _HILB50 @ x
    s = np.where(r >= 0, 1.0, -1.0)
    return float(np.sum(np.abs(r))), _HILB50.T @ s


def _goffin(x):
    n = x.size
    k = _first_max(x)
    g = -np.ones_like(x)
    g[k] += n
    return float(n * x[k] - x.sum()), g


# ---------------------------------------------------------------- linearly constrained (ch. 3)
def _mad12_pieces(z):
    x1, x2 = _c(z, 1), _c(z, 2)
    return np.stack([x1**2 + x2**2 + x1 * x2 - 1, np.sin(x1), -np.cos(x2)], -1)


def _mad45_pieces(z):
    x1, x2 = _c(z, 1), _c(z, 2)
    return np.stack([-np.exp(x1 - x2), np.sinh(x1 - 1) - 1, -np.log(x2) - 1], -1)


def _pentagon_pieces(z):
    d = [np.sqrt((_c(z, a) - _c(z, b)) ** 2 + (_c(z, a + 1) - _c(z, b + 1)) ** 2)
         for a, b in ((1, 3), (3, 5), (5, 1))]
    return -np.stack(d, -1)


_MAD6_Y = 2 * np.pi * np.sin(np.pi * (8.5 + 0.5 * np.arange(1, 164)) / 180.0)


def _mad6_pieces(z):
    return (1 + 2 * np.sum(np.cos(_MAD6_Y[:, None] * z[..., None, :]), axis=-1)) / 15.0


def _equil_data():
    """Data a (5x8), b (5x8), c (5) of the Walrasian equilibrium problem EQUIL."""
    a = np.ones((5, 8))
    b = np.full((5, 8), 0.1)
    a[1, [0, 1, 3]] = [2.0, 0.8, 0.5]
    a[2, 1:8] = [1.2, 0.8, 1.2, 1.6, 2.0, 0.6, 0.1]
    a[3, [0, 1, 2, 3, 7]] = [2.0, 0.1, 0.6, 2.0, 2.0]
    a[4, [0, 1, 2, 4, 5, 6, 7]] = [1.2, 1.2, 0.8, 1.2, 0.1, 3.0, 4.0]
    b[0, [0, 1, 4, 7]] = [3.0, 1.0, 5.0, 6.0]
    b[1, [1, 4]] = [10.0, 5.0]
    b[2, [1, 2, 4, 6]] = [9.0, 10.0, 4.0, 7.0]
    b[3, [3, 5]] = [10.0, 3.0]
    b[4, 7] = 11.0
    c = np.array([0.5, 1.2, 0.8, 2.0, 1.5])
    return a, b, c


_EQ_A, _EQ_B, _EQ_C = _equil_data()


def _equil_pieces(z):
    """f_l = Σ_i [a_il p_i / (x_l^c_i A_i) − b_il], p_i = Σ_j b_ij x_j, A_i = Σ_j a_ij x_j^(1−c_i)."""
    a, b, c = _EQ_A, _EQ_B, _EQ_C
    p = z @ b.T                                               # (..., 5)
    xpow = z[..., None, :] ** (-c[:, None])                   # (..., 5, 8)
    A = np.sum(a * z[..., None, :] * xpow, axis=-1)           # (..., 5)
    q = a * (p / A)[..., None] * xpow
    return np.sum(q - b, axis=-2)


def _wong_base(z):
    x = [_c(z, i) for i in range(1, 11)]
    return (x[0]**2 + x[1]**2 + x[0]*x[1] - 14*x[0] - 16*x[1] + (x[2]-10)**2 + 4*(x[3]-5)**2
            + (x[4]-3)**2 + 2*(x[5]-1)**2 + 5*x[6]**2 + 7*(x[7]-11)**2 + 2*(x[8]-10)**2
            + (x[9]-7)**2)


def _wong_penalties(z):
    x = [None] + [_c(z, i) for i in range(1, z.shape[-1] + 1)]
    return [0 * x[1],
            3*(x[1]-2)**2 + 4*(x[2]-3)**2 + 2*x[3]**2 - 7*x[4] - 120,
            5*x[1]**2 + 8*x[2] + (x[3]-6)**2 - 2*x[4] - 40,
            0.5*(x[1]-8)**2 + 2*(x[2]-4)**2 + 3*x[5]**2 - x[6] - 30,
            x[1]**2 + 2*(x[2]-2)**2 - 2*x[1]*x[2] + 14*x[5] - 6*x[6],
            6*x[2] - 3*x[1] + 12*(x[9]-8)**2 - 7*x[10]]


def _wong2_pieces(z):
    base = _wong_base(z) + 45
    return np.stack([base + 10 * p if i else base for i, p in enumerate(_wong_penalties(z))], -1)


def _wong3_pieces(z):
    x = [None] + [_c(z, i) for i in range(1, 21)]
    base = (_wong_base(z) + (x[11]-9)**2 + 10*(x[12]-1)**2 + 5*(x[13]-7)**2 + 4*(x[14]-14)**2
            + 27*(x[15]-1)**2 + x[16]**4 + (x[17]-2)**2 + 13*(x[18]-2)**2 + (x[19]-3)**2
            + x[20]**2 + 95)
    more = [x[1]**2 + 15*x[11] - 8*x[12] - 28,
            4*x[1] + 9*x[2] + 5*x[13]**2 - 9*x[14] - 87,
            3*x[1] + 4*x[2] + 3*(x[13]-6)**2 - 14*x[14] - 10,
            14*x[1]**2 + 35*x[15] - 79*x[16] - 92,
            15*x[2]**2 + 11*x[15] - 61*x[16] - 54,
            5*x[1]**2 + 2*x[2] + 9*x[17]**4 - x[18] - 68,
            x[1]**2 - x[2] + 19*x[19] - 20*x[20] + 19,
            7*x[1]**2 + 5*x[2]**2 + x[19]**2 - 30*x[20]]
    pens = _wong_penalties(z)[1:] + more
    return np.stack([base] + [base + 10 * p for p in pens], -1)


def _lc10_pieces(z):
    """f_k = Σx − 1 + x_i(x_i − 1) (k = 2i − 2 even) or x_i(2x_i − 1) (k = 2i − 1 odd)."""
    s = np.sum(z, axis=-1)[..., None] - 1
    return np.stack([s[..., 0] + z[..., i] * (2 * z[..., i] - 1) if k % 2 else
                     s[..., 0] + z[..., i] * (z[..., i] - 1)
                     for k, i in ((k, (k + 1) // 2 - 1 if k % 2 else (k + 2) // 2 - 1)
                                  for k in range(1, 39))], -1)


def _lc11_data():
    a = (1.012577 - 0.987423) / 60
    y = np.empty(124)
    y[0] = 0.967320
    y[1:62] = 0.987423 + np.arange(61) * a
    y[62:123] = y[1:62]
    y[123] = 1.032680
    return y


_LC11_Y = _lc11_data()


def _lc11_pieces(z):
    a = _LC11_Y
    s = np.where((np.arange(1, 125) > 62) & (np.arange(1, 125) < 124), -1.0, 1.0)
    p = -8 * np.log(a)
    for i in range(4):
        b = z[..., None, i + 4] ** 2 - a**2
        p = p + np.log(b * b + a**2 * z[..., None, i] ** 2)
    fa = (0.5 * p - z[..., None, 8]) * s
    shift = np.zeros(124)
    shift[[0, 123]] = 3.0164
    return fa + shift


def _hs114_pieces(z):
    x = [None] + [_c(z, i) for i in range(1, 11)]
    P, A = 500.0, 0.99
    f = 5.04*x[1] + 0.035*x[2] + 10*x[3] + 3.36*x[5] - 0.063*x[4]*x[7]
    c1 = 1.12*x[1] + x[1]*x[8]*(0.13167 - 0.00667*x[8])
    c2 = 57.425 + x[8]*(1.098 - 0.038*x[8]) + 0.325*x[6]
    c3 = 9.8e4*x[3]/(x[4]*x[9] + 1e3*x[3]) - x[6]
    c4 = (x[2] + x[5])/x[1] - x[8]
    return np.stack([f, f + P*(c1 - x[4]/A), f - P*(c1 - x[4]*A), f + P*(c2 - x[7]/A),
                     f - P*(c2 - x[7]*A), f + P*c3, f - P*c3, f + P*c4, f - P*c4], -1)


_DEMBO3_Y = np.array([
    1.715, 0.035, 4.0565, 10.0, 3000.0, -0.063, 0.59553571e-2, 0.88392857, -0.1175625, 1.1088,
    0.1303533, -0.0066033, 0.66173269e-3, 0.17239878e-1, -0.56595559e-2, -0.19120592e-1,
    0.5685075e2, 1.08702, 0.32175, -0.03762, 0.006198, 0.24623121e4, -0.25125634e2,
    0.16118996e3, 5000.0, -0.48951e6, 0.44333333e2, 0.33, 0.022556, -0.007595, 0.00061,
    -0.0005, 0.819672, 0.819672, 24500.0, -250.0, 0.10204082e-1, 0.12244898e-4, 0.0000625,
    0.0000625, -0.00007625, 1.22, 1.0, -1.0])


def _dembo3_pieces(z):
    y = np.r_[0.0, _DEMBO3_Y]                  # 1-based as in the report
    x = [None] + [_c(z, i) for i in range(1, 8)]
    P = 1e5
    f = y[1]*x[1] + y[2]*x[1]*x[6] + y[3]*x[3] + y[4]*x[2] + y[5] + y[6]*x[3]*x[5]
    c = [y[7]*x[6]**2 + y[8]*x[3]/x[1] + y[9]*x[6],
         (y[10] + y[11]*x[6] + y[12]*x[6]**2)*x[1]/x[3],
         y[13]*x[6]**2 + y[14]*x[5] + y[15]*x[4] + y[16]*x[6],
         (y[17] + y[18]*x[6] + y[19]*x[4] + y[20]*x[6]**2)/x[5],
         y[21]*x[7] + (y[22]/x[4] + y[23])*x[2]/x[3],
         (y[24] + (y[25] + y[26]/x[4])*x[2]/x[3])/x[7],
         (y[27] + y[28]*x[7])/x[5],
         (y[33]*x[1] + y[34])/x[3],
         (y[35]/x[4] + y[36])*x[2]/x[3],
         (y[37] + y[38]*x[3]/x[2])*x[4],
         y[39]*x[1]*x[6] + y[40]*x[1] + y[41]*x[3],
         (y[42]*x[3] + y[43])/x[1] + y[44]*x[6]]
    return np.stack([f] + [f + P*(ci - 1) for ci in c], -1)


def _hs106_pieces(z):
    x = [None] + [_c(z, i) for i in range(1, 9)]
    P = 1e5
    f = x[1] + x[2] + x[3]
    return np.stack([f,
                     f + P*((833.33252*x[4]/x[1] + 100 - 83333.333/x[1])/x[6] - 1),
                     f + P*((1250*(x[5] - x[4])/x[2] + x[4])/x[7] - 1),
                     f + P*(((1.25e6 - 2500*x[5])/x[3] + x[5])/x[8] - 1)], -1)


def _dembo7_pieces(z):
    x = [None] + [_c(z, i) for i in range(1, 17)]
    P = 2e3
    f = (1.262626*(x[12] + x[13] + x[14] + x[15] + x[16])
         - 1.231060*(x[1]*x[12] + x[2]*x[13] + x[3]*x[14] + x[4]*x[15] + x[5]*x[16]))
    c = [x[i]*(0.975 + (0.03475 - 0.00975*x[i])/x[i + 5]) - 1 for i in range(1, 6)]
    c += [(x[6] + (x[1] - x[6])*x[12]/x[11])/x[7] - 1,
          (x[7] + 0.002*(x[7] - x[1])*x[12])/x[8] + 0.002*x[13]*(x[2]/x[8] - 1) - 1,
          x[8] + x[9] + 0.002*x[13]*(x[8] - x[2]) + 0.002*x[14]*(x[3] - x[9]) - 1,
          (x[9] + ((x[4] - x[8])*x[15] + 500*(x[10] - x[9]))/x[14])/x[3] - 1,
          x[10]/x[4] + (x[5]/x[4] - 1)*x[16]/x[15] + 500*(1 - x[10]/x[4])/x[15] - 1,
          0.9/x[4] + 0.002*x[16]*(1 - x[5]/x[4]) - 1,
          x[12]/x[11] - 1, x[4]/x[5] - 1, x[3]/x[4] - 1, x[2]/x[3] - 1, x[1]/x[2] - 1,
          x[9]/x[10] - 1, x[8]/x[9] - 1]
    return np.stack([f] + [f + P*ci for ci in c], -1)


def _rows(n, spec):
    """A matrix of linear constraints from {(row, column): value} (1-based)."""
    m = max(r for r, _ in spec)
    A = np.zeros((m, n))
    for (r, c), v in spec.items():
        A[r - 1, c - 1] = v
    return A


# f(x0) by the reference code's own formulas (ACM TOMS 811, subs.f), where the report's table
# is not at hand: a check of the transcription
_F_X0 = {"Wolfe": 60.20797289396148, "Colville1": 20.0, "HS78": 72.75,
         "El-Attar": 24.254415960351725, "Gill": 189.02251756659132,
         "Steiner2": 25.7327034467988, "MXHILB": 4.499205338329423,
         "Shell Dual": 2400.0105255000594, "MAD4": 3.605170185988091,
         "PENTAGON": -1.4142135623730951, "MAD6": 0.22051986506559493, "Wong2": 753.0,
         "Wong3": 901.0, "MAXABS-38": 21899.0, "FILTER-124": 2.1490066545682103,
         "HS114": -829.61265172596, "Dembo3": 2478.554000000012, "HS106": 20555.55555555556,
         "Dembo7": 571.5044552423527}

# the report's starts of PENTAGON and HS114 violate their constraints (the reference code
# makes them feasible first): here their Euclidean projections onto the feasible set
_PENTAGON_X0 = np.array([-1.0, 0.0, 0.0, -1.0, 0.7526553929614432, 0.9196328654161845])
_HS114_X0 = np.array([1744.873867675725, 12000.0, 110.0, 3048.153881435615, 1973.873867675725,
                      89.2, 92.8, 8.0, 3.6, 145.0])


def _build() -> dict[str, NonsmoothProblem]:
    P = NonsmoothProblem
    arr = np.asarray
    sb, mm = _smooth_branch, _minimax
    maxq_x0 = np.array([i if i <= 10 else -i for i in range(1, 21)], dtype=float)
    steiner_x0 = np.zeros(12)
    steiner_x0[0], steiner_x0[6] = 2.0 / 3.0, 5.0 / 3.0
    for i in range(1, 5):
        steiner_x0[i] = (steiner_x0[i - 1] + _ST_P[i] + _ST_P[i + 1]) / 3.0
        steiner_x0[i + 6] = (steiner_x0[i + 5] + _ST_P[i + 6] + _ST_P[i + 7]) / 3.0
    steiner_x0[5] = (steiner_x0[4] + 11.5) / 3.0
    steiner_x0[11] = (steiner_x0[10] + 1.0) / 3.0
    shell_x0 = np.full(15, 1e-4)
    shell_x0[11] = 60.0
    u = [  # the unconstrained problems 1-25 of the report (TR48, 21, needs data not published
        # in the reference code and is left out)
        P("Rosenbrock", sb(_rosenbrock), arr([-1.2, 1.0]), 0.0, 24.2, False, number=1),
        P("Crescent", sb(_crescent), arr([-1.5, 2.0]), 0.0, 4.25, False, number=2),
        P("CB2", mm(_cb2_pieces), arr([1.0, -0.1]), 1.9522245, 5.41, True, number=3),
        P("CB3", mm(_cb3_pieces), arr([2.0, 2.0]), 2.0, 20.0, True, number=4),
        P("DEM", mm(_dem_pieces), arr([1.0, 1.0]), -3.0, 6.0, True, number=5),
        P("QL", mm(_ql_pieces), arr([-1.0, 5.0]), 7.2, 56.0, True, number=6),
        P("LQ", mm(_lq_pieces), arr([-0.5, -0.5]), -np.sqrt(2.0), 1.0, True, number=7),
        P("Mifflin1", mm(_mifflin1_pieces), arr([0.8, 0.6]), -1.0, -0.8, True, number=8),
        P("Mifflin2", sb(_mifflin2), arr([-1.0, -1.0]), -1.0, 4.75, False, number=9),
        P("Wolfe", sb(_wolfe), arr([3.0, 2.0]), -8.0, None, True, number=10),
        P("Rosen-Suzuki", mm(_rosen_suzuki_pieces), np.zeros(4), -44.0, 0.0, True, number=11),
        P("Shor", mm(_shor_pieces), arr([0.0, 0, 0, 0, 1]), 22.600162, 80.0, True, number=12),
        P("Colville1", sb(_colville1), arr([0.0, 0, 0, 0, 1]), -32.348679, None, False,
          number=13),
        P("HS78", sb(_hs78), arr([-2.0, 1.5, 2.0, -1.0, -1.0]), -2.9197004, None, False,
          number=14),
        P("El-Attar", sb(_el_attar), arr([2.0, 2, 7, 0, -2, 1]), 0.5598131, None, False,
          number=15),
        P("Maxquad", mm(_maxquad_pieces), np.ones(10), -0.8414083, 5337.0664, True, number=16),
        P("Gill", mm(_gill_pieces), np.full(10, -0.1), 9.7857721, None, False, number=17),
        P("Steiner2", sb(_steiner2), steiner_x0, 16.703838, None, False, number=18),
        P("MAXQ", mm(_maxq_pieces), maxq_x0, 0.0, 400.0, True, number=19),
        P("MAXL", mm(_identity, absolute=True), maxq_x0.copy(), 0.0, 20.0, True, number=20),
        P("GOFFIN", _goffin, np.arange(1, 51) - 25.5, 0.0, 1225.0, True, number=22),
        P("MXHILB", mm(_mxhilb_pieces, absolute=True), np.ones(50), 0.0, None, True,
          number=23),
        P("L1HILB", _l1hilb, np.ones(50), 0.0, 68.817218, True, number=24),
        P("Shell Dual", sb(_shell_dual), shell_x0, 32.348679, None, False, number=25),
    ]
    mad6_x0 = 0.5 * np.arange(1, 8)
    lc = [
        P("MAD1", mm(_mad12_pieces), arr([1.0, 2.0]), -0.38965952, 6.0, False,
          A_ub=arr([[-1.0, -1.0]]), b_ub=arr([-0.5]), number=1),
        P("MAD2", mm(_mad12_pieces), arr([-2.0, -1.0]), -0.33035714, 6.0, False,
          A_ub=arr([[3.0, 1.0]]), b_ub=arr([-2.5]), number=2),
        P("MAD4", mm(_mad45_pieces), arr([-1.0, 0.01]), -0.44891079, None, False,
          lb=arr([-np.inf, 0.01]), A_ub=arr([[-0.05, 1.0]]), b_ub=arr([0.5]), number=3),
        P("MAD5", mm(_mad45_pieces), arr([-1.0, 3.0]), -0.42928061, -0.018315639, False,
          lb=arr([-np.inf, 0.01]), A_ub=arr([[0.9, -1.0]]), b_ub=arr([-1.0]), number=4),
        P("PENTAGON", mm(_pentagon_pieces), _PENTAGON_X0, -1.8596187, None,
          False, A_ub=np.vstack([np.kron(np.eye(3)[i], [[np.sin(2 * np.pi * j / 5),
                                                        np.cos(2 * np.pi * j / 5)]
                                                       for j in range(5)]) for i in range(3)]),
          b_ub=np.ones(15), number=5),
        P("MAD6", mm(_mad6_pieces, absolute=True), mad6_x0, 0.10183089, None, False,
          lb=arr([0.4] + [-np.inf] * 5 + [3.5]), ub=arr([np.inf] * 6 + [3.5]),
          A_ub=np.vstack([_rows(7, {(1, i): 1.0, (1, i + 1): -1.0}) for i in range(1, 7)]),
          b_ub=np.full(6, -0.4), A_eq=_rows(7, {(1, 4): -1.0, (1, 6): 1.0}), b_eq=arr([1.0]),
          number=6),
        P("EQUIL", mm(_equil_pieces), np.full(8, 0.125), 0.0, 9.7878304, False,
          lb=np.full(8, 1e-8), A_eq=np.ones((1, 8)), b_eq=arr([1.0]), number=7),
        P("Wong2", mm(_wong2_pieces), arr([2.0, 3, 5, 5, 1, 2, 7, 3, 6, 10]), 24.306209, None,
          True, A_ub=_rows(10, {(1, 1): 4, (1, 2): 5, (1, 7): -3, (1, 8): 9, (2, 1): 10,
                                (2, 2): -8, (2, 7): -17, (2, 8): 2, (3, 1): -8, (3, 2): 2,
                                (3, 9): 5, (3, 10): -2}), b_ub=arr([105.0, 0, 12]), number=8),
        P("Wong3", mm(_wong3_pieces),
          arr([2.0, 3, 5, 5, 1, 2, 7, 3, 6, 10, 2, 2, 6, 15, 1, 2, 1, 2, 1, 3]), 133.72828,
          None, True,
          A_ub=_rows(20, {(1, 1): 4, (1, 2): 5, (1, 7): -3, (1, 8): 9, (2, 1): 10, (2, 2): -8,
                          (2, 7): -17, (2, 8): 2, (3, 1): -8, (3, 2): 2, (3, 9): 5,
                          (3, 10): -2, (4, 1): 1, (4, 2): 1, (4, 11): 4, (4, 12): -21}),
          b_ub=arr([105.0, 0, 12, 0]), number=9),
        P("MAXABS-38", mm(_lc10_pieces, absolute=True), np.full(20, 100.0), 0.50694800,
          None, False, lb=arr([0.5] * 10 + [-np.inf] * 10), number=10),
        P("FILTER-124", mm(_lc11_pieces, absolute=True),
          arr([0.0398, 0.968e-4, 0.103e-3, 0.0389, 1.01, 0.968, 1.03, 0.988, -11.6]),
          0.27608128e-3, None, False, lb=arr([0.0] * 8 + [-np.inf]),
          A_ub=-np.vstack([_rows(9, {(1, i): 1e4, (1, i + 4): -1.0}) for i in range(1, 5)]),
          b_ub=np.zeros(4), number=11),
        P("HS114", mm(_hs114_pieces),
          _HS114_X0, -1768.8070, None,
          False, lb=arr([1e-5] * 5 + [85.0, 90, 3, 1.2, 140]),
          ub=arr([2000.0, 16000, 120, 5000, 2000, 93, 95, 12, 4, 160]),
          A_ub=_rows(10, {(1, 9): 0.9, (1, 10): 0.222, (2, 9): -1 / 0.9, (2, 10): -0.222,
                          (3, 7): -3.0, (3, 10): 0.99, (4, 7): 3.0, (4, 10): -1 / 0.99}),
          b_ub=arr([35.82, -35.82, -133.0, 133.0]),
          A_eq=_rows(10, {(1, 1): -1.0, (1, 4): 1.22, (1, 5): -1.0}), b_eq=arr([0.0]),
          number=12),
        P("Dembo3", mm(_dembo3_pieces), arr([1745.0, 110, 3048, 89, 92, 8, 145]), 1227.2261,
          None, False, lb=arr([1.0, 1, 1, 85, 90, 3, 145]), ub=arr([2000.0, 120, 5000, 93, 95,
                                                                    12, 162]),
          A_ub=_rows(7, {(1, 5): _DEMBO3_Y[28], (1, 7): _DEMBO3_Y[29], (2, 1): _DEMBO3_Y[31],
                         (2, 3): _DEMBO3_Y[30]}), b_ub=arr([1.0, 1.0]), number=13),
        P("HS106", mm(_hs106_pieces), arr([5000.0, 5000, 5000, 200, 350, 150, 225, 425]),
          7049.2480, None, False, lb=arr([100.0, 1000, 1000, 10, 10, 10, 10, 10]),
          ub=arr([1e4, 1e4, 1e4, 1e3, 1e3, 1e3, 1e3, 1e3]),
          A_ub=_rows(8, {(1, 4): 2.5e-3, (1, 6): 2.5e-3, (2, 4): -2.5e-3, (2, 5): 2.5e-3,
                         (2, 7): 2.5e-3, (3, 5): -1e-2, (3, 8): 1e-2}), b_ub=np.ones(3),
          number=14),
        P("Dembo7", mm(_dembo7_pieces),
          arr([0.8, 0.83, 0.85, 0.87, 0.9, 0.1, 0.12, 0.19, 0.25, 0.29, 512, 13.1, 71.8, 640,
               650, 5.7]), 174.78699, None, False,
          lb=arr([0.1] * 4 + [0.9, 1e-4] + [0.1] * 4 + [1.0, 1e-6, 1.0, 500, 500, 1e-6]),
          ub=arr([0.9] * 4 + [1.0, 0.1] + [0.9] * 4 + [1e4, 5e3, 5e3, 1e4, 1e4, 5e3]),
          A_ub=_rows(16, {(1, 11): 2e-3, (1, 12): -2e-3}), b_ub=arr([1.0]), number=15),
    ]
    u = [dataclasses.replace(p, group="unconstrained", f_x0=_F_X0.get(p.name, p.f_x0)) for p in u]
    lc = [dataclasses.replace(p, group="linearly constrained", f_x0=_F_X0.get(p.name, p.f_x0))
          for p in lc]
    return {p.name: p for p in u + lc}


@functools.cache
def _problems() -> dict[str, NonsmoothProblem]:
    return _build()


def problem_names() -> list[str]:
    """Names of the test problems in the order of the report's tables."""
    return list(_problems())


def get_problem(name: str) -> NonsmoothProblem:
    """The test problem called ``name`` (case-insensitive)."""
    for key, prob in _problems().items():
        if key.lower() == name.lower():
            return prob
    raise KeyError(f"unknown test problem {name!r}; known: {', '.join(_problems())}")


# ---------------------------------------------------------------- polyhedral, n >= 50
def goffin_problem(n=50) -> NonsmoothProblem:
    """GOFFIN of Lukšan & Vlček (report 798, problem 2.22): f(x) = n·max_i x_i − Σ x_i.

    A maximum of n linear functions, f* = 0 on the line x = c·1, from x_i = i − (n + 1)/2
    (f(x0) = n(n − 1)/2).  Its minimum is the meeting point of all n pieces: a bundle method
    needs room for n cuts (plus one) to certify it.
    """
    def oracle(x):
        k = int(np.argmax(x))
        g = -np.ones_like(x)
        g[k] += n
        return float(n * x[k] - x.sum()), g

    x0 = np.arange(1, n + 1) - (n + 1) / 2.0
    return NonsmoothProblem(f"GOFFIN-{n}", oracle, x0, 0.0, n * (n - 1) / 2.0, True)


def max_linear_problem(n=60, pieces=None, seed=7, f_star=1.0) -> NonsmoothProblem:
    """f(x) = f* + max_k a_kᵀ(x − x*), k = 1..pieces (default 2n), a polyhedral f with a known
    sharp minimum f* at x* (constructed here, not from the report).

    The a_k are random with norms between 0.1 and 10 and then shifted so that
    Σ_k w_k a_k = 0 for random weights w_k > 0: every piece-weighted sum vanishes, hence
    f(x) ≥ f* + Σ w_k a_kᵀ(x − x*) / Σ w_k = f*, with equality only at x* (the a_k span Rⁿ).
    At x* all pieces are active; a bundle needs at least n + 1 of them.  Start x0 = 0,
    x* uniform in [−5, 5]ⁿ; ``data`` holds a, w and x*.
    """
    pieces = 2 * n if pieces is None else pieces
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(pieces, n))
    a *= (10.0 ** rng.uniform(-1, 1, pieces) / np.linalg.norm(a, axis=1))[:, None]
    w = rng.uniform(0.5, 1.5, pieces)
    a -= (w @ a) / w.sum()
    x_star = rng.uniform(-5, 5, n)

    def oracle(x):
        vals = a @ (x - x_star)
        k = int(np.argmax(vals))
        return float(f_star + vals[k]), a[k].copy()

    x0 = np.zeros(n)
    return NonsmoothProblem(f"MAXLIN-{n}", oracle, x0, f_star, None, True,
                            data={"a": a, "w": w, "x_star": x_star})


# ---------------------------------------------------------------- the paper's admissible set
def paper_admissible_set(rows=8, cols=4, upper=0.75, d_row=0.5 * 2 / 7, d_col=0.5 / 3,
                         volume=0.01 * 32) -> dict:
    """Linear constraints of a design set with the structure of U in Beremlijski et al. (2009).

    x = α.ravel() (row-major) for α of shape (rows, cols): ``0 ≤ α_ij ≤ upper``,
    ``|α_{i+1,j} − α_ij| ≤ d_row``, ``|α_{i,j+1} − α_ij| ≤ d_col`` and ``Σ α_ij = volume``.
    Returns the keyword arguments lb, ub, A_ub, b_ub, A_eq, b_eq of ``minimize_bundle``.
    """
    n = rows * cols
    idx = np.arange(n).reshape(rows, cols)
    pairs = [(idx[i + 1, j], idx[i, j], d_row) for i in range(rows - 1) for j in range(cols)]
    pairs += [(idx[i, j + 1], idx[i, j], d_col) for i in range(rows) for j in range(cols - 1)]
    A = np.zeros((2 * len(pairs), n))
    b = np.zeros(2 * len(pairs))
    for k, (a, c, bound) in enumerate(pairs):
        A[2 * k, a], A[2 * k, c] = 1.0, -1.0
        A[2 * k + 1, a], A[2 * k + 1, c] = -1.0, 1.0
        b[2 * k] = b[2 * k + 1] = bound
    return dict(lb=np.zeros(n), ub=np.full(n, float(upper)), A_ub=A, b_ub=b,
                A_eq=np.ones((1, n)), b_eq=np.array([float(volume)]))


def max_quadratics_problem(seed=4, pieces=5, rows=8, cols=4) -> NonsmoothProblem:
    """f(x) = max_k ½(x − c_k)ᵀQ_k(x − c_k) + b_k over the paper-like set, from α = 0.01.

    Convex and nonsmooth; Q_k = ½I + L_kL_kᵀ (L_k of rank 3), centres c_k concentrated on a few
    components, so that at the minimiser several pieces, bounds and slope constraints are
    active.  ``data`` holds Q, c, b (for an independent SOCP reference); f* is not tabulated.
    """
    n = rows * cols
    rng = np.random.default_rng(seed)
    L = [rng.normal(size=(n, 3)) * 0.6 for _ in range(pieces)]
    Q = np.array([0.5 * np.eye(n) + Lk @ Lk.T for Lk in L])
    c = np.array([rng.dirichlet(np.full(n, 0.1)) * 0.32 * 6.0 for _ in range(pieces)])
    b = rng.uniform(0.0, 0.05, pieces)

    def oracle(x):
        r = x[None, :] - c
        vals = 0.5 * np.einsum("ki,kij,kj->k", r, Q, r) + b
        k = int(np.argmax(vals))
        return float(vals[k]), Q[k] @ r[k]

    cons = paper_admissible_set(rows, cols, volume=0.01 * n)
    return NonsmoothProblem(f"MAXQUAD-U{n}", oracle, np.full(n, 0.01), None, None, True,
                            data={"Q": Q, "c": c, "b": b}, **cons)


def max_quadratics_reference(prob):
    """Independent optimum of :func:`max_quadratics_problem`: (x, f) from Clarabel.

    min_x max_k ½(x−c_k)ᵀQ_k(x−c_k)+b_k over U as an SOCP with an epigraph variable s.
    Clarabel is a test-only dependency: ImportError when it is not installed.
    """
    import clarabel
    import scipy.sparse as sp

    n = prob.n
    Q, c, b = prob.data["Q"], prob.data["c"], prob.data["b"]
    blocks, rhs = [np.hstack([prob.A_eq, np.zeros((1, 1))])], [prob.b_eq]
    cones = [clarabel.ZeroConeT(1)]
    lin = np.vstack([prob.A_ub, np.eye(n), -np.eye(n)])
    blocks.append(np.hstack([lin, np.zeros((lin.shape[0], 1))]))
    rhs.append(np.concatenate([prob.b_ub, prob.ub, -prob.lb]))
    cones.append(clarabel.NonnegativeConeT(lin.shape[0]))
    for Qk, ck, bk in zip(Q, c, b):
        # ½‖Lᵀ(x−c)‖² ≤ s − b  ⇔  (s−b+1, √2 Lᵀ(x−c), s−b−1) ∈ second-order cone
        L = np.linalg.cholesky(Qk)
        A = np.zeros((n + 2, n + 1))
        r = np.zeros(n + 2)
        A[0, n], r[0] = -1.0, 1.0 - bk
        A[1:n + 1, :n], r[1:n + 1] = -np.sqrt(2) * L.T, -np.sqrt(2) * L.T @ ck
        A[n + 1, n], r[n + 1] = -1.0, -bk - 1.0
        blocks.append(A)
        rhs.append(r)
        cones.append(clarabel.SecondOrderConeT(n + 2))
    q = np.zeros(n + 1)
    q[n] = 1.0
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-11
    sol = clarabel.DefaultSolver(sp.csc_matrix((n + 1, n + 1)), q,
                                 sp.csc_matrix(np.vstack(blocks)), np.concatenate(rhs),
                                 cones, settings).solve()
    if str(sol.status) not in ("Solved", "AlmostSolved"):
        raise RuntimeError(f"Clarabel did not solve the reference SOCP: {sol.status}")
    x = np.array(sol.x[:n])
    return x, prob(x)[0]


# ---------------------------------------------------------------- nonlinear constraints c(x) ≤ 0
@dataclass(frozen=True)
class ConstrainedProblem:
    """min f(x) over U ∩ {c(x) ≤ 0}: ``oracle(x) -> (f, g, c, J)`` (the form of
    :func:`contactopt.optimize.constrained.minimize_constrained`; J one subgradient of each c_i
    per row), start ``x0`` (it may violate c ≤ 0), optimal value ``f_star``, ``source`` where
    the data and the optimum come from; U as in :class:`NonsmoothProblem`."""

    name: str
    oracle: Callable = field(repr=False)
    x0: np.ndarray = field(repr=False)
    f_star: float
    source: str = ""
    A_ub: np.ndarray | None = field(default=None, repr=False)
    b_ub: np.ndarray | None = field(default=None, repr=False)

    @property
    def n(self) -> int:
        return self.x0.size

    def __call__(self, x):
        return self.oracle(np.asarray(x, dtype=float))

    def constraints(self) -> dict:
        """Keyword arguments of the linear part U for ``minimize_bundle``."""
        return {k: getattr(self, k) for k in ("A_ub", "b_ub") if getattr(self, k) is not None}


def _constrained(f_pieces, c_pieces, max_of_c=False, f_abs=False):
    """(f, g, c, J): f the max of ``f_pieces`` (|·| with ``f_abs``), c each of ``c_pieces`` (or
    their max, one constraint); subgradients of the first maximiser, by the complex step."""
    fo = _minimax(f_pieces, absolute=f_abs)

    def oracle(x):
        f, g = fo(x)
        z = x[None, :] + 1j * _H * np.eye(x.size)
        c = np.real(c_pieces(x))
        J = (np.asarray(c_pieces(z)).imag / _H).T
        if max_of_c:
            k = _first_max(c)
            c, J = c[k:k + 1], J[k:k + 1]
        return f, g, c, J
    return oracle


def _stack(*funcs):
    return lambda z: np.stack([fn(z) for fn in funcs], -1)


def _l1_pieces(z):
    return np.sum(z * np.sign(np.real(z) + (np.real(z) == 0)), axis=-1)[..., None]


def _linf_pieces(z):
    return z


def _build_constrained() -> dict[str, ConstrainedProblem]:
    """The nonlinearly constrained problems (:class:`ConstrainedProblem`)."""
    C = ConstrainedProblem
    arr = np.asarray

    def rs_f(z):
        return _rosen_suzuki_pieces(z)[..., :1]

    def rs_c(z):
        f1 = _rosen_suzuki_pieces(z)[..., 0]
        return np.stack([(_rosen_suzuki_pieces(z)[..., i] - f1) / 10 for i in (1, 2, 3)], -1)

    def wong2_f(z):
        return (_wong_base(z) + 45)[..., None]

    def wong2_c(z):
        return np.stack(_wong_penalties(z)[1:], -1)

    def wong3_f(z):
        return _wong3_pieces(z)[..., :1]

    def wong3_c(z):
        p = _wong3_pieces(z)
        return (p[..., 1:] - p[..., :1]) / 10

    w = np.array([1.0, 2.0, 3.0])
    lin2 = dict(A_ub=_problems()["Wong2"].A_ub, b_ub=_problems()["Wong2"].b_ub)
    lin3 = dict(A_ub=_problems()["Wong3"].A_ub, b_ub=_problems()["Wong3"].b_ub)
    lv = "Lukšan & Vlček, TR 798 (2000)"
    probs = [
        C("C-Mifflin1", _constrained(lambda z: -z[..., :1], lambda z: (z[..., 0]**2 + z[..., 1]**2 - 1)[..., None]),
          arr([0.8, 0.6]), -1.0,
          f"min −x1 s.t. x1² + x2² ≤ 1: {lv} unconstrained problem 8 (Mifflin 1) is its exact penalty "
          "−x1 + 20 max(0, c); x* = (1, 0), f* = −1"),
        C("C-Rosen-Suzuki", _constrained(rs_f, rs_c, max_of_c=True), np.zeros(4), -44.0,
          "Hock & Schittkowski problem 43 (Rosen–Suzuki) with the one constraint max(g1, g2, g3) ≤ 0, "
          f"nonsmooth at x* = (0, 1, 2, −1) where g1 and g3 are active; f* = −44 ({lv} problem 11 is "
          "its exact penalty)"),
        C("C-Wong2", _constrained(wong2_f, wong2_c), arr([2.0, 3, 5, 5, 1, 2, 7, 3, 6, 10]), 24.306209,
          f"Hock & Schittkowski problem 113 (Wong 2): five quadratic constraints and three linear rows; "
          f"f* = 24.306209 ({lv} linearly constrained problem 8 is its exact penalty)", **lin2),
        C("C-Wong3", _constrained(wong3_f, wong3_c),
          arr([2.0, 3, 5, 5, 1, 2, 7, 3, 6, 10, 2, 2, 6, 15, 1, 2, 1, 2, 1, 3]), 133.72828,
          f"Wong 3: thirteen nonlinear constraints and four linear rows; f* = 133.72828 ({lv} linearly "
          "constrained problem 9 is its exact penalty)", **lin3),
        C("C-L1-halfspace", _constrained(lambda z: _l1_pieces(z), lambda z: (1 - z @ w)[..., None]),
          np.zeros(3), 1.0 / 3.0,
          "min ‖x‖₁ s.t. x1 + 2x2 + 3x3 ≥ 1, from the infeasible x0 = 0: by LP duality f* = 1/‖w‖∞ = 1/3 "
          "at x* = (0, 0, 1/3), where f is not differentiable (x1 = x2 = 0)"),
        C("C-Linf-L1ball", _constrained(_linf_pieces, lambda z: (np.sum(
            (z - 2) * np.sign(np.real(z) - 2 + (np.real(z) == 2)), axis=-1) - 1)[..., None], f_abs=True),
          np.zeros(10), 1.9,
          "min ‖x‖∞ s.t. ‖x − 2·1‖₁ ≤ 1 in R¹⁰, from the infeasible x0 = 0: max x_i < 2 − 1/10 would give "
          "Σ(2 − x_i) > 1, so f* = 1.9 at x* = 1.9·1, where f and c are both nonsmooth"),
    ]
    return {p.name: p for p in probs}


@functools.cache
def _constrained_problems() -> dict[str, ConstrainedProblem]:
    return _build_constrained()


def __getattr__(name: str):
    """``PROBLEMS`` and ``CONSTRAINED``, built on first use."""
    if name == "PROBLEMS":
        return _problems()
    if name == "CONSTRAINED":
        return _constrained_problems()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


PROBLEMS: dict[str, NonsmoothProblem]
"""The problems of Lukšan & Vlček's report by name, in the order of its tables (built on first use)."""

CONSTRAINED: dict[str, ConstrainedProblem]
"""The problems with nonlinear constraints c(x) ≤ 0 by name (built on first use)."""
