"""The two bodies' Newton system on the full-space path and its AMG hierarchy
(contactopt.paths.coupled, contactopt.fem.amg): the system formed near the contact DOFs agrees
with the product Tᵀ diag(A, K_f) T, and the hierarchy that gives each aggregate the near-null
columns of its own body only has about half the coarse unknowns of pyamg's with all twelve and
preconditions as well.

Conventions: per contact node (t1, t2, ν); the contact DOFs of u_loc hold w = u_body − u_partner.
"""

import numpy as np
import pytest
import scipy.sparse as sp

from contactopt.config import load_config
from contactopt.fem.amg import ContactHierarchy
from contactopt.fem.krylov import gmres
from contactopt.paths.fullspace import HIERARCHY_SEED
from contactopt.problem import ShapeProblem

E_BODY = 21.19


def _problem(partner):
    foundation = {"block": {"size": [3.0, 2.0, 1.0], "cells": [12, 8, 4], "origin": [-0.5, -0.5],
                            "element": "hexahedron"}, "partner": partner, "material": {"E": E_BODY / 10}}
    cfg = load_config("example1").with_updates({"mesh": {"nx": 16, "ny": 8, "nz": 5}, "foundation": foundation,
                                                "linear_solver": {"path": "fullspace"}})
    return ShapeProblem(cfg)


@pytest.mark.parametrize("partner", ["point", "mortar"])
def test_the_system_formed_near_the_contact_dofs_is_the_product(partner):
    pb = _problem(partner)
    path, m = pb.path, pb.model
    asm = m.assemble(m.initial_design(), path.first_loads)
    couple = path.couple
    law_A, law_L = couple.system(asm.A, asm.L)
    big = sp.block_diag([asm.A] + [part.K for part in couple.parts], format="csr")
    ref = sp.csr_matrix(couple.T.T @ big @ couple.T)
    assert abs(law_A - ref).max() <= 1e-14 * abs(ref).max()
    assert np.allclose(law_L, couple.T.T @ couple.load(asm.L), rtol=0, atol=1e-14 * np.abs(law_L).max())
    law_A.check_format(full_check=True)
    copy = law_A.copy()
    copy.sort_indices()
    assert np.array_equal(copy.indices, law_A.indices)          # sorted as it says
    cd = m.contact_dofs.reshape(-1, 3)
    rows, cols = np.repeat(cd, 3, axis=1).ravel(), np.tile(cd, (1, 3)).ravel()
    pattern = law_A.copy()
    pattern.data[:] = 1.0
    assert np.all(np.asarray(pattern[rows, cols]).ravel() == 1.0)   # every contact block in the pattern


def test_aggregates_take_the_near_null_columns_of_their_own_body():
    pb = _problem("point")
    path, m = pb.path, pb.model
    alpha = m.initial_design()
    asm = m.assemble(alpha, path.first_loads)
    A = path.prepare(asm).law_A
    own = path.build_hierarchy(alpha, asm)
    modes = path.couple.modes(asm.coords, m.assembler.free)
    saved = np.random.get_state()
    np.random.seed(HIERARCHY_SEED)
    try:
        every = ContactHierarchy(A, modes, contact_dofs=m.contact_dofs)    # pyamg, twelve columns everywhere
    finally:
        np.random.set_state(saved)
    n1_own, n1_every = own.sizes()[1], every.sizes()[1]
    assert n1_every % 12 == 0 and n1_own <= 0.65 * n1_every
    for P in own.P:                                       # no coarse unknown without a column
        assert np.all(np.bincount(P.indices, minlength=P.shape[1]) > 0)
    # preconditioning: GMRES on the two bodies' system, nothing held at the contact
    b = np.random.default_rng(3).standard_normal(A.shape[0])
    none = np.zeros(A.shape[0], dtype=bool)
    its = {}
    for name, h in (("own", own), ("every", every)):
        res = gmres(A.dot, b, h.preconditioner(h.fine_matrix(A), none), rtol=1e-10, restart=60, max_iter=300)
        assert np.linalg.norm(A @ res.x - b) <= 1.1e-10 * np.linalg.norm(b)
        its[name] = res.iterations
    assert its["own"] <= its["every"] + 2, its
