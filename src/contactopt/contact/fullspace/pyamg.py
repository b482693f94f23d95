"""The pyamg backend of the full-space method (:mod:`contactopt.contact.fullspace`): NumPy/SciPy
arrays, GMRES preconditioned by a V-cycle of a pyamg hierarchy of H = A + K_t
(:class:`~contactopt.fem.amg.ContactHierarchy`). Conventions as in :mod:`.core`.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from ..._threads import sequential_openblas
from ...errors import ProblemDataError, SolverError
from ...fem.amg import ContactHierarchy, block_positions, rigid_body_modes
from ...fem.krylov import KrylovNotConverged, gmres
from ..fallback import diagnose, penetrating_start, run_chain
from .core import OPEN, SLIDE, STICK, FullSpaceResult, finish, newton_loop, rho_of, start, start_forces


# ----------------------------------------------------------------------------- Newton system
class NewtonSystem:
    """The linear system of one smooth piece of the full-space Newton method (module docstring),
    per contact node (t1, t2, ν) DOFs ``cd``: Dirichlet DOFs D (all three of a sticking node, the
    normal one of a sliding node), the Robin blocks K_t = k t tᵀ on the sliding nodes' tangential
    DOFs, and the friction coupling c = μ n of a sliding node's normal row into its tangential
    rows, so that on the rows I outside D

        G = (I − C_N)(A + K_t),   (C_N y)_t = c y_ν.

    :meth:`apply` is G (the state's Newton step), :meth:`apply_transpose` its transpose on I (the
    adjoint (4.15), :mod:`contactopt.sensitivity.adjoint_fullspace`): the tangential unknowns
    enter the normal DOF through −c."""

    def __init__(self, A, cd, stick, slide, tvec, k, coupling):
        n = A.shape[0]
        self.A = A
        self.dirichlet = np.zeros(n, dtype=bool)
        self.dirichlet[cd[stick].ravel()] = True
        self.dirichlet[cd[slide, 2]] = True
        self.D = np.flatnonzero(self.dirichlet)
        self.rows = np.repeat(cd[slide, :2], 2, axis=1).ravel()        # (t1,t1),(t1,t2),(t2,t1),(t2,t2)
        self.cols = np.tile(cd[slide, :2], (1, 2)).ravel()
        self.blk = (k[:, None, None] * tvec[:, :, None] * tvec[:, None, :]).reshape(-1)
        self.kt = sp.csr_matrix((self.blk, (self.rows, self.cols)), shape=(n, n))
        self.T1, self.T2, self.Nsl = cd[slide, 0], cd[slide, 1], cd[slide, 2]
        self.c1, self.c2 = coupling[:, 0], coupling[:, 1]

    def stiffness(self, x):
        """(A + K_t) x."""
        y = self.A @ x
        if self.kt.nnz:
            y += self.kt @ x
        return y

    def couple(self, y):
        """(I − C_N) y in place: a sliding node's normal row, times c, out of its tangential rows."""
        y[self.T1] -= self.c1 * y[self.Nsl]
        y[self.T2] -= self.c2 * y[self.Nsl]
        return y

    def apply(self, x):
        """G x on the rows I (zero on D)."""
        y = self.couple(self.stiffness(x))
        y[self.D] = 0.0
        return y

    def lift(self, x):
        """x with the normal DOF of every sliding node set from its tangential ones, −cᵀx_t."""
        w = x.copy()
        w[self.Nsl] = -(self.c1 * x[self.T1] + self.c2 * x[self.T2])
        return w

    def apply_transpose(self, x):
        """Gᵀ x on the rows I, for x zero on D."""
        y = self.stiffness(self.lift(x))
        y[self.D] = 0.0
        return y

    def fine_matrix(self, hierarchy):
        """A + K_t for the V-cycle's smoother (a fresh copy)."""
        H = hierarchy.fine_matrix(self.A)
        H.data[block_positions(self.A, self.rows, self.cols)] += self.blk
        return H


