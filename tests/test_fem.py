"""Finite-element foundation: patch test, rigid modes, convergence rates, design derivatives."""

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from contactopt.config import load_config
from contactopt.design.bezier import BezierSurface
from contactopt.fem.elasticity import ElasticityAssembler, element_geometry, gauss_hex, hex_shape, lame
from contactopt.fem.model import ElasticModel
from contactopt.fem.weight import block_hexmesh

E, NU = 21.19, 0.277


def curved_mesh(nx, ny, nz, seed=0):
    surf = BezierSurface(3, 2, 2.0, 1.0)
    alpha = 0.05 + 0.25 * np.random.default_rng(seed).random(surf.size)
    mesh = block_hexmesh(nx, ny, nz, surf, 1.0)
    return mesh, mesh.coordinates(alpha)


def boundary_nodes(mesh):
    i = np.rint(mesh.ref_coords[:, 0] / mesh.surface.a * mesh.nx)
    j = np.rint(mesh.ref_coords[:, 1] / mesh.surface.b * mesh.ny)
    k = np.rint(mesh.ref_coords[:, 2] * mesh.nz)
    return (i == 0) | (i == mesh.nx) | (j == 0) | (j == mesh.ny) | (k == 0) | (k == mesh.nz)


def solve_dirichlet(asm, X, bnd, g_values, f_full):
    """Solve A u = f with u = g on the boundary nodes (all components)."""
    A = asm.full_stiffness(X).tocsr()
    fixed = np.repeat(bnd, 3)
    u = np.zeros(A.shape[0])
    u[fixed] = g_values.ravel()[fixed]
    free = ~fixed
    rhs = f_full[free] - A[free][:, fixed] @ u[fixed]
    u[free] = spla.spsolve(A[free][:, free].tocsc(), rhs)
    return u


def test_patch_test_linear_field_on_curved_mesh():
    mesh, X = curved_mesh(6, 4, 3)
    asm = ElasticityAssembler(mesh.elements, mesh.n_nodes, [], E, NU)
    rng = np.random.default_rng(1)
    M, c = rng.standard_normal((3, 3)), rng.standard_normal(3)
    exact = X @ M.T + c
    bnd = boundary_nodes(mesh)
    u = solve_dirichlet(asm, X, bnd, exact, np.zeros(3 * mesh.n_nodes))
    assert np.abs(u.reshape(-1, 3) - exact).max() < 1e-10 * np.abs(exact).max()


def test_element_has_six_rigid_modes_and_reduced_matrix_is_spd():
    mesh, X = curved_mesh(3, 2, 2)
    asm = ElasticityAssembler(mesh.elements, mesh.n_nodes, [], E, NU)
    Ke = asm.element_matrices(X[mesh.elements])
    for e in range(Ke.shape[0]):
        ev = np.linalg.eigvalsh(Ke[e])
        assert np.sum(np.abs(ev) < 1e-10 * ev.max()) == 6
        assert ev[6] > 1e-4 * ev.max()
    clamped = mesh.node_sets["clamped"]
    asm2 = ElasticityAssembler(mesh.elements, mesh.n_nodes, (3 * clamped[:, None] + np.arange(3)).ravel(), E, NU)
    A = asm2.stiffness(X).toarray()
    assert np.abs(A - A.T).max() < 1e-13 * np.abs(A).max()
    assert np.linalg.eigvalsh(A).min() > 0


# ---- manufactured solution: u_i = Π_m sin(k_im x_m + φ_im)
K = np.array([[0.9, 1.3, 0.7], [1.1, 0.6, 1.4], [0.5, 1.2, 1.0]])
PHI = np.array([[0.3, 0.2, 0.5], [0.1, 0.4, 0.25], [0.6, 0.35, 0.15]])


def u_exact(x):
    return np.stack([np.prod(np.sin(K[i] * x + PHI[i]), axis=-1) for i in range(3)], axis=-1)


def grad_exact(x):
    """H[..., i, j] = ∂u_i/∂x_j."""
    s, c = np.sin(K[None] * x[:, None, :] + PHI[None]), np.cos(K[None] * x[:, None, :] + PHI[None])
    H = np.empty(x.shape[:1] + (3, 3))
    for j in range(3):
        f = s.copy()
        f[:, :, j] = K[None, :, j] * c[:, :, j]
        H[:, :, j] = np.prod(f, axis=2)
    return H


