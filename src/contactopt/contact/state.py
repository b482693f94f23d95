"""The contact state of one design and the node classes of Table 4.1.

Conventions (every array is in contact-node order, see :mod:`contactopt.fem.model`):

* ``u_c[m] = (u1, u2, u3)``: displacement of contact node m; tangential part u_t = (u1, u2),
  normal part u_ν = u3 (the foundation x3 ≤ 0 has normal e3);
* ``gap[m] = ϑ_α(x'_m)``: initial distance to the foundation; non-penetration u_ν + g ≥ 0;
* ``lam[m] = λ_m = (S u_c − ℓ)_ν ≥ 0``: normal contact force on the body (paper (3.17));
* ``tau[m] = τ_m = −(S u_c − ℓ)_t``: the paper's tangential contact force, so that
  ‖τ_m‖ ≤ F λ_m and u_t ≠ 0 ⇒ τ_m = F λ_m u_t/‖u_t‖ (the friction force acting on the body
  is −τ_m, opposite to the slip).

Table 4.1 classes of node m, with a = (u_t, u_ν, λ) and b = (τ, 0, −(u_ν + g)):

    L   no contact (λ = 0, u_ν + g > 0)          M1  sliding (u_t ≠ 0) with contact (λ > 0)
    M2  sliding, weak contact (λ = 0 = u_ν + g)  M3+ sticking, ‖τ‖ < Fλ, contact
    M3− weak sticking ‖τ‖ = Fλ, u_t = 0, contact M4  weak sticking, weak contact

A quantity counts as zero below ``rtol`` times its scale: displacements against the largest of
|u_c|, g and the body's whole displacement |u|, forces against the largest |λ| (or the load when
nothing is in contact). Scales that cannot vanish while the body is loaded: a contact face that
does not move (a column held at its top and pressed on the plane, u_c = 0 to round-off) still
has a displacement scale from the rest of the body, so round-off of u_c does not decide its classes.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields
from types import MappingProxyType

import numpy as np

CLASS_NAMES = ("L", "M1", "M2", "M3+", "M3-", "M4")
CLASS_CODES = {name: k for k, name in enumerate(CLASS_NAMES)}
DEGENERATE = ("M2", "M3-", "M4")


TO_FCLIB = np.array([2, 0, 1])    # per node (t1, t2, ν) -> the local solvers' (ν, t1, t2)
FROM_FCLIB = np.array([1, 2, 0])  # and back
CLASS_RTOL = 1e-7      # relative tolerance below which a displacement or force counts as zero


def displacement_scale(u_c: np.ndarray, gap: np.ndarray, u=None) -> float:
    """max(|u_c|, |g|, |u|): the scale against which displacements and clearances count as zero
    (``u``: the whole displacement of the body, any layout; None: the contact nodes' alone)."""
    whole = 0.0 if u is None else np.abs(u).max(initial=0.0)
    return max(np.abs(u_c).max(initial=0.0), np.abs(gap).max(initial=0.0), whole, 1e-300)


def classify_nodes(u_c: np.ndarray, lam: np.ndarray, tau: np.ndarray, gap: np.ndarray,
                   friction, rtol: float = CLASS_RTOL, force_scale: float | None = None,
                   u=None) -> np.ndarray:
    """Class code (index into CLASS_NAMES) of every contact node, Table 4.1; ``friction`` F, a
    scalar or (p,) per node; ``u`` the body's whole displacement (module docstring: the
    displacement scale)."""
    u_c = np.asarray(u_c).reshape(-1, 3)
    u_scale = displacement_scale(u_c, gap, u)
    f_scale = force_scale if force_scale is not None else max(np.abs(lam).max(initial=0.0), 1e-300)
    tol_u, tol_f = rtol * u_scale, rtol * f_scale
    slide = np.linalg.norm(u_c[:, :2], axis=1) > tol_u
    clearance = u_c[:, 2] + gap
    pos_force = lam > tol_f
    open_gap = clearance > tol_u
    strong = pos_force & ~open_gap
    weak = ~pos_force & ~open_gap
    none = ~pos_force & open_gap
    slack = friction * lam - np.linalg.norm(tau, axis=1)
    stick_strong = ~slide & (slack > tol_f)
    out = np.full(lam.shape, CLASS_CODES["M4"])
    out[none] = CLASS_CODES["L"]
    out[strong & slide] = CLASS_CODES["M1"]
    out[weak & slide] = CLASS_CODES["M2"]
    out[strong & stick_strong] = CLASS_CODES["M3+"]
    out[strong & ~slide & ~stick_strong] = CLASS_CODES["M3-"]
    out[weak & ~slide] = CLASS_CODES["M4"]
    # without friction a node in contact "slides" freely: treat sticking as sliding (per node
    # where F is given per node, F_m = 0)
    out[strong & ~slide & (np.asarray(friction) == 0.0)] = CLASS_CODES["M1"]
    return out


def friction_at(friction, nodes):
    """The Coulomb coefficient at the contact nodes ``nodes`` (indices or a mask): a scalar F stays
    the scalar, a per-node array (p,) is taken at those nodes."""
    return friction if np.ndim(friction) == 0 else np.asarray(friction)[nodes]


def one_friction(friction):
    """F as one number where every contact node has the same coefficient, else the (p,) array."""
    if np.ndim(friction) and np.size(friction) and np.all(friction == np.asarray(friction).flat[0]):
        return float(np.asarray(friction).flat[0])
    return friction


def friction_record(friction):
    """F as JSON holds it: a float, or per contact node a list of floats."""
    return float(friction) if np.ndim(friction) == 0 else [float(f) for f in np.asarray(friction)]


def class_counts(codes: np.ndarray) -> dict:
    return {name: int(np.sum(codes == k)) for k, name in enumerate(CLASS_NAMES)}


class FoundationState:
    """What a state on an elastic foundation adds (:mod:`contactopt.fem.foundation`): the state's
    ``u_c`` is then the relative displacement w = u_body − u_partner, and here are the body's own
    contact displacement ``u_body_c`` and its partners' ``u_partner`` ((p, 3) per node (t1, t2, ν))
    and the foundation's displacement ``displacement`` (3 per node of its mesh).

    ``displacement`` may be given as a function of no arguments: it is then called on first read
    (the outputs read it, an evaluation does not: its sparse solves on the foundation's interior
    are left to the states that are written)."""

    __slots__ = ("u_body_c", "u_partner", "_displacement")

    def __init__(self, u_body_c: np.ndarray, u_partner: np.ndarray, displacement):
        self.u_body_c, self.u_partner, self._displacement = u_body_c, u_partner, displacement

    @property
    def displacement(self) -> np.ndarray:
        if callable(self._displacement):
            self._displacement = np.asarray(self._displacement())
        return self._displacement


@dataclass
class SolveStats:
    """What a path reports about the solve of a state; None where the path does not report it."""

    path: str | None = None                # the path's name
    backend: str | None = None             # its linear algebra: "pyamg", "petsc", a factorization library
    ranks: int | None = None               # MPI ranks (PETSc)
    zone_nodes: int | None = None          # contact nodes in the final zone
    zone_misses: int | None = None         # zone enlargements (nodes found in contact outside it)
    delassus: str | None = None            # the Delassus matrix: "formed", "reused" or "none"
    sparse_solves: int | None = None       # solves with the sparse factor (the Delassus path)
    krylov_iterations: int | None = None   # Krylov iterations of the full-space Newton steps
    adjoint_krylov: int | None = None      # Krylov iterations of the adjoint solve
    extra: dict = field(default_factory=dict)   # a caller's statistics without a named field

    def items(self) -> Iterator[tuple[str, object]]:
        """(name, value) of every statistic reported: the named fields set, then ``extra``."""
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name != "extra" and value is not None:
                yield f.name, value
        yield from self.extra.items()

    @classmethod
    def of(cls, entries: Mapping) -> SolveStats:
        """The record of the dictionary form ``entries``: names of fields into them, the rest into
        ``extra``."""
        named = {f.name for f in fields(cls)} - {"extra"}
        return cls(**{k: v for k, v in entries.items() if k in named},
                   extra={k: v for k, v in entries.items() if k not in named})


@dataclass(frozen=True)
class ObstacleControl:
    """A force-controlled obstacle (``contactopt.paths.force``): its translation s along the
    force's direction, the resultant of the contact forces at s, and the state solves it took."""

    translation: float
    resultant: float
    solves: int


@dataclass(frozen=True)
class RigidAnchor:
    """The anchor of a body held by no Dirichlet condition (``contactopt.paths.rigid``): the
    iterations of its rigid-motion loop and the loop's final residual ratio."""

    iterations: int
    residual: float


# the dictionary form of State's data (State.info): key -> (field, attribute of the field's record)
_DATA_KEYS = {"step": ("step", None), "substep": ("substep", None), "slip": ("slip", None),
              "objective": ("objective", None),
              "obstacle_translation": ("obstacle", "translation"),
              "obstacle_resultant": ("obstacle", "resultant"), "obstacle_solves": ("obstacle", "solves"),
              "rigid_iterations": ("rigid", "iterations"), "rigid_residual": ("rigid", "residual"),
              "uniqueness_bound_F0": ("uniqueness_bound", None),
              "uniqueness_bound_F0_reason": ("uniqueness_reason", None)}
_RECORDS = {"obstacle": ObstacleControl, "rigid": RigidAnchor}


@dataclass
class State:
    """Solution of the discrete Coulomb contact problem for one design (see module docstring)."""

    alpha: np.ndarray
    coords: np.ndarray            # node coordinates of Ω(α), (n_nodes, 3)
    u: np.ndarray                 # full displacement, (3·n_nodes,), zero on Γ_u
    u_c: np.ndarray               # (p, 3)
    lam: np.ndarray               # (p,)
    tau: np.ndarray               # (p, 2)
    gap: np.ndarray               # (p,)
    classes: np.ndarray           # (p,) codes into CLASS_NAMES
    friction: float | np.ndarray  # F used: a scalar, or (p,) per contact node
    method: str
    iterations: int
    residual: float               # Siconos error of the local problem
    complementarity: float        # max violation of the contact conditions, relative
    converged: bool
    timings: dict = field(default_factory=dict)
    stats: SolveStats = field(default_factory=SolveStats)   # what the path reports about the solve
    slip_ref: np.ndarray | None = None   # (p, 2) u_t at the end of the previous load step, or None
    foundation: FoundationState | None = None   # on an elastic foundation
    step: str | None = None              # on a load path: the step's name
    substep: int | None = None           # and the substep (1, 2, ... up to the step's end)
    slip: np.ndarray | None = None       # (p, 2) the slip accumulated along the load path
    objective: float | None = None       # J at a step's end (the steps the objective sees)
    obstacle: ObstacleControl | None = None   # a force-controlled obstacle
    rigid: RigidAnchor | None = None     # a body anchored by its contact alone
    uniqueness_bound: float | None = None     # the friction bound F0 of the uniqueness estimate
    uniqueness_reason: str | None = None      # why that bound is absent or only an estimate

    @property
    def info(self) -> Mapping:
        """The dictionary form of the solve statistics and the data (read-only, for old code):
        the keys of :class:`SolveStats`, ``step``, ``substep``, ``slip``, ``objective``,
        ``obstacle_translation``/``_resultant``/``_solves``, ``rigid_iterations``/``_residual``,
        ``uniqueness_bound_F0(_reason)``, each where set. New code reads the named fields."""
        out = dict(self.stats.items())
        for key, (name, attr) in _DATA_KEYS.items():
            value = getattr(self, name)
            if value is not None and attr is not None:
                value = getattr(value, attr)
            if value is not None:
                out[key] = value
        return MappingProxyType(out)

    @staticmethod
    def fields_of_info(info: Mapping) -> dict:
        """The keyword arguments of State (``stats`` and the data fields) for the dictionary
        form ``info`` (:attr:`info`; e.g. read back from a state file)."""
        out, parts, rest = {}, {}, {}
        for key, value in info.items():
            if key not in _DATA_KEYS:
                rest[key] = value
            elif _DATA_KEYS[key][1] is None:
                out[_DATA_KEYS[key][0]] = value
            else:
                parts.setdefault(_DATA_KEYS[key][0], {})[_DATA_KEYS[key][1]] = value
        for name, kw in parts.items():
            out[name] = _RECORDS[name](**kw)
        return {"stats": SolveStats.of(rest), **out}

    @property
    def slip_increment(self) -> np.ndarray:
        """The tangential displacement the friction law acts on, (p, 2) — u_t − u_t^(k−1) in a
        load step, u_t itself in the static problem (sensitivity/steps.py)."""
        ut = self.u_c[:, :2]
        return ut if self.slip_ref is None else ut - self.slip_ref

    @property
    def class_names(self) -> np.ndarray:
        return np.array(CLASS_NAMES, dtype=object)[self.classes]

    @property
    def counts(self) -> dict:
        return class_counts(self.classes)

    @property
    def n_degenerate(self) -> int:
        return int(sum(self.counts[n] for n in DEGENERATE))

    def summary(self) -> dict:
        """JSON-ready summary (no large arrays)."""
        return {
            "method": self.method, "iterations": int(self.iterations), "converged": bool(self.converged),
            "residual": float(self.residual), "complementarity": float(self.complementarity),
            "friction": friction_record(self.friction), "node_classes": self.counts,
            "degenerate_nodes": self.n_degenerate,
            "total_normal_force": float(self.lam.sum()), "max_normal_force": float(self.lam.max(initial=0)),
            "nodes_in_contact": int(np.sum(self.lam > 0)),
            "max_displacement": float(np.abs(self.u).max(initial=0)),
            "timings_s": {k: float(v) for k, v in self.timings.items()},
            **self.scalars(),
        }

    def scalars(self) -> dict:
        """The scalars of :attr:`info` (solver counts, the path, the step, J ...), and whether the
        state is on an elastic foundation."""
        out = {k: v for k, v in self.info.items() if isinstance(v, (int, float, str, bool))}
        if self.foundation is not None:
            out["foundation"] = True
        return out


def contact_conditions_violation(u_c, lam, tau, gap, friction) -> float:
    """Largest violation of the contact conditions (3.17), relative to the force/displacement scales.

    λ ≥ 0, u_ν + g ≥ 0, λ(u_ν + g) = 0, ‖τ‖ ≤ Fλ, and ‖τ‖·‖u_t‖ = Fλ·‖u_t‖ with τ ∥ u_t
    (i.e. τ‖u_t‖ − Fλ u_t = 0); F a scalar or (p,) per node.
    """
    u_c = np.asarray(u_c).reshape(-1, 3)
    fs = max(np.abs(lam).max(initial=0.0), 1e-300)
    us = max(np.abs(u_c).max(initial=0.0), np.abs(gap).max(initial=0.0), 1e-300)
    clear = u_c[:, 2] + gap
    ut = u_c[:, :2]
    nut = np.linalg.norm(ut, axis=1)
    v = [np.max(-lam, initial=0.0) / fs,
         np.max(-clear, initial=0.0) / us,
         np.max(np.abs(lam * clear), initial=0.0) / (fs * us),
         np.max(np.linalg.norm(tau, axis=1) - friction * lam, initial=0.0) / fs,
         np.max(np.linalg.norm(tau * nut[:, None] - (friction * lam)[:, None] * ut, axis=1), initial=0.0) / (fs * us)]
    return float(max(v))
