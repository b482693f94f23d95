"""Several designed faces in one model: α = (α_1, …, α_D) and U = U_1 × … × U_D.

Each designed face d has its own Bézier surface ϑ_d of degree (d1, d2)_d on its own design
rectangle (:class:`~contactopt.design.bezier.BezierSurface`) and its own admissible set U_d
(:class:`~contactopt.design.admissible.AdmissibleSet`). The design vector is the concatenation of
the faces' control points in ``[[designs]]`` order, each block flattened in C order as one face's
α is (:mod:`contactopt.design.bezier`): block d occupies ``offsets[d]:offsets[d + 1]``.

A model of one design keeps the :class:`BezierSurface` and :class:`AdmissibleSet` themselves; the
classes here serve the same calls (``as_vector``, ``size``, ``constraints``, ``violations`` …) for
D > 1, so that the optimizer, the sensitivities and the state solves see one vector α.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .admissible import feasible, required
from .bezier import BezierSurface


@dataclass(frozen=True)
class DesignSurfaces:
    """The Bézier surfaces of D ≥ 2 designed faces; α their control points concatenated."""

    surfaces: tuple[BezierSurface, ...]

    @property
    def sizes(self) -> tuple[int, ...]:
        return tuple(s.size for s in self.surfaces)

    @property
    def offsets(self) -> np.ndarray:
        """(D + 1,) where each design's block of α starts (and the total size last)."""
        return np.concatenate([[0], np.cumsum(self.sizes)]).astype(np.int64)

    @property
    def size(self) -> int:
        return int(sum(self.sizes))

    def as_vector(self, alpha) -> np.ndarray:
        """α as one flat float vector: given flat (length ``size``) or as one array per design
        (a control-point matrix or vector each)."""
        if isinstance(alpha, (list, tuple)) and len(alpha) == len(self.surfaces) and not np.isscalar(alpha[0]) \
                and all(np.size(a) == s.size for a, s in zip(alpha, self.surfaces)):
            return np.concatenate([s.as_vector(a) for s, a in zip(self.surfaces, alpha)])
        arr = np.asarray(alpha, dtype=float)
        if arr.size != self.size:
            raise ValueError(f"design has {arr.size} entries, the {len(self.surfaces)} designed faces need "
                             f"{self.size} = " + " + ".join(str(n) for n in self.sizes))
        return arr.reshape(-1).copy()

    def split(self, alpha) -> list[np.ndarray]:
        """α as one vector per design."""
        x = self.as_vector(alpha)
        o = self.offsets
        return [x[o[d]:o[d + 1]].copy() for d in range(len(self.surfaces))]

    def as_matrices(self, alpha) -> list[np.ndarray]:
        """α as one control-point matrix per design."""
        return [s.as_matrix(a) for s, a in zip(self.surfaces, self.split(alpha))]


def surfaces_of(surface) -> tuple[BezierSurface, ...]:
    """The Bézier surface(s) of a model's ``surface``: itself for one design, each for several."""
    return surface.surfaces if isinstance(surface, DesignSurfaces) else (surface,)


def split_design(surface, alpha) -> list[np.ndarray]:
    """α as one vector per design of a model's ``surface`` (one design: ``[α]``)."""
    return surface.split(alpha) if isinstance(surface, DesignSurfaces) else [surface.as_vector(alpha)]


def alpha_record(surface, alpha):
    """α as written to result files: the control-point matrix (nested lists) of one design, a list
    of them, one per design in ``[[designs]]`` order, for several."""
    if isinstance(surface, DesignSurfaces):
        return [m.tolist() for m in surface.as_matrices(alpha)]
    return surface.as_matrix(alpha).tolist()


def flat_design(surface, value) -> np.ndarray:
    """A design read from a result file (:func:`alpha_record`) or given flat, as one flat vector."""
    if isinstance(surface, DesignSurfaces) and isinstance(value, list) and len(value) == len(surface.surfaces) \
            and all(isinstance(v, list) for v in value):
        return np.concatenate([np.asarray(v, float).reshape(-1) for v in value])
    return np.asarray(value, float).reshape(-1)


class ProductAdmissible:
    """U = U_1 × … × U_D: each design's constraints on its own block of α, the optimizer's box and
    rows the blocks' side by side (block-diagonal rows). Violations are named per design
    (``designs[d]: …``)."""

    def __init__(self, sets, names=None):
        self.sets = tuple(sets)
        self.names = tuple(names or (f"designs[{d}]" for d in range(len(self.sets))))
        sizes = [U.size for U in self.sets]
        self.offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.lb = np.concatenate([U.lb for U in self.sets])
        self.ub = np.concatenate([U.ub for U in self.sets])
        self.A_ub = _block_rows([U.A_ub for U in self.sets], sizes)
        self.b_ub = np.concatenate([U.b_ub for U in self.sets])
        self.A_eq = _block_rows([U.A_eq for U in self.sets], sizes)
        self.b_eq = np.concatenate([U.b_eq for U in self.sets])

    @property
    def size(self) -> int:
        return int(self.offsets[-1])

    def _blocks(self, alpha):
        x = np.asarray(alpha, float).reshape(-1)
        return [x[self.offsets[d]:self.offsets[d + 1]] for d in range(len(self.sets))]

    def constraints(self) -> dict:
        """Keyword arguments for :func:`contactopt.optimize.minimize_bundle`."""
        return dict(lb=self.lb, ub=self.ub, A_ub=self.A_ub, b_ub=self.b_ub, A_eq=self.A_eq, b_eq=self.b_eq)

    def nonempty(self) -> bool:
        return all(U.nonempty() for U in self.sets)

    def violations(self, alpha, tol: float = 1e-9) -> list[str]:
        """Every violated constraint at α, by design, name and amount (empty when α ∈ U)."""
        x = np.asarray(alpha, float).reshape(-1)
        if x.size != self.size:
            return [f"design has {x.size} entries, expected {self.size}"]
        return [f"{name}: {v}" for name, U, a in zip(self.names, self.sets, self._blocks(x))
                for v in U.violations(a, tol)]

    def is_feasible(self, alpha, tol: float = 1e-9) -> bool:
        return feasible(self, alpha, tol)

    def require_feasible(self, alpha, tol: float = 1e-9) -> np.ndarray:
        """Return α as a vector, or raise :class:`InfeasibleDesignError` naming every violation."""
        return required(self, alpha, tol)


def _block_rows(blocks, sizes) -> np.ndarray:
    """Rows of each design on its own columns: a block-diagonal matrix of the (possibly empty) blocks."""
    return sla.block_diag(*[np.asarray(B, float).reshape(-1, n) for B, n in zip(blocks, sizes)])
