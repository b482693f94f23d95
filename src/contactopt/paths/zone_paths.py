"""What the condensation and Delassus paths share: the local Coulomb problem on the contact zone.

Both solve the local problem u = W r + q on the zone Z (FCLIB convention, per node (ν, t1, t2)):
W_Z the zone's block of the Delassus operator W = S⁻¹, q = (S⁻¹ℓ)_Z + (g, 0, 0), where P
reorders each node's (t1, t2, ν) to (ν, t1, t2); the FCLIB friction law r_T = −μ r_N u_T/‖u_T‖
is the Coulomb law of the condensed problem (3.17). The zone grows by every node it misses
(:mod:`contactopt.contact.zone`), so the state never depends on it.

Newton builds its matrices from the block W_Z of an earlier design, kept in single precision,
while products W_Z r are exact (triangular or sparse solves in double precision), so the block is
formed only when it has drifted from the current one (``[state] reuse_delassus``;
:meth:`ZonePath.solve_local`). The paths differ in how a zone problem is built
(:meth:`ZonePath.zone_problem`) and in how a product by W costs: a triangular solve with the
Cholesky factor of S, or a sparse solve with that of A(α).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .._threads import sequential_openblas
from ..contact import zone as zone_rules
from ..contact.fallback import solve_with_fallbacks
from ..contact.newton import solve_newton
from ..contact.state import FROM_FCLIB, displacement_scale, friction_at
from ..errors import CheckpointError, ContactOptError
from .base import Context, SolverPath, check_design, check_node_set

log = logging.getLogger(__name__)

REUSE_MAX_STEPS = 12   # a solve with a kept Delassus block that needs more steps drops it
REUSE_MAX_GAP = 0.2    # kept blocks farther than this from the new W_Z (relative) are not used
CHORD_MIN_GAP = 1e-3   # below this gap Newton is nearly quadratic: no chord steps
JACOBIAN_DTYPE = np.float32  # a kept block only builds Newton matrices, and is 1e-3–0.2 off the
                             # current W_Z anyway: single precision (docs/large_meshes.md)
REUSE_TOL_FACTOR = 0.1  # Newton on a kept block iterates to this times tol: exact Newton's last,
                        # quadratic step usually overshoots far below tol; an inexact Jacobian
                        # converges linearly and would otherwise stop just below it


class KeptBlock(NamedTuple):
    """A Delassus block kept from an earlier design: the design ``alpha``, the ``zone`` (contact
    nodes) and the block ``W`` = W_Z (single precision, per node in the FCLIB order)."""

    alpha: np.ndarray
    zone: np.ndarray
    W: np.ndarray


@dataclass
class ZoneContext(Context):
    """A load case's context on a zone path: also ``jacobian``, its :class:`KeptBlock`, or None."""

    jacobian: KeptBlock | None = None