def hess_exact(x):
    """T[..., i, j, l] = ∂²u_i/∂x_j∂x_l."""
    s, c = np.sin(K[None] * x[:, None, :] + PHI[None]), np.cos(K[None] * x[:, None, :] + PHI[None])
    T = np.empty(x.shape[:1] + (3, 3, 3))
    for j in range(3):
        for l in range(3):
            f = s.copy()
            if j == l:
                f[:, :, j] = -K[None, :, j] ** 2 * s[:, :, j]
            else:
                f[:, :, j] = K[None, :, j] * c[:, :, j]
                f[:, :, l] = K[None, :, l] * c[:, :, l]
            T[:, :, j, l] = np.prod(f, axis=2)
    return T


def body_force(x):
    lam, mu = lame(E, NU)
    T = hess_exact(x)
    div_grad = np.einsum("nkki->ni", T)          # ∂_i (div u)
    lap = np.einsum("nijj->ni", T)
    return -(lam * div_grad + mu * (lap + div_grad))


def test_convergence_rates_manufactured_solution():
    lam, mu = lame(E, NU)
    qf, wf = gauss_hex(3)
    Nf, dNf = hex_shape(qf)
    q2, w2 = gauss_hex(2)
    N2, dN2 = hex_shape(q2)
    hs, l2, en = [], [], []
    for n in (2, 4, 8, 16):
        mesh, X = curved_mesh(2 * n, n, n, seed=3)
        asm = ElasticityAssembler(mesh.elements, mesh.n_nodes, [], E, NU)
        Xe = X[mesh.elements]
        # consistent load of the body force with a 3×3×3 rule
        _, det = element_geometry(Xe, dNf)
        xq = np.einsum("qa,eam->eqm", Nf, Xe)
        fq = body_force(xq.reshape(-1, 3)).reshape(xq.shape)
        fe = np.einsum("q,qa,eq,eqm->eam", wf, Nf, det, fq)
        f = np.zeros((mesh.n_nodes, 3))
        for m in range(3):
            f[:, m] = np.bincount(mesh.elements.ravel(), fe[:, :, m].ravel(), minlength=mesh.n_nodes)
        bnd = boundary_nodes(mesh)
        u = solve_dirichlet(asm, X, bnd, u_exact(X), f.ravel())
        ue = u.reshape(-1, 3)[mesh.elements]
        G, det = element_geometry(Xe, dNf)
        err = np.einsum("qa,eam->eqm", Nf, ue) - u_exact(xq.reshape(-1, 3)).reshape(xq.shape)
        l2.append(np.sqrt(np.einsum("q,eq,eqm->", wf, det, err ** 2)))
        Hh = np.einsum("eai,eqaj->eqij", ue, G)
        He = Hh - grad_exact(xq.reshape(-1, 3)).reshape(Hh.shape)
        eps = 0.5 * (He + np.swapaxes(He, -1, -2))
        tr = np.einsum("eqii->eq", eps)
        energy = 2 * mu * np.einsum("eqij,eqij->eq", eps, eps) + lam * tr ** 2
        en.append(np.sqrt(np.einsum("q,eq,eq->", wf, det, energy)))
        hs.append(1.0 / n)
    rate_l2 = np.polyfit(np.log(hs), np.log(l2), 1)[0]
    rate_en = np.polyfit(np.log(hs), np.log(en), 1)[0]
    assert abs(rate_l2 - 2.0) < 0.15, (rate_l2, l2)
    assert abs(rate_en - 1.0) < 0.15, (rate_en, en)


def small_model(**loads):
    cfg = load_config("example1").with_updates({
        "mesh": {"nx": 6, "ny": 3, "nz": 3},
        "loads": {"right_traction": [-0.05, 0.02, 0.03], "body_force": [0.01, -0.02, -0.03], **loads}})
    return ElasticModel(cfg)


@pytest.mark.parametrize("k", [0, 9, 30])
def test_design_derivatives_match_central_differences(k):
    model = small_model()
    rng = np.random.default_rng(k)
    alpha = 0.02 + 0.1 * rng.random(model.n_design)
    asm = model.assembler
    u = asm.to_full(rng.standard_normal(asm.n_free))
    v = asm.to_full(rng.standard_normal(asm.n_free))
    X = model.mesh.coordinates(alpha)
    pred = model.design_contraction(X, u, v)[k]
    h = 1e-5
    e = np.zeros(model.n_design)
    e[k] = h
    p, m = model.assemble(alpha + e), model.assemble(alpha - e)
    fd = (v[asm.free] @ ((p.A - m.A) @ u[asm.free]) - v @ (p.L_full - m.L_full)) / (2 * h)
    assert abs(pred - fd) <= 1e-6 * abs(fd)