class PyamgBackend:
    """:class:`~.core.NewtonBackend` on NumPy/SciPy arrays: the Newton systems as :class:`NewtonSystem`,
    solved by GMRES preconditioned by a V-cycle of the hierarchy's H = A + K_t (module
    docstring). Per contact node ``cd`` the free DOFs (t1, t2, ν); r = (A u − L)_c is the
    contact force on the body. Appends each step's Krylov iterations, residual history and
    tolerance to the lists given (those of the start solve before them)."""

    label = "full-space Newton"

    def __init__(self, A, L, cd, gap, hierarchy, H, Lnorm, restart, max_krylov, krylov_its, krylov_hist,
                 krylov_eta, shift=None):
        self.A, self.L, self.cd, self.gap, self.hierarchy, self.H = A, L, cd, gap, hierarchy, H
        self.shift = shift        # (p, 2) a load step's reference u_t: sticking u_t = shift, Robin on u_t − shift
        self.n, p = A.shape[0], cd.shape[0]
        self.Lnorm, self.restart, self.max_krylov = Lnorm, restart, max_krylov
        self.krylov_its, self.krylov_hist, self.krylov_eta = krylov_its, krylov_hist, krylov_eta
        # positions of the tangential 2×2 blocks of every contact node in A.data (Robin blocks)
        tt_rows = np.repeat(cd[:, :2], 2, axis=1).ravel()      # (t1,t1),(t1,t2),(t2,t1),(t2,t2)
        tt_cols = np.tile(cd[:, :2], (1, 2)).ravel()
        self.tt_pos = block_positions(A, tt_rows, tt_cols).reshape(p, 4)
        self.other = np.ones(self.n, dtype=bool)    # rows that must be in plain equilibrium
        self.touched = np.zeros(0, dtype=np.int64)  # entries of H holding the last Robin blocks

    def contact_force(self, u, Au_L=None):
        """r(u) = (A u − L)_c per node (t1, t2, ν), from ``Au_L`` = A u − L where given."""
        if Au_L is None:
            Au_L = self.A @ u - self.L
        return Au_L[self.cd.ravel()].reshape(-1, 3)

    def residual(self, u, z):
        other = self.other
        other[:] = True
        other[self.cd[z].ravel()] = False
        Au_L = self.A @ u - self.L
        rphys = self.contact_force(u, Au_L)
        e_other = Au_L[other]
        return rphys, u[self.cd], e_other, 0.5 * float(e_other @ e_other), float(np.linalg.norm(e_other)) / self.Lnorm

    def max_abs(self, u) -> float:
        return float(np.abs(u).max(initial=0.0))

    def newton_step(self, u, uc, stick, slide, tvec, k, coupling, eta, step):
        A, L, cd, gap, H = self.A, self.L, self.cd, self.gap, self.H
        t0 = time.perf_counter()
        system = NewtonSystem(A, cd, stick, slide, tvec, k, coupling)
        dirichlet, kt, D, Nsl = system.dirichlet, system.kt, system.D, system.Nsl
        # H = A + K_t: restore the blocks of the last step, add the new ones
        if self.touched.size:
            H.data[self.touched] = A.data[self.touched]
        pos = self.tt_pos[slide].ravel()
        H.data[pos] += system.blk
        self.touched = pos
        if self.shift is None:
            b = system.couple(L.copy())
        else:                     # the Robin rows of sliding nodes: K_t (u − shift)
            s_full = np.zeros(A.shape[0])
            s_full[cd[:, :2].ravel()] = self.shift.ravel()
            b = system.couple(L + system.kt @ s_full)
        b[D] = 0.0
        x0 = u.copy()
        x0[cd[stick, 0]] = 0.0 if self.shift is None else self.shift[stick, 0]
        x0[cd[stick, 1]] = 0.0 if self.shift is None else self.shift[stick, 1]
        x0[cd[stick, 2]] = -gap[stick]
        x0[Nsl] = -gap[slide]
        y0 = system.couple(A @ x0 + kt @ x0)    # b − G x0 on the rows I
        rhs = b - y0
        rhs[D] = 0.0
        t1 = time.perf_counter()
        Mv = self.hierarchy.preconditioner(H, dirichlet, kt)
        t2 = time.perf_counter()
        try:
            kres = gmres(system.apply, rhs, Mv, atol=eta * self.Lnorm, restart=self.restart,
                         max_iter=self.max_krylov, scale=self.Lnorm)
        except KrylovNotConverged as exc:
            exc.args = (f"full-space Newton step {step}: {exc.args[0]}",)
            raise
        t3 = time.perf_counter()
        self.krylov_its.append(kres.iterations), self.krylov_hist.append(kres.history), self.krylov_eta.append(eta)
        if self.hierarchy.reference_iterations is None:
            self.hierarchy.reference_iterations = kres.iterations
        return x0 + kres.x - u, {"newton": t1 - t0, "preconditioner": t2 - t1, "krylov": t3 - t2}

    def line(self, du, e_other):
        Adu = self.A @ du                           # r is affine in u: its contact rows give dr
        dr = Adu[self.cd.ravel()].reshape(-1, 3)
        de_other = Adu[self.other]

        def theta_other(t):
            e_t = e_other + t * de_other
            return 0.5 * float(e_t @ e_t)
        return dr, du[self.cd], theta_other

    def advance(self, u, t, du):
        return u + t * du


