"""The two bodies' V-cycle in the bodies' own coordinates (contactopt.fem.amg, docs/scaling.md, "Two
bodies at scale on one process"): the first coarse space is T⁻¹ times each body's own, and the
sweeps on the band coupling the bodies correct in the basis Z = T⁻¹ (off the held contact DOFs),
in which the two bodies' system is each body's stiffness again; fewer Krylov iterations per
evaluation for the same answer.

Conventions: per contact node (t1, t2, ν); the contact DOFs of u_loc hold w = u_body − u_partner.
"""

import numpy as np
import pytest
import scipy.sparse as sp

from contactopt.fem.krylov import gmres
from test_two_body_scale import two_body_problem


@pytest.fixture(scope="module")
def two_bodies():
    return two_body_problem()


def test_the_first_coarse_space_is_each_body_s_own(two_bodies):
    """T P_0: every coarse unknown moves one body only (P_0 = T⁻¹ P_B, P_B the smoothed
    aggregation of diag(A, K_f) per body), so that with nothing held the first coarse operator is
    the two bodies' own, P_Bᵀ diag(A, K_f) P_B."""
    pb, A, h = two_bodies
    nb = pb.model.assembler.n_free
    TP = sp.csr_matrix(pb.path.couple.T @ sp.csr_matrix(h.P[0], dtype=np.float64)).tocoo()
    body = TP.row < nb
    on_body = np.bincount(TP.col[body], weights=np.abs(TP.data[body]), minlength=TP.shape[1])
    on_slab = np.bincount(TP.col[~body], weights=np.abs(TP.data[~body]), minlength=TP.shape[1])
    assert np.all(np.minimum(on_body, on_slab) <= 1e-5 * np.maximum(on_body, on_slab))
    assert np.any(on_body > 0) and np.any(on_slab > 0)


def test_the_band_is_smoothed_in_the_bodies_own_coordinates(two_bodies):
    """With nothing held, the band's matrix in the basis Z_J (Z = T⁻¹ without the frames' rotation)
    has no entry between the body's DOFs and the slab's: Z_Jᵀ H_JJ Z_J is each body's stiffness,
    where the two bodies' system couples every contact DOF with its partners."""
    pb, A, h = two_bodies
    nb = pb.model.assembler.n_free
    n = A.shape[0]
    J, Z, HJ, Hy = h.band_basis(h.fine_matrix(A), np.zeros(n, dtype=bool))
    assert np.array_equal(J, h.interface)
    Hy = sp.csr_matrix(Hy, dtype=np.float64).tocoo()
    cross = (J[Hy.row] < nb) != (J[Hy.col] < nb)
    assert np.abs(Hy.data[cross]).max(initial=0.0) <= 1e-5 * np.abs(Hy.data).max()
    AJ = sp.csr_matrix(A[J][:, J]).tocoo()
    assert np.abs(AJ.data[(J[AJ.row] < nb) != (J[AJ.col] < nb)]).max() > 0.05 * np.abs(AJ.data).max()


def test_fewer_krylov_iterations_for_the_same_evaluation(two_bodies):
    """GMRES on the two bodies' system (3,996 unknowns) with nothing held: 13 iterations to 1e-10
    (21 with the coarse space and the band's sweeps in the unknowns u_loc); one evaluation at α0:
    51 Krylov iterations of the state over 6 Newton steps and 18 of the adjoint (69 and 24), the
    same Θ (measured)."""
    pb, A, h = two_bodies
    n = A.shape[0]
    b = np.random.default_rng(3).standard_normal(n)
    res = gmres(A.dot, b, h.preconditioner(h.fine_matrix(A), np.zeros(n, dtype=bool)), rtol=1e-10,
                restart=60, max_iter=300)
    assert np.linalg.norm(A @ res.x - b) <= 1.1e-10 * np.linalg.norm(b)
    assert res.iterations <= 15, res.iterations
    r = pb.subgradient(pb.model.initial_design())
    st = r.state
    assert st.info["krylov_iterations"] <= 58 and st.info["adjoint_krylov"] <= 20, st.info
    assert r.value == pytest.approx(4.954575375988e-05, rel=1e-10)


def test_the_bodies_matrix_is_the_products_and_the_strength_pattern_gives_pyamg_s_aggregates(two_bodies):
    """``bodies_matrix`` (A + Δ near the contact DOFs) against T⁻ᵀ A T⁻¹ formed by two products of
    the whole matrix: the same matrix to round-off, no entry between the bodies; and the
    aggregates of ``strength_pattern`` (A's own pattern) against those of pyamg's symmetric
    strength of connection at θ = 0, on the bodies' matrix and on the system."""
    from pyamg.aggregation.aggregate import standard_aggregation
    from pyamg.strength import symmetric_strength_of_connection

    from contactopt.fem.amg import bodies_matrix, body_label, strength_pattern
    pb, A, h = two_bodies
    couple = pb.path.couple
    Tinv = couple.inverse()
    asm = pb.model.assemble(pb.model.initial_design(), pb.path.first_loads)
    label = body_label(np.asarray(couple.T @ couple.modes(asm.coords, pb.model.assembler.free)), 6)
    Bm = bodies_matrix(A, Tinv, label)
    ref = sp.csr_matrix(Tinv.T @ sp.csr_matrix(A @ Tinv)).tocoo()
    same = label[ref.row] == label[ref.col]
    assert np.abs(ref.data[~same]).max(initial=0.0) <= 1e-12 * np.abs(ref.data).max()      # round-off only
    ref = sp.csr_matrix((ref.data[same], (ref.row[same], ref.col[same])), shape=A.shape)
    assert abs(Bm - ref).max() <= 1e-14 * abs(ref).max()
    coo = Bm.tocoo()
    assert np.all(label[coo.row] == label[coo.col]) and np.all(coo.data != 0)
    assert abs(Bm - Bm.T).max() <= 1e-14 * abs(Bm).max()
    for M in (Bm, sp.csr_matrix(A)):
        M.sort_indices()
        ours, _ = standard_aggregation(strength_pattern(M))
        theirs, _ = standard_aggregation(symmetric_strength_of_connection(M))
        assert ours.shape == theirs.shape and (sp.csr_matrix(ours) != sp.csr_matrix(theirs)).nnz == 0