class ZonePath(SolverPath):
    """A path whose state is the zone's local problem (module docstring)."""

    reuse_tol_factor = REUSE_TOL_FACTOR
    accept_at_tol = False     # accept a reused-block solve that reached tol (not the factor)
    probe_warm = False        # measure a kept block's distance on the warm start
    new_fraction = 0.25       # a kept block takes exact columns for at most this fraction of new nodes

    def new_context(self) -> ZoneContext:
        return ZoneContext(None, self.all_nodes)

    # ------------------------------------------------------------------ hooks
    def zone_problem(self, system, zone, warm, reuse: bool, shared: dict):
        """(zone problem, zone) of a load case's system (the zone may be predicted anew)."""
        raise NotImplementedError

    def free_displacement(self, system, zp, r_loc, u_body) -> np.ndarray:
        """The displacement on the free DOFs of the zone's forces ``r_loc`` (FCLIB order), whose
        contact DOFs are ``u_body`` (:meth:`body_contact_displacement`)."""
        raise NotImplementedError

    def body_contact_displacement(self, system, u_c, r) -> np.ndarray:
        """The body's own displacement on the contact DOFs (3p,) for the contact law's ``u_c`` and
        the forces ``r`` (p, 3) per node (t1, t2, ν): ``u_c`` itself on the rigid foundation."""
        return np.ravel(u_c)

    def load_scale(self, system) -> np.ndarray:
        """The load against which forces count as zero when nothing is in contact."""
        raise NotImplementedError

    def own_block(self, system, zone) -> np.ndarray:
        """W_Z of ``zone`` from the zone's own factorization (what a checkpoint rebuilds)."""
        raise NotImplementedError

    def max_new(self, nodes, fraction: float) -> dict:
        return {"max_new": fraction}

    # ------------------------------------------------------------------ state
    def solve_state(self, system, ctx, alpha, *, method, warm_start, tol, shared, label="", slip_ref=None):
        """The state through the transforms of the contact system (:meth:`transformed_state`)."""
        return self.transformed_state(system, ctx, alpha, method=method, warm_start=warm_start, tol=tol,
                                      shared=shared, label=label, slip_ref=slip_ref)

    def fixed_state(self, system, ctx, alpha, **kw):
        return self.zone_state(system, ctx, alpha, **kw)

    def zone_state(self, system, ctx, alpha, *, method, warm_start, tol, shared, label="", slip_ref=None):
        """The zone's Coulomb state; ``slip_ref`` (p, 2): in a load step, u_t at the end of the
        previous step (q shifted by −slip_ref, sensitivity/steps.py)."""
        s = self.settings
        timings = dict(system.timings, delassus=0.0, contact=0.0)
        zone = ctx.next_zone if s.use_zone else self.all_nodes
        warm = ctx.warm if warm_start else None
        misses, reused = 0, []
        t0 = time.perf_counter()
        # a kept Delassus block will most likely serve Newton: the products need no W_Z
        reuse = method == "newton" and s.reuse_delassus and ctx.jacobian is not None
        zp, zone = self.zone_problem(system, zone, warm, reuse, shared)
        t1 = time.perf_counter()
        timings["recovery"] = 0.0
        while True:
            res, t_inv, how = self.solve_local(zp, system, warm, method, tol, alpha, ctx, slip_ref)
            reused.append(how)
            u3 = zp.displacements(res.r)
            timings["delassus"] += t1 - t0 + t_inv
            timings["contact"] += time.perf_counter() - t1 - t_inv
            clearance = u3[:, 2] + system.gap
            u_scale = displacement_scale(u3, system.gap)
            missed = zone_rules.missed_nodes(zone, clearance, u_scale)
            if missed.size == 0:
                # the classes count a gap closed against the whole displacement's scale: the
                # zone must hold every node they call closed (its nodes outside are of class L)
                t3 = time.perf_counter()
                r = np.zeros((self.model.n_contact, 3))                      # per node (t1, t2, ν)
                r[zone] = res.r.reshape(-1, 3)[:, FROM_FCLIB]
                u_body = self.body_contact_displacement(system, u3, r)
                u = self.model.assembler.to_full(self.free_displacement(system, zp, res.r, u_body))
                timings["recovery"] += time.perf_counter() - t3
                u_scale = displacement_scale(u3, system.gap, u)
                missed = zone_rules.missed_nodes(zone, clearance, u_scale)
                if missed.size == 0:
                    break
            misses += 1
            lam_all = np.zeros(system.gap.size)
            lam_all[zone] = res.r[0::3]
            log.debug("contact zone of %d nodes missed %d node(s) closing their gap; solving again",
                      zone.size, missed.size)
            t0 = time.perf_counter()
            zp = zp.grow(np.union1d(missed, zone_rules.near_nodes(lam_all, clearance, u_scale, s.zone_margin)))
            t1 = time.perf_counter()
            warm = self._zone_warm(res.r, zone)
            zone = zp.zone
        stats = {"backend": self.library_of(system), "zone_nodes": int(zone.size), "zone_misses": misses,
                "delassus": reused[-1], **self.solve_counts(zp),
                **({"fallback": res.stats["fallback"]} if "fallback" in res.stats else {})}
        state = self.finish_state(ctx, alpha=alpha, coords=system.assembled.coords, u=u, u_c=u3, r=r,
                                  gap=system.gap, load=lambda: self.load_scale(system), method=method,
                                  outcome=(res.iterations, res.error, res.converged),
                                  timings=timings, stats=stats, slip_ref=slip_ref,
                                  foundation=self.foundation_state(system, u3, r, u_body))
        ctx.warm = self._zone_warm(res.r, zone)
        self.n_zone_misses += misses
        log.debug("state%s: %s %d it, residual %.2e, zone %d/%d nodes, %.3f s", label, method,
                  res.iterations, res.error, zone.size, self.model.n_contact, timings["total"])
        return state

    def library_of(self, system) -> str:
        return getattr(system.factor, "backend", "?")

    def solve_counts(self, zp) -> dict:
        return {}

    def foundation_state(self, system, u_c, r, u_body):
        """The :class:`~contactopt.contact.state.FoundationState` of a state on an elastic
        foundation (the condensation path's), else None."""
        return None

    def solve_local(self, zp, system, warm, method, tol, alpha, ctx, slip_ref=None):
        """The zone's local problem u = W r + q, q = (S⁻¹ℓ)_Z + (g, 0, 0), in the FCLIB convention.

        Returns (result, time spent forming W_Z, how W_Z entered: "formed" or "reused"). With
        ``reuse_delassus``, Newton first runs with the Delassus block of an earlier design as its
        matrix and exact products W_Z r (:meth:`ZoneProblem.product`), so the state is exact
        either way; W_Z is formed (and kept for later designs) when that solve fails, and the kept
        block is dropped when it needed more than REUSE_MAX_STEPS steps."""
        s = self.settings
        q = zp.q0.copy()
        q[0::3] += system.gap[zp.zone]
        if slip_ref is not None:          # a load step: the law acts on u_t − u_t^(k−1)
            q[1::3] -= slip_ref[zp.zone, 0]
            q[2::3] -= slip_ref[zp.zone, 1]
        r0 = warm[zp.zone].ravel() if warm is not None else None
        mu = friction_at(self.friction, zp.zone)
        tol = tol or s.tol
        if method == "newton" and s.reuse_delassus and not zp.has_W:
            W_old = None if ctx.jacobian is None else zp.block_from(
                ctx.jacobian.zone, ctx.jacobian.W, **self.max_new(zp.zone, self.new_fraction))
            eta = np.inf if W_old is None else zp.relative_gap(W_old, r0 if self.probe_warm else None)
            if eta <= REUSE_MAX_GAP:
                res = solve_newton(W_old, q, mu, tol=tol * self.reuse_tol_factor, max_iter=s.max_iter,
                                   r0=r0, product=zp.product, chord=eta > CHORD_MIN_GAP, raise_on_failure=False)
                if res.converged or (self.accept_at_tol and res.error <= tol):
                    if res.iterations > REUSE_MAX_STEPS:
                        ctx.jacobian = None                # stale: form W_Z at the next design
                    return res, 0.0, "reused"
                log.debug("Newton with the Delassus block of an earlier design stopped at %.2e "
                          "after %d steps; forming W_Z", res.error, res.iterations)
                r0 = res.r
        t0 = time.perf_counter()
        keep = method == "newton" and s.reuse_delassus
        # a kept block must be what import_context rebuilds, bit for bit (a resumed run repeats
        # the uninterrupted one): the zone's own factorization, not the grown block (equal up to
        # round-off). Zones grow rarely.
        W = self.own_block(system, zp.zone) if keep and zp.grown else zp.W
        t_inv = time.perf_counter() - t0
        self.n_delassus += 1
        if keep:
            ctx.jacobian = KeptBlock(alpha, zp.zone, W.astype(JACOBIAN_DTYPE))
        res = solve_with_fallbacks(W, q, mu, method=method, tol=tol, max_iter=s.max_iter, r0=r0,
                                   gap=system.gap[zp.zone])
        return res, t_inv, "formed"

    def _zone_warm(self, r_loc: np.ndarray, zone: np.ndarray) -> np.ndarray:
        """Contact forces of a zone solve as a (p, 3) warm start, per node (N, T1, T2)."""
        w = np.zeros((self.model.n_contact, 3))
        w[zone] = r_loc.reshape(-1, 3)
        return w

    # ------------------------------------------------------------------ checkpoints
    def export_context(self, ctx) -> dict:
        jac = ctx.jacobian       # rebuilt at resume: the same Newton matrices
        return {**super().export_context(ctx),
                "jacobian_alpha": np.asarray(jac.alpha if jac else np.zeros(0), dtype=float),
                "jacobian_zone": np.asarray(jac.zone if jac else np.zeros(0), dtype=np.int64)}

    def import_context(self, ctx, arrays: dict, where: str, others=()) -> None:
        """Also form the kept Delassus block W_Z at the checkpoint's design and zone (W_Z does
        not depend on the load; cases that kept the same block share it)."""
        super().import_context(ctx, arrays, where, others)
        a = arrays.get("jacobian_alpha")
        if a is None or not a.size:
            return
        alpha = check_design(a, self.model.n_design, where, "Delassus design")
        zone = check_node_set(arrays["jacobian_zone"], self.model.n_contact, where, "Delassus zone")
        if not self.settings.reuse_delassus:
            return
        for other in others:
            j = other.jacobian
            if j is not None and np.array_equal(j.alpha, alpha) and np.array_equal(j.zone, zone):
                ctx.jacobian = j
                return
        try:
            with sequential_openblas(), self.evaluation_threads():   # the round-off of a state solve
                system = self.prepare(self.model.assemble(alpha, self.first_loads))
                ctx.jacobian = KeptBlock(alpha, zone, self.own_block(system, zone).astype(JACOBIAN_DTYPE))
        except ContactOptError as exc:
            raise CheckpointError(f"{where}: its Delassus design cannot be rebuilt: {exc}") from None