def solve_fullspace(A, L, contact_dofs, gap, friction, *, coords, free, r0=None, u0=None,
                    tol: float = 1e-10, hierarchy: ContactHierarchy | None = None, zone=None,
                    rho_scale: float = 0.5, max_steps: int = 50, krylov_rtol: float | None = None,
                    eta_max: float = 1e-2, eta_factor: float = 0.1, restart: int = 60,
                    max_krylov: int = 400, zone_margin: float = 0.1, amg: dict | None = None,
                    raise_on_failure: bool = True, slip_ref=None, force_scale: float | None = None,
                    polish_below: float = 0.0, stall_forcing: tuple | None = None) -> FullSpaceResult:
    """Solve the discrete Coulomb problem A u = L + Bᵀ r with the contact law on the contact nodes
    (module docstring) by a full-space semismooth Newton method with AMG-preconditioned GMRES.

    Parameters
    ----------
    A, L : stiffness (sparse SPD) and load on the free DOFs, as ``ElasticModel.assemble`` gives.
    contact_dofs : (3p,) free-DOF indices, per contact node (t1, t2, ν).
    gap : (p,) initial gaps g; friction : F (scalar or per node).
    coords, free : node coordinates (N, 3) and the free DOFs' full indices (rigid-body modes).
    r0 : (p, 3) warm start, FCLIB order (N, T1, T2) (e.g. the forces of the previous design).
    u0 : warm start of u (free DOFs); without it u0 solves A u0 = L + Bᵀ r0 (one Krylov solve).
    tol : Siconos error and relative equilibrium residual to reach.
    hierarchy : a :class:`ContactHierarchy` of an earlier A (reused); built from A if None.
    zone : node indices of the contact zone (default: all contact nodes).
    rho_scale : Alart–Curnier ρ_m = rho_scale / w̃_m, w̃_m = W_DIAG_FACTOR / mean(A_mm) + the
        coarse compliance of node m (:meth:`ContactHierarchy.coarse_compliance`), an estimate
        of tr(W_mm)/3 within 0.5–1.7 × on Example 1 and the bracket.
    max_steps : Newton steps.  krylov_rtol : the tightest Krylov tolerance (default 0.1·tol);
    the step k uses η_k = clip(eta_factor · error_k, krylov_rtol, eta_max) relative to ‖L‖, and
    krylov_rtol once error_k ≤ 0.01·√tol with the node classes of the step before.
    restart, max_krylov : GMRES restart length and iteration limit per Newton step.
    amg : keyword arguments of pyamg's smoothed_aggregation_solver when a hierarchy is built.
    raise_on_failure : raise ContactNotConverged on a Newton failure (else return converged=False).
    slip_ref : (p, 2) in a load step, u_t at the end of the previous step (the tangential law on
        u_t − slip_ref, :mod:`contactopt.sensitivity.steps`); None: the static problem.
    polish_below : one Newton step more where the iterate that meets ``tol`` has its error or
        equilibrium above this (:func:`~contactopt.contact.fullspace.core.newton_loop`); 0: none.
    stall_forcing : (eta_factor, eta_max) from the first step whose error is not below half the
        one before (:func:`~contactopt.contact.fullspace.core.newton_loop`); None: none.
    force_scale : the force the equilibrium residual and the Krylov tolerances are measured
        against when L = 0 (a press fit: :func:`~contactopt.contact.fullspace.core.overlap_force`);
        None: 1. With a load it is ‖L‖.

    OpenBLAS runs sequentially inside (:func:`contactopt._threads.sequential_openblas`): the dense
    work here is the GMRES basis products, memory-bound, and its threads competed with the sparse
    kernels (3–4× slower on the shared 2-core machine).
    """
    with sequential_openblas():
        return _solve_fullspace(A, L, contact_dofs, gap, friction, coords, free, r0, u0, tol, hierarchy,
                                zone, rho_scale, max_steps, krylov_rtol, eta_max, eta_factor, restart,
                                max_krylov, zone_margin, amg, raise_on_failure, slip_ref, force_scale, polish_below,
                                stall_forcing)


