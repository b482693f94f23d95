"""Bézier surfaces on a rectangle: the contact-surface parametrisation of §5.2.

The contact surface is the graph of

    ϑ_α(x1, x2) = Σ_{i=0..d1} Σ_{j=0..d2} α_ij β^i_{d1}(x1) β^j_{d2}(x2),   (x1, x2) ∈ R,

on the design rectangle R = [x1lo, x1lo + a]×[x2lo, x2lo + b] (the paper's block: [0,a]×[0,b]),
with the Bernstein polynomials β^ℓ_d(x1) = C(d,ℓ) t^ℓ (1 − t)^{d−ℓ}, t = (x1 − x1lo)/a, and
likewise in x2 (paper §5.2).
The design vector is α flattened in C order (row-major): index k = i·(d2+1) + j.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import comb


def bernstein(degree: int, t: np.ndarray) -> np.ndarray:
    """Bernstein basis of the given degree at parameters ``t`` ∈ [0,1]: array (len(t), degree+1)."""
    t = np.asarray(t, dtype=float).reshape(-1)
    ell = np.arange(degree + 1)
    coef = comb(degree, ell)
    # 0**0 = 1 in numpy, which is the right convention at the end points.
    return coef * t[:, None] ** ell * (1.0 - t[:, None]) ** (degree - ell)


def bernstein_derivative(degree: int, t: np.ndarray) -> np.ndarray:
    """d/dt of the Bernstein basis: d·(B^{ℓ−1}_{d−1} − B^ℓ_{d−1}); array (len(t), degree+1)."""
    t = np.asarray(t, dtype=float).reshape(-1)
    out = np.zeros((t.size, degree + 1))
    if degree == 0:
        return out
    low = bernstein(degree - 1, t)
    out[:, 1:] += degree * low
    out[:, :-1] -= degree * low
    return out


@dataclass(frozen=True)
class BezierSurface:
    """A tensor-product Bézier surface of degree (d1, d2) on [x1lo, x1lo+a]×[x2lo, x2lo+b].

    ``a``, ``b`` are the side lengths of the design rectangle (the paper's block: its origin is 0).
    """

    d1: int
    d2: int
    a: float
    b: float
    x1lo: float = 0.0
    x2lo: float = 0.0

    @property
    def shape(self) -> tuple[int, int]:
        """Shape of the control-point matrix α: (d1+1, d2+1)."""
        return (self.d1 + 1, self.d2 + 1)

    @property
    def size(self) -> int:
        """Number of design variables (d1+1)(d2+1)."""
        return (self.d1 + 1) * (self.d2 + 1)

    def basis_matrix(self, x1, x2) -> np.ndarray:
        """Matrix Bm with ϑ_α(x1_m, x2_m) = (Bm @ α.ravel())_m; shape (len(x1), size).

        Column k = i·(d2+1)+j holds β^i_{d1}(x1) β^j_{d2}(x2), so this is also ∂ϑ/∂α_ij.
        """
        t1, t2 = self.parameters(x1, x2)
        b1, b2 = bernstein(self.d1, t1), bernstein(self.d2, t2)
        return (b1[:, :, None] * b2[:, None, :]).reshape(b1.shape[0], -1)

    def parameters(self, x1, x2):
        """Bernstein parameters t = ((x1 − x1lo)/a, (x2 − x2lo)/b) ∈ [0, 1]² on the rectangle."""
        return (np.asarray(x1, float) - self.x1lo) / self.a, (np.asarray(x2, float) - self.x2lo) / self.b

    def derivative_matrices(self, x1, x2) -> tuple[np.ndarray, np.ndarray]:
        """Matrices D1, D2 with ∂ϑ/∂x1 = D1 @ α, ∂ϑ/∂x2 = D2 @ α at the given points."""
        t1, t2 = self.parameters(x1, x2)
        b1, b2 = bernstein(self.d1, t1), bernstein(self.d2, t2)
        db1 = bernstein_derivative(self.d1, t1) / self.a
        db2 = bernstein_derivative(self.d2, t2) / self.b
        n = b1.shape[0]
        return ((db1[:, :, None] * b2[:, None, :]).reshape(n, -1),
                (b1[:, :, None] * db2[:, None, :]).reshape(n, -1))

    def evaluate(self, alpha, x1, x2) -> np.ndarray:
        """Heights ϑ_α at the points (x1, x2)."""
        return self.basis_matrix(x1, x2) @ self.as_vector(alpha)

    def as_vector(self, alpha) -> np.ndarray:
        """α as a flat float vector of length ``size`` (accepts the matrix or the vector)."""
        arr = np.asarray(alpha, dtype=float)
        if arr.size != self.size:
            raise ValueError(
                f"design has {arr.size} entries, the Bézier surface of degree "
                f"({self.d1},{self.d2}) needs {self.size} = {self.shape[0]}×{self.shape[1]}")
        return arr.reshape(-1).copy()

    def as_matrix(self, alpha) -> np.ndarray:
        """α as the (d1+1)×(d2+1) control-point matrix."""
        return self.as_vector(alpha).reshape(self.shape)