def test_load_derivative_alone_matches_central_differences():
    model = small_model()
    alpha = np.full(model.n_design, 0.05)
    alpha[-4:] = [0.1, 0.2, 0.15, 0.05]
    v = np.random.default_rng(5).standard_normal(3 * model.mesh.n_nodes)
    X = model.mesh.coordinates(alpha)
    pred = -model.design_contraction(X, np.zeros_like(v), v)
    h = 1e-5
    for k in (28, 30):
        e = np.zeros(model.n_design)
        e[k] = h
        fd = v @ (model.assemble(alpha + e).L_full - model.assemble(alpha - e).L_full) / (2 * h)
        assert abs(fd) > 1e-6
        assert abs(pred[k] - fd) <= 1e-6 * abs(fd)


def test_parallel_assembly_equals_one_chunk_and_names_inverted_elements_globally(monkeypatch):
    # Example 1's mesh (4320 elements) is assembled in one chunk per core; the matrices do not
    # depend on the split, and an inverted element is named by its index in the whole mesh
    from contactopt.errors import MeshError
    from contactopt.fem import elasticity
    model = ElasticModel(load_config("example1"))
    asm = model.assembler
    coords = model.mesh.coordinates(model.initial_design())
    monkeypatch.setattr(elasticity, "_assembly_chunks", lambda n: 3)
    A3 = asm.stiffness(coords)
    monkeypatch.setattr(elasticity, "_assembly_chunks", lambda n: 1)
    A1 = asm.stiffness(coords)
    assert np.array_equal(A3.data, A1.data) and np.array_equal(A3.indices, A1.indices)
    bad = coords.copy()
    e = 4000                                    # in the last of three chunks
    a, b = asm.elements[e, 0], asm.elements[e, 6]
    bad[[a, b]] = bad[[b, a]]                   # swap two opposite corners: det J < 0
    monkeypatch.setattr(elasticity, "_assembly_chunks", lambda n: 3)
    with pytest.raises(MeshError, match=r"element\(s\) inverted") as exc:
        asm.stiffness(bad)
    assert str(exc.value).startswith("1 element(s)") and str(exc.value).endswith(f"[{e}]")


def test_parallel_assembly_in_a_forked_child():
    # worker threads do not survive fork: a child process must assemble with its own pool. The
    # parent is a fresh interpreter whose only threads are its own and the assembly's idle pool, as
    # in a run that forks (io/forked.py), not this test process with whatever native thread pools
    # earlier tests left behind. Both assemble as a state solve does, on one OpenBLAS thread (the
    # element kernels' products round differently when OpenBLAS splits them over threads).
    import os
    import subprocess
    import sys
    if not hasattr(os, "fork"):
        pytest.skip("no fork on this platform")
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, "-c", _FORKED_ASSEMBLY], env=env, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    threads, verdict = proc.stdout.split()
    from contactopt.fem import elasticity
    if elasticity._assembly_chunks(4320) > 1:         # Example 1's mesh is assembled in parallel here
        assert int(threads.split(":")[1]) >= 1
    assert verdict == "same"


_FORKED_ASSEMBLY = """
import os, threading
import numpy as np
from contactopt.config import load_config
from contactopt.fem.model import ElasticModel

def stiffness_data():
    model = ElasticModel(load_config("example1"))
    return model.assemble(model.initial_design()).A.data

parent = stiffness_data()                     # the parent's pool exists now
pool = [t for t in threading.enumerate() if t.name.startswith("contactopt-assembly")]
print(f"pool-threads-before-fork:{len(pool)}")
read, write = os.pipe()
pid = os.fork()
if pid == 0:
    code = 1
    try:
        os.close(read)
        with os.fdopen(write, "wb") as pipe:
            pipe.write(stiffness_data().tobytes())
        code = 0
    finally:
        os._exit(code)
os.close(write)
with os.fdopen(read, "rb") as pipe:
    child = np.frombuffer(pipe.read(), dtype=parent.dtype)
_, status = os.waitpid(pid, 0)
print("same" if status == 0 and np.array_equal(child, parent) else f"differ status={status}")
"""