def sorted_csr(A):
    """A as a CSR matrix with sorted column indices (a copy only where they are not): the
    positions of the Robin blocks and the smoother's rows are found in A.data by them."""
    A = sp.csr_matrix(A)
    if not A.has_sorted_indices:
        A = A.copy()
        A.sort_indices()
    return A


def _solve_fullspace(A, L, contact_dofs, gap, friction, coords, free, r0, u0, tol, hierarchy, zone,
                     rho_scale, max_steps, krylov_rtol, eta_max, eta_factor, restart, max_krylov,
                     zone_margin, amg, raise_on_failure, slip_ref=None, force_scale=None, polish_below=0.0,
                     stall_forcing=None):
    t_start = time.perf_counter()
    A = sorted_csr(A)
    n = A.shape[0]
    L = np.asarray(L, dtype=np.float64)
    cd = np.asarray(contact_dofs, dtype=np.int64).reshape(-1, 3)
    p = cd.shape[0]
    gap = np.asarray(gap, dtype=np.float64)
    if L.shape != (n,) or gap.shape != (p,):
        raise ProblemDataError(f"L of shape {L.shape} / gap of shape {gap.shape} do not match A ({n}) "
                               f"and {p} contact nodes")
    st = start(friction, p, tol, krylov_rtol, zone)
    timings = st.timings
    Lnorm = float(np.linalg.norm(L)) or force_scale or 1.0

    # -- the hierarchy (reused when given)
    if hierarchy is None:
        t0 = time.perf_counter()
        hierarchy = ContactHierarchy(A, rigid_body_modes(coords, free), contact_dofs=cd.ravel(),
                                     **(amg or {}))
        timings["amg_setup"] = time.perf_counter() - t0
    elif hierarchy.n != n:
        raise SolverError(f"the AMG hierarchy is of a matrix with {hierarchy.n} rows, A has {n}")
    hierarchy.forget_updates()

    # ρ: the compliance of the body's global deformations from a coarse level of the hierarchy
    rho_all = rho_of(A.diagonal()[cd], hierarchy.coarse_compliance(cd.ravel()), rho_scale)
    H = hierarchy.fine_matrix(A)                # A + K_t for the smoother, changed in place per step

    # -- the start
    t0 = time.perf_counter()
    krylov_its, krylov_hist, krylov_eta = [], [], []
    if u0 is None:
        f = L.copy()
        if r0 is not None:
            f[cd.ravel()] += start_forces(r0, st.zone, p).ravel()        # r = 0 outside the zone
        M0 = hierarchy.preconditioner(H, np.zeros(n, dtype=bool))
        eta0 = max(st.krylov_rtol, 1e-6)
        res = gmres(A.dot, f, M0, atol=eta0 * np.linalg.norm(f), restart=restart, max_iter=max_krylov,
                    scale=np.linalg.norm(f))
        u = res.x
        krylov_its.append(res.iterations), krylov_hist.append(res.history), krylov_eta.append(eta0)
        if hierarchy.reference_iterations is None:
            hierarchy.reference_iterations = res.iterations
    else:
        u = np.array(u0, dtype=np.float64)
        if u.shape != (n,):
            raise ProblemDataError(f"u0 of shape {u.shape}, expected ({n},)")
    timings["start"] = time.perf_counter() - t0

    shift = None if slip_ref is None else np.asarray(slip_ref, dtype=np.float64).reshape(p, 2)
    backend = PyamgBackend(A, L, cd, gap, hierarchy, H, Lnorm, restart, max_krylov, krylov_its, krylov_hist,
                           krylov_eta, shift)
    out = newton_loop(backend, u, st.zone, gap=gap, mu_all=st.mu, rho_all=rho_all, tol=tol, max_steps=max_steps,
                      krylov_rtol=st.krylov_rtol, eta_max=eta_max, eta_factor=eta_factor, zone_margin=zone_margin,
                      timings=timings, t_start=t_start, shift=shift, polish_below=polish_below,
                      stall_forcing=stall_forcing)
    classes = out.classes
    return finish(backend, out, u_c=out.u[cd].copy(), tol=tol, t_start=t_start, timings=timings,
                  krylov_iterations=krylov_its, raise_on_failure=raise_on_failure, krylov_histories=krylov_hist,
                  krylov_rtol=krylov_eta, hierarchy=hierarchy,
                  info={"levels": hierarchy.sizes(), "operator_complexity": hierarchy.operator_complexity,
                        "class_counts": {"open": int(np.sum(classes == OPEN)), "stick": int(np.sum(classes == STICK)),
                                         "slide": int(np.sum(classes == SLIDE))},
                        "start_solve": u0 is None})


