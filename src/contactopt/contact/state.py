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

from dataclasses import dataclass, field

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
                   friction: float, rtol: float = CLASS_RTOL, force_scale: float | None = None,
                   u=None) -> np.ndarray:
    """Class code (index into CLASS_NAMES) of every contact node, Table 4.1; ``u`` the body's
    whole displacement (module docstring: the displacement scale)."""
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
    if np.all(np.asarray(friction) == 0.0):
        # without friction every node in contact "slides" freely: treat sticking as sliding
        out[strong & ~slide] = CLASS_CODES["M1"]
    return out


def class_counts(codes: np.ndarray) -> dict:
    return {name: int(np.sum(codes == k)) for k, name in enumerate(CLASS_NAMES)}


@dataclass(frozen=True)
class FoundationState:
    """What a state on an elastic foundation adds (:mod:`contactopt.fem.foundation`): the state's
    ``u_c`` is then the relative displacement w = u_body − u_partner, and here are the body's own
    contact displacement ``u_body_c`` and its partners' ``u_partner`` ((p, 3) per node (t1, t2, ν))
    and the foundation's displacement ``displacement`` (3 per node of its mesh)."""

    u_body_c: np.ndarray
    u_partner: np.ndarray
    displacement: np.ndarray


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
    friction: float
    method: str
    iterations: int
    residual: float               # Siconos error of the local problem
    complementarity: float        # max violation of the contact conditions, relative
    converged: bool
    timings: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    slip_ref: np.ndarray | None = None   # (p, 2) u_t at the end of the previous load step, or None
    foundation: FoundationState | None = None   # on an elastic foundation

    @property
    def slip_increment(self) -> np.ndarray:
        """(p, 2) the tangential displacement the friction law acts on: u_t − u_t^(k−1) in a load
        step, u_t itself in the static problem (sensitivity/steps.py)."""
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
            "friction": float(self.friction), "node_classes": self.counts,
            "degenerate_nodes": self.n_degenerate,
            "total_normal_force": float(self.lam.sum()), "max_normal_force": float(self.lam.max(initial=0)),
            "nodes_in_contact": int(np.sum(self.lam > 0)),
            "max_displacement": float(np.abs(self.u).max(initial=0)),
            "timings_s": {k: float(v) for k, v in self.timings.items()},
            **self.scalars(),
        }

    def scalars(self) -> dict:
        """The scalars of ``info`` (solver counts, the path), and whether the state is on an
        elastic foundation."""
        out = {k: v for k, v in self.info.items() if isinstance(v, (int, float, str, bool))}
        if self.foundation is not None:
            out["foundation"] = True
        return out


def contact_conditions_violation(u_c, lam, tau, gap, friction) -> float:
    """Largest violation of the contact conditions (3.17), relative to the force/displacement scales.

    λ ≥ 0, u_ν + g ≥ 0, λ(u_ν + g) = 0, ‖τ‖ ≤ Fλ, and ‖τ‖·‖u_t‖ = Fλ·‖u_t‖ with τ ∥ u_t
    (i.e. τ‖u_t‖ − Fλ u_t = 0).
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
         np.max(np.linalg.norm(tau * nut[:, None] - friction * lam[:, None] * ut, axis=1), initial=0.0) / (fs * us)]
    return float(max(v))
