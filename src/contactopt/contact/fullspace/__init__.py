"""Full-space semismooth Newton for the discrete Coulomb problem, with AMG-preconditioned Krylov
solves: the state solver for meshes where no factorization of A(α) fits (≥ 900k DOFs).

Problem (paper (3.17)/(3.18), the same as the condensation path's, :mod:`contactopt.paths.condensation`).
On the free DOFs, with B selecting the contact DOFs (``contact_dofs``: per contact node m the DOFs
(t1, t2, ν) = (x1, x2, x3); the foundation x3 ≤ 0 has normal e3),

    A u = L + Bᵀ r,     r per node (t1, t2, ν) the contact force on the body,
    λ = r_ν ≥ 0,  τ = −r_t,  u_ν + g ≥ 0,  λ(u_ν + g) = 0,  ‖τ‖ ≤ Fλ,  u_t ≠ 0 ⇒ τ = Fλ u_t/‖u_t‖.

Nothing is condensed: the unknown is u on all free DOFs, and r is *defined* by the equilibrium of
the contact rows, r := B(A u − L); the other rows must satisfy (A u − L)_j = 0. The contact law is
written in the FCLIB convention of :mod:`contactopt.contact.newton` (normal first): per node
R = (r_ν, r_t1, r_t2) = (λ, −τ) and U = (u_ν + g, u_t1, u_t2), friction law R_T = −μ R_N U_T/‖U_T‖;
the Alart–Curnier function (:func:`contactopt.contact.newton.alart_curnier`)

    x_N = R_N − ρ U_N,  x_T = R_T − ρ U_T,  Φ_N = R_N − max(0, x_N),  Φ_T = R_T − P_{D(μ max(0, x_N))}(x_T)

vanishes exactly at the solutions. Nodes outside the contact zone (default: none — in full space a
node without contact costs nothing, its rows are natural boundary rows) carry r = 0.

Newton step. On each smooth piece of Φ, the Newton equation Φ + Φ'·(Δu) = 0 is *linear in the new
iterate* u⁺ (the piece's data ρ, n, c frozen at the current iterate), per node class:

* open (x_N ≤ 0): R⁺ = 0 — the node's rows are plain equilibrium rows (natural boundary);
* stick (x_N > 0, ‖x_T‖ ≤ μ x_N): U⁺ = 0, i.e. u⁺_c = (0, 0, −g): three Dirichlet DOFs;
* slide (x_N > 0, ‖x_T‖ > μ x_N), in the frame (n, t) of the tangent plane with n = x_T/‖x_T‖,
  t ⊥ n, c = μ x_N/‖x_T‖ < 1: u⁺_ν = −g (Dirichlet), R⁺_n = μ R⁺_N (the friction force of the
  normal reaction, along n) and (1 − c) R⁺_t + c ρ U⁺_t = 0, a Robin condition
  R⁺_t = −k U⁺_t with k = cρ/(1 − c) ≥ 0 (at the solution k = Fλ/‖u_t‖, the C of the adjoint).

With D the Dirichlet DOFs (three per sticking node, the normal one per sliding node) and I the
others, substituting R⁺ = B(A u⁺ − L) into the rows I gives one linear system for u⁺_I,

    G u⁺ = L − μ N L  on I,   u⁺_D prescribed,   G = A + K_t − μ N A,

where K_t adds k t tᵀ on the tangential DOFs of a sliding node and N copies the normal row of a
sliding node, times n, into its tangential rows. G is non-symmetric (the friction coupling μ N A)
and sparse (A plus a few rows): it is applied as A x + K_t x (K_t: 2×2 blocks at the sliding
nodes) with a correction of the sliding tangential rows. Each step is solved by right-
preconditioned restarted GMRES (flexible: it keeps the preconditioned directions), warm-started at
the current iterate, to a relative residual η_k (inexact Newton: 0.1·error while the error is
large, ``krylov_rtol`` once it is below 0.01·√tol and the node classes have settled),
preconditioned by a V-cycle of H = A + K_t restricted to I:

* the smoothed-aggregation hierarchy (pyamg, rigid-body modes as near-null space) of an A(α_ref)
  — of this design, or of an earlier one: :class:`ContactHierarchy`, reused over Newton steps and
  nearby designs, never rebuilt inside a solve;
* the fine level smooths H itself by Gauss–Seidel on the rows I only (x_D = 0 kept);
* the coarse operators are the Galerkin products (Π P)ᵀ H (Π P) of the prolongation with the D
  rows removed (Π), obtained from the stored ones of A(α_ref) by sparse updates supported near D
  and the sliding nodes (the fine matrix differs from A(α_ref) only there, up to the design
  change), so no full triple product is redone per step (docs/large_meshes.md: as few
  iterations as a fresh hierarchy of the constrained matrix).

Globalization: Armijo backtracking on the merit ½‖Φ‖² along u + t(u⁺ − u) (non-monotone over the
last four values, as in :mod:`contactopt.contact.newton`); r is affine in u, so a trial step costs
one product with the contact rows of A. ρ per node is ``rho_scale`` / w̃_m with w̃_m ≈ 2/mean(A_mm)
an estimate of the Delassus diagonal tr(W_mm)/3 (docs/large_meshes.md).

Convergence: the Siconos error ‖R − P_K(R − Ũ)‖ / max(‖R‖, ‖U‖) on the zone ≤ ``tol`` and the
equilibrium of the other rows ‖(A u − L)_other‖ / ‖L‖ ≤ ``tol``. A Newton or Krylov failure raises
:class:`contactopt.errors.ContactNotConverged` / :class:`contactopt.fem.krylov.KrylovNotConverged`
(both SolverErrors) with their histories, never an inaccurate state. With a zone smaller than all
contact nodes, a converged state whose outside nodes close their gap grows the zone (as
:mod:`contactopt.contact.zone` does) and Newton continues from the current iterate.

One package, two linear-algebra backends. What does not depend on how vectors and matrices are
stored is :mod:`.core`: the options and start-up of a solve, the iteration itself (stopping test,
zone growth, ρ rescaling, forcing term, line search: :func:`newton_loop`), the one result type
:class:`FullSpaceResult`, and the adjoint's sliding frame (:func:`sliding_frame`). A backend
(:class:`NewtonBackend`) gives the residual, the Newton system and the update: :mod:`.pyamg` on
NumPy/SciPy arrays with a pyamg V-cycle (:func:`solve_fullspace`), :mod:`.petsc` on PETSc objects
over MPI ranks (:class:`~contactopt.contact.fullspace.petsc.PetscNewton`; imported only where
PETSc runs).
"""

from .core import (
                   OPEN,
                   SLIDE,
                   STICK,
                   W_DIAG_FACTOR,
                   FullSpaceResult,
                   NewtonBackend,
                   NewtonOutcome,
                   newton_loop,
                   sliding_frame,
)
from .pyamg import FullSpaceProblem, NewtonSystem, solve_fullspace, solve_fullspace_with_fallbacks

__all__ = ("solve_fullspace", "solve_fullspace_with_fallbacks", "FullSpaceProblem", "FullSpaceResult", "NewtonSystem", "newton_loop", "NewtonBackend",
           "NewtonOutcome", "sliding_frame", "OPEN", "STICK", "SLIDE", "W_DIAG_FACTOR")