# ----------------------------------------------------------------------------- the fallback chain
DIAGNOSIS_MAX_DOFS = 30000      # largest A factorized to form W for a diagnosis (no fallback converged)
_DIAGNOSIS_BLOCK = 256          # columns of W per block of solves (n × 256 doubles at a time)
LOAD_CONTINUATION = (0.25, 0.5, 0.75, 1.0)


class FullSpaceProblem:
    """The full-space Newton method as a :class:`contactopt.contact.fallback.FallbackProblem`:
    the chain of :func:`contactopt.contact.fallback.run_chain` with the parts that apply without
    a Delassus operator (:data:`contactopt.contact.fallback.FULLSPACE_FALLBACKS`):

    * ``cold restart``: from nothing, without the warm start of r, u and the zone;
    * ``friction continuation``: F·t for t = 0, 1/4, 1/2, 3/4, 1, each from the displacement of
      the one before (with friction only);
    * ``load continuation``: the load t·L for t = 1/4, 1/2, 3/4, 1, each from the last.

    ``options``: the keyword arguments of :func:`solve_fullspace` (A, L, the contact DOFs per node
    (t1, t2, ν), the gap, F, the warm starts r0 in FCLIB order (N, T1, T2) and u0). Each attempt
    is bounded by the same ``max_steps`` (per step of a continuation) and reuses the AMG hierarchy
    of the first. The diagnosis names a penetrating start and, on at most
    :data:`DIAGNOSIS_MAX_DOFS` free DOFs, forms W = B A⁻¹ Bᵀ (FCLIB order) from a factorization
    of A for :func:`contactopt.contact.fallback.diagnose` (which checks its eigenvalues on up to
    2000 contact nodes)."""

    def __init__(self, A, L, contact_dofs, gap, friction, *, what: str = "the contact state (full space)", **options):
        self.A, self.L, self.contact_dofs, self.gap, self.friction = A, L, contact_dofs, gap, friction
        self.options, self.what = options, what
        self.tol = options.get("tol", 1e-10)
        warm = any(options.get(k) is not None for k in ("r0", "u0", "zone"))
        self.first_name = "full-space Newton" + (" from the warm start" if warm else "")
        self.hierarchy = options.get("hierarchy")

    def _solve(self, *, L=None, friction=None, **over):
        kw = {**self.options, "hierarchy": self.hierarchy, **over, "raise_on_failure": False}
        res = solve_fullspace(self.A, self.L if L is None else L, self.contact_dofs, self.gap,
                              self.friction if friction is None else friction, **kw)
        self.hierarchy = res.hierarchy
        return res

    def first(self):
        return self._solve()

    def attempts(self):
        cold = dict(r0=None, u0=None, zone=None)
        if any(self.options.get(k) is not None for k in cold):
            yield "cold restart", lambda: self._solve(**cold)

        def continuation(scales, of):
            res, total = None, 0
            for t in scales:
                res = self._solve(**of(t), r0=None, zone=None, u0=None if res is None else res.u)
                total += res.newton_steps
            res.newton_steps = total
            return res
        mu = np.asarray(self.friction, dtype=float)
        if float(np.max(mu)) > 0:
            yield "friction continuation", lambda: continuation((0.0, 0.25, 0.5, 0.75, 1.0),
                                                                of=lambda t: {"friction": mu * t})
        yield "load continuation", lambda: continuation(LOAD_CONTINUATION, of=lambda t: {"L": self.scaled_load(t)})

    def scaled_load(self, t: float):
        """t·L, the load of a step of the load continuation."""
        return np.asarray(self.L, dtype=float) * t

    def steps(self, result) -> int:
        return result.newton_steps

    def stop(self, result) -> str:
        return result.reason or f"Siconos error {result.error:.2e}, equilibrium {result.equilibrium:.2e}"

    def converged_by(self, result, name, spent):
        result.fallback, result.fallback_iterations = name, spent
        return result

    def diagnose(self, best) -> str:
        A = sp.csc_matrix(self.A)
        gap = np.asarray(self.gap, dtype=float)
        cd = np.asarray(self.contact_dofs, dtype=np.int64).reshape(-1, 3)
        if A.shape[0] > DIAGNOSIS_MAX_DOFS:
            found = penetrating_start(gap)
            return "The model: " + "; ".join(found or [
                f"no penetrating start; A has {A.shape[0]} free DOFs, too many to form W for the check of a rigid "
                "motion or an unbalanced load: check body.clamped, the loads and the initial gap"]) + "."
        try:
            lu = sla.splu(A)
        except RuntimeError:            # A exactly singular: the clamps leave a motion free
            return ("The model: " + "; ".join(penetrating_start(gap) + [
                "a rigid motion: the stiffness A is singular, so the body is not held in some direction; check "
                "body.clamped (a support or a symmetry plane missing)"]) + ".")
        order = cd[:, [2, 0, 1]].ravel()                    # FCLIB order (ν, t1, t2) per node
        W = np.empty((order.size, order.size))
        for j in range(0, order.size, _DIAGNOSIS_BLOCK):     # W = B A⁻¹ Bᵀ, a block of columns at a time
            cols = order[j:j + _DIAGNOSIS_BLOCK]
            E = np.zeros((A.shape[0], cols.size))
            E[cols, np.arange(cols.size)] = 1.0
            W[:, j:j + cols.size] = lu.solve(E)[order]
        q = lu.solve(np.asarray(self.L, dtype=float))[order]
        q[0::3] += gap
        shift = self.options.get("slip_ref")
        if shift is not None:
            s = np.asarray(shift, dtype=float).reshape(-1, 2)
            q[1::3] -= s[:, 0]
            q[2::3] -= s[:, 1]
        return diagnose(W, q, self.friction, gap=gap)


def solve_fullspace_with_fallbacks(A, L, contact_dofs, gap, friction, **options) -> FullSpaceResult:
    """:func:`solve_fullspace` and, where it does not converge, the fallback chain of
    :class:`FullSpaceProblem`: a converged state (``fallback`` names the path that reached it,
    None when the first did) or :class:`~contactopt.errors.ContactNotConverged` with the
    diagnosis of the model. A solve that converges at once is :func:`solve_fullspace`'s, bit for bit."""
    return run_chain(FullSpaceProblem(A, L, contact_dofs, gap, friction, **options))
