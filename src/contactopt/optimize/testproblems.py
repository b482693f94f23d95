"""Nonsmooth test problems of Lukšan & Vlček for the bundle method.

Source: L. Lukšan, J. Vlček, *Test problems for nonsmooth unconstrained and linearly
constrained optimization*, Technical report 798, ICS AS CR, Prague, 2000; the selection and
the optimal values f* are those of ``/work/shared/data/NONSMOOTH_TESTS.md``.

Every problem is a :class:`NonsmoothProblem`: calling it returns ``(f, g)`` with ``g`` one
Clarke subgradient (for a maximum the gradient of the first active piece, for ``|h|`` the
vector ``sign(h)·∇h`` with ``sign(0) = 0``, which lies in ``conv{∇h, −∇h}``).  The linear
constraints use the keyword names of :func:`contactopt.optimize.minimize_bundle`
(``lb``, ``ub``, ``A_ub x <= b_ub``, ``A_eq x == b_eq``), see :meth:`NonsmoothProblem.constraints`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["NonsmoothProblem", "PROBLEMS", "get_problem", "problem_names",
           "paper_admissible_set", "max_quadratics_problem", "goffin_problem",
           "max_linear_problem"]


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


def _max_pieces(values, grads):
    """max of pieces; subgradient of the first maximiser."""
    k = int(np.argmax(values))
    return float(values[k]), np.asarray(grads[k], dtype=float)


# ---------------------------------------------------------------- unconstrained, n = 2
def _cb2(x):
    x1, x2 = x
    e = 2.0 * np.exp(-x1 + x2)
    vals = [x1**2 + x2**4, (2 - x1) ** 2 + (2 - x2) ** 2, e]
    grads = [(2 * x1, 4 * x2**3), (-2 * (2 - x1), -2 * (2 - x2)), (-e, e)]
    return _max_pieces(vals, grads)


def _cb3(x):
    x1, x2 = x
    e = 2.0 * np.exp(-x1 + x2)
    vals = [x1**4 + x2**2, (2 - x1) ** 2 + (2 - x2) ** 2, e]
    grads = [(4 * x1**3, 2 * x2), (-2 * (2 - x1), -2 * (2 - x2)), (-e, e)]
    return _max_pieces(vals, grads)


def _dem(x):
    x1, x2 = x
    vals = [5 * x1 + x2, -5 * x1 + x2, x1**2 + x2**2 + 4 * x2]
    grads = [(5.0, 1.0), (-5.0, 1.0), (2 * x1, 2 * x2 + 4)]
    return _max_pieces(vals, grads)


def _ql(x):
    x1, x2 = x
    q = x1**2 + x2**2
    vals = [q, q + 10 * (-4 * x1 - x2 + 4), q + 10 * (-x1 - 2 * x2 + 6)]
    grads = [(2 * x1, 2 * x2), (2 * x1 - 40, 2 * x2 - 10), (2 * x1 - 10, 2 * x2 - 20)]
    return _max_pieces(vals, grads)


def _lq(x):
    x1, x2 = x
    vals = [-x1 - x2, -x1 - x2 + x1**2 + x2**2 - 1]
    grads = [(-1.0, -1.0), (-1 + 2 * x1, -1 + 2 * x2)]
    return _max_pieces(vals, grads)


def _mifflin1(x):
    x1, x2 = x
    h = x1**2 + x2**2 - 1
    if h > 0:
        return -x1 + 20 * h, np.array([-1 + 40 * x1, 40 * x2])
    return -x1 + 0.0, np.array([-1.0, 0.0])


def _mifflin2(x):
    x1, x2 = x
    h = x1**2 + x2**2 - 1
    s = np.sign(h)
    f = -x1 + 2 * h + 1.75 * abs(h)
    c = 2 + 1.75 * s
    return f, np.array([-1 + c * 2 * x1, c * 2 * x2])


def _crescent(x):
    x1, x2 = x
    a = x1**2 + (x2 - 1) ** 2
    vals = [a + x2 - 1, -a + x2 + 1]
    grads = [(2 * x1, 2 * (x2 - 1) + 1), (-2 * x1, -2 * (x2 - 1) + 1)]
    return _max_pieces(vals, grads)


# ---------------------------------------------------------------- unconstrained, n > 2
def _rosen_suzuki(x):
    x1, x2, x3, x4 = x
    f1 = x1**2 + x2**2 + 2 * x3**2 + x4**2 - 5 * x1 - 5 * x2 - 21 * x3 + 7 * x4
    g1 = np.array([2 * x1 - 5, 2 * x2 - 5, 4 * x3 - 21, 2 * x4 + 7])
    # the three constraints of the Rosen-Suzuki problem, penalised exactly with weight 10
    pieces = [
        (0.0, np.zeros(4)),
        (x1**2 + x2**2 + x3**2 + x4**2 + x1 - x2 + x3 - x4 - 8,
         np.array([2 * x1 + 1, 2 * x2 - 1, 2 * x3 + 1, 2 * x4 - 1])),
        (x1**2 + 2 * x2**2 + x3**2 + 2 * x4**2 - x1 - x4 - 10,
         np.array([2 * x1 - 1, 4 * x2, 2 * x3, 4 * x4 - 1])),
        (x1**2 + x2**2 + x3**2 + 2 * x1 - x2 - x4 - 5,
         np.array([2 * x1 + 2, 2 * x2 - 1, 2 * x3, -1.0])),
    ]
    m, gm = _max_pieces([p[0] for p in pieces], [p[1] for p in pieces])
    return f1 + 10 * m, g1 + 10 * gm


_SHOR_A = np.array([
    [0, 0, 0, 0, 0],
    [2, 1, 1, 1, 3],
    [1, 2, 1, 1, 2],
    [1, 4, 1, 2, 2],
    [3, 2, 1, 0, 1],
    [0, 2, 1, 0, 1],
    [1, 1, 1, 1, 1],
    [1, 0, 1, 2, 1],
    [0, 0, 2, 1, 0],
    [1, 1, 2, 0, 0],
], dtype=float)
_SHOR_B = np.array([1, 5, 10, 2, 4, 3, 1.7, 2.5, 6, 3.5])


def _shor(x):
    r = x[None, :] - _SHOR_A
    vals = _SHOR_B * np.sum(r * r, axis=1)
    k = int(np.argmax(vals))
    return float(vals[k]), 2 * _SHOR_B[k] * r[k]


def _maxq(x):
    k = int(np.argmax(x * x))
    g = np.zeros_like(x)
    g[k] = 2 * x[k]
    return float(x[k] ** 2), g


def _maxl(x):
    k = int(np.argmax(np.abs(x)))
    g = np.zeros_like(x)
    g[k] = np.sign(x[k])
    return float(abs(x[k])), g


_HILB50 = 1.0 / (np.arange(1, 51)[:, None] + np.arange(1, 51)[None, :] - 1.0)


def _l1hilb(x):
    r = _HILB50 @ x
    return float(np.sum(np.abs(r))), _HILB50.T @ np.sign(r)


# ---------------------------------------------------------------- linearly constrained
def _mad12(x):
    x1, x2 = x
    vals = [x1**2 + x2**2 + x1 * x2 - 1, np.sin(x1), -np.cos(x2)]
    grads = [(2 * x1 + x2, 2 * x2 + x1), (np.cos(x1), 0.0), (0.0, np.sin(x2))]
    return _max_pieces(vals, grads)


def _mad5(x):
    x1, x2 = x
    e = np.exp(x1 - x2)
    vals = [-e, np.sinh(x1 - 1) - 1, -np.log(x2) - 1]
    grads = [(-e, e), (np.cosh(x1 - 1), 0.0), (0.0, -1.0 / x2)]
    return _max_pieces(vals, grads)


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


def _equil(x):
    """max_l f_l with f_l = sum_i [a_il p_i / (x_l^c_i A_i) - b_il],
    p_i = sum_j b_ij x_j, A_i = sum_j a_ij x_j^(1 - c_i)."""
    a, b, c = _EQ_A, _EQ_B, _EQ_C
    p = b @ x                                   # (5,)
    xpow = x[None, :] ** (-c[:, None])          # x_j^-c_i, (5, 8)
    A = np.sum(a * x[None, :] * xpow, axis=1)   # sum_j a_ij x_j^(1-c_i)
    q = a * p[:, None] * xpow / A[:, None]      # q_il
    vals = np.sum(q - b, axis=0)
    l = int(np.argmax(vals))
    # d q_il / d x_k = a_il x_l^-c_i [b_ik / A_i - p_i a_ik (1-c_i) x_k^-c_i / A_i^2]
    #                  - delta_lk c_i q_il / x_l
    coef = a[:, l] * xpow[:, l]                 # (5,)
    dA = a * (1 - c[:, None]) * xpow            # (5, 8)
    dq = coef[:, None] * (b / A[:, None] - p[:, None] * dA / A[:, None] ** 2)
    g = dq.sum(axis=0)
    g[l] -= np.sum(c * q[:, l]) / x[l]
    return float(vals[l]), g


def _build() -> dict[str, NonsmoothProblem]:
    P = NonsmoothProblem
    arr = np.asarray
    maxq_x0 = np.array([i if i <= 10 else -i for i in range(1, 21)], dtype=float)
    probs = [
        P("CB2", _cb2, arr([1.0, -0.1]), 1.9522245, 5.41, True),
        P("CB3", _cb3, arr([2.0, 2.0]), 2.0, 20.0, True),
        P("DEM", _dem, arr([1.0, 1.0]), -3.0, 6.0, True),
        P("QL", _ql, arr([-1.0, 5.0]), 7.2, 56.0, True),
        P("LQ", _lq, arr([-0.5, -0.5]), -1.4142136, 1.0, True),
        P("Mifflin1", _mifflin1, arr([0.8, 0.6]), -1.0, -0.8, True),
        P("Mifflin2", _mifflin2, arr([-1.0, -1.0]), -1.0, 4.75, False),
        P("Crescent", _crescent, arr([-1.5, 2.0]), 0.0, 4.25, False),
        P("Rosen-Suzuki", _rosen_suzuki, np.zeros(4), -44.0, 0.0, True),
        P("Shor", _shor, arr([0.0, 0, 0, 0, 1]), 22.600162, 80.0, True),
        P("MAXQ", _maxq, maxq_x0, 0.0, 400.0, True),
        P("MAXL", _maxl, maxq_x0.copy(), 0.0, 20.0, True),
        P("L1HILB", _l1hilb, np.ones(50), 0.0, 68.817218, True),
        P("MAD1", _mad12, arr([1.0, 2.0]), -0.38965952, 6.0, False,
          A_ub=arr([[-1.0, -1.0]]), b_ub=arr([-0.5])),
        P("MAD2", _mad12, arr([-2.0, -1.0]), -0.33035714, 6.0, False,
          A_ub=arr([[3.0, 1.0]]), b_ub=arr([-2.5])),
        P("MAD5", _mad5, arr([-1.0, 3.0]), -0.42928061, -0.018315639, False,
          lb=arr([-np.inf, 0.01]), A_ub=arr([[0.9, -1.0]]), b_ub=arr([-1.0])),
        P("EQUIL", _equil, np.full(8, 0.125), 0.0, 9.7878304, False,
          lb=np.full(8, 1e-8), A_eq=np.ones((1, 8)), b_eq=arr([1.0])),
    ]
    return {p.name: p for p in probs}


PROBLEMS: dict[str, NonsmoothProblem] = _build()


def problem_names() -> list[str]:
    """Names of the test problems in the order of the report's tables."""
    return list(PROBLEMS)


def get_problem(name: str) -> NonsmoothProblem:
    """The test problem called ``name`` (case-insensitive)."""
    for key, prob in PROBLEMS.items():
        if key.lower() == name.lower():
            return prob
    raise KeyError(f"unknown test problem {name!r}; known: {', '.join(PROBLEMS)}")


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
