"""B-bar hexahedra (the dilatation replaced by its element mean) for nearly incompressible
materials: the element matrix against Hughes' B̄ built by hand, a patch test on a distorted mesh,
convergence rates at ν = 0.4999 where standard hexahedra lock, the design derivatives against
finite differences, the choice of ``[material] formulation`` and its refusal on tetrahedra, and
the same state on every solver path."""

import logging
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import tomli_w

from contactopt.cli import main
from contactopt.config import load_config
from contactopt.errors import ConfigError, MeshError
from contactopt.fem import loads as L
from contactopt.fem.elasticity import ElasticityAssembler, element_geometry, lame
from contactopt.fem.elements import HEX8, TET4, gauss_hex
from contactopt.fem.model import ElasticModel
from contactopt.problem import ShapeProblem
from contactopt.sensitivity.adjoint import subgradient
from contactopt.sensitivity.check import check_gradient
from test_elements import cube_mesh, solve_dirichlet

E = 21.19
DATA = Path(__file__).parent / "data"


# ---------------------------------------------------------------------- the element
def bbar_by_hand(Xe, lam, mu):
    """Hughes' B̄ matrix of one hexahedron, Voigt (xx, yy, zz, yz, xz, xy): B̄ = B + (b̄ − b)/3 on
    the normal rows, b the divergence row and b̄ its volume mean; K = Σ_q w det J B̄ᵀ D B̄."""
    G, det = element_geometry(Xe[None], HEX8.dN)
    G, wd = G[0], det[0] * HEX8.w
    B = np.zeros((8, 6, 24))
    for a in range(8):
        gx, gy, gz = G[:, a].T
        B[:, 0, 3 * a], B[:, 1, 3 * a + 1], B[:, 2, 3 * a + 2] = gx, gy, gz
        B[:, 3, 3 * a + 1], B[:, 3, 3 * a + 2] = gz, gy
        B[:, 4, 3 * a], B[:, 4, 3 * a + 2] = gz, gx
        B[:, 5, 3 * a], B[:, 5, 3 * a + 1] = gy, gx
    b = B[:, 0] + B[:, 1] + B[:, 2]
    bmean = wd @ b / wd.sum()
    Bb = B.copy()
    Bb[:, :3] += ((bmean - b) / 3.0)[:, None, :]
    D = np.zeros((6, 6))
    D[:3, :3] = lam
    D[range(3), range(3)] += 2 * mu
    D[3:, 3:] = mu * np.eye(3)
    return np.einsum("q,qsi,st,qtj->ij", wd, Bb, D, Bb)


@pytest.mark.parametrize("nu", [0.3, 0.4999])
def test_element_matrix_is_hughes_bbar_and_the_pair_assembly_sums_it(nu):
    X, cells, _, _ = cube_mesh("HEX8", 2, amp=0.1, jitter=0.25, seed=3)
    asm = ElasticityAssembler(cells, len(X), [], E, nu, formulation="bbar")
    assert asm.formulation == "bbar" and asm.bbar
    Ke = asm.element_matrices(X[cells])
    lam, mu = lame(E, nu)
    for e in (0, 3, 7):
        ref = bbar_by_hand(X[cells[e]], lam, mu)
        assert np.abs(Ke[e] - ref).max() <= 1e-13 * np.abs(ref).max()
        ev = np.linalg.eigvalsh(Ke[e])
        assert np.sum(np.abs(ev) < 1e-10 * ev.max()) == 6 and ev[6] > 1e-8 * ev.max()
    # the volumetric part has rank one per element: the dilatation modes of K_std cost κ|e| θ̄² only
    std = ElasticityAssembler(cells, len(X), [], E, nu).element_matrices(X[cells])
    assert np.linalg.matrix_rank(std[0] - Ke[0], tol=1e-9 * np.abs(std[0]).max()) > 1
    fixed = (3 * np.flatnonzero(X[:, 2] < 1e-12)[:, None] + np.arange(3)).ravel()
    asm2 = ElasticityAssembler(cells, len(X), fixed, E, nu, formulation="bbar")
    A = asm2.stiffness(X)
    Af = asm.full_stiffness(X).tocsr()[asm2.free][:, asm2.free]
    assert abs(A - Af).max() <= 1e-14 * abs(Af).max() and abs(A - A.T).max() <= 1e-13 * abs(A).max()


def test_bbar_is_refused_on_tetrahedra_by_the_assembler():
    with pytest.raises(MeshError, match="hexahedra"):
        ElasticityAssembler(np.array([[0, 1, 2, 3]]), 4, [], E, 0.49, element=TET4, formulation="bbar")
    assert ElasticityAssembler(np.array([[0, 1, 2, 3]]), 4, [], E, 0.49, element=TET4,
                               formulation="auto").formulation == "standard"


# ---------------------------------------------------------------------- patch test
@pytest.mark.parametrize("nu", [0.3, 0.4999])
def test_patch_test_affine_field_and_constant_stress_on_a_distorted_mesh(nu):
    X, cells, faces, bnd = cube_mesh("HEX8", 4, amp=0.08, jitter=0.25, seed=2)
    asm = ElasticityAssembler(cells, len(X), [], E, nu, formulation="bbar")
    rng = np.random.default_rng(1)
    M, c = rng.standard_normal((3, 3)), rng.standard_normal(3)
    exact = X @ M.T + c
    u = solve_dirichlet(asm, X, bnd, exact, np.zeros(X.size))
    assert np.abs(u.reshape(-1, 3) - exact).max() < 1e-10 * np.abs(exact).max()
    lam, mu = lame(E, nu)
    eps = 0.5 * (M + M.T)
    sigma = lam * np.trace(eps) * np.eye(3) + 2 * mu * eps
    f = asm.full_stiffness(X) @ exact.ravel()
    Ln = L.pressure_load(X, faces, -1.0).reshape(-1, 3)          # ∫ N_a n dS
    assert np.abs(f.reshape(-1, 3) - Ln @ sigma.T).max() < 1e-10 * np.abs(f).max()
    s = asm.cell_stresses(X, exact.ravel())
    voigt = sigma[[0, 1, 2, 1, 0, 0], [0, 1, 2, 2, 2, 1]]
    assert np.abs(s - voigt).max() < 1e-10 * np.abs(sigma).max()


# ---------------------------------------------------------------------- convergence
# a divergence-free field u = curl(χ, 0, φ) (φ, χ products of sines): the body force −μΔu does not
# depend on λ, so the exact solution is the same for every ν, and the incompressible limit exists
K1, P1 = np.array([1.1, 0.9, 1.3]), np.array([0.3, 0.5, 0.2])
K2, P2 = np.array([0.8, 1.2, 1.0]), np.array([0.6, 0.1, 0.4])
TERMS = [[(1, K1, P1, (0, 1, 0))],                              # u1 = φ_y
         [(1, K2, P2, (0, 0, 1)), (-1, K1, P1, (1, 0, 0))],      # u2 = χ_z − φ_x
         [(-1, K2, P2, (0, 1, 0))]]                             # u3 = −χ_y


def _derivative(x, k, p, alpha):
    """∂^α Π_i sin(k_i x_i + p_i)."""
    out = np.ones(x.shape[0])
    for i in range(3):
        out = out * k[i] ** alpha[i] * np.sin(k[i] * x[:, i] + p[i] + alpha[i] * np.pi / 2)
    return out


def curl_field(x, extra=(0, 0, 0)):
    return np.stack([sum(s * _derivative(x, k, p, np.add(a, extra)) for s, k, p, a in TERMS[i])
                     for i in range(3)], axis=-1)


def test_the_manufactured_field_is_divergence_free():
    x = np.random.default_rng(0).random((5, 3))
    div = sum(curl_field(x, e)[:, i] for i, e in enumerate(np.eye(3, dtype=int)))
    assert np.abs(div).max() < 1e-14


def convergence(formulation, nu, sizes=(3, 6, 12)):
    """L2 and H1-seminorm errors of the Dirichlet problem with the divergence-free field above."""
    lam, mu = lame(E, nu)
    q, w = gauss_hex(3)
    N, dN = HEX8.shape(q)
    l2, h1 = [], []
    for n in sizes:
        X, cells, _, bnd = cube_mesh("HEX8", n)
        asm = ElasticityAssembler(cells, len(X), [], E, nu, formulation=formulation)
        Xe = X[cells]
        G, det = element_geometry(Xe, dN)
        xq = np.einsum("qa,eam->eqm", N, Xe).reshape(-1, 3)
        fq = (-mu * sum(curl_field(xq, 2 * e) for e in np.eye(3, dtype=int))).reshape(len(cells), -1, 3)
        fe = np.einsum("q,qa,eq,eqm->eam", w, N, det, fq)
        f = np.stack([np.bincount(cells.ravel(), fe[:, :, m].ravel(), minlength=len(X)) for m in range(3)], axis=1)
        u = solve_dirichlet(asm, X, bnd, curl_field(X), f.ravel())
        ue = u.reshape(-1, 3)[cells]
        err = np.einsum("qa,eam->eqm", N, ue) - curl_field(xq).reshape(fq.shape)
        l2.append(np.sqrt(np.einsum("q,eq,eqm->", w, det, err ** 2)))
        grad = np.stack([curl_field(xq, e) for e in np.eye(3, dtype=int)], axis=-1)
        He = np.einsum("eai,eqaj->eqij", ue, G) - grad.reshape(len(cells), -1, 3, 3)
        h1.append(np.sqrt(np.einsum("q,eq,eqij->", w, det, He ** 2)))
    h = 1.0 / np.asarray(sizes, float)
    return np.polyfit(np.log(h), np.log(l2), 1)[0], np.polyfit(np.log(h), np.log(h1), 1)[0], l2, h1


def test_bbar_converges_at_the_optimal_rates_at_nu_04999_where_standard_hexahedra_lock():
    r_l2, r_h1, l2, h1 = convergence("bbar", 0.4999)
    assert abs(r_l2 - 2.0) < 0.15, (r_l2, l2)
    assert abs(r_h1 - 1.0) < 0.15, (r_h1, h1)
    s_l2, _, sl2, _ = convergence("standard", 0.4999)
    # standard Q1: the rate of the last refinement collapses and the error is larger on the same mesh
    assert np.log2(sl2[-2] / sl2[-1]) < 1.5, sl2
    assert sl2[-1] > 1.5 * l2[-1], (sl2, l2)


# ---------------------------------------------------------------------- design derivatives
@pytest.mark.parametrize("nu", [0.49, 0.4999])
def test_bbar_shape_contraction_matches_central_differences_of_the_assembled_matrix(nu):
    X, cells, _, _ = cube_mesh("HEX8", 2, amp=0.1, jitter=0.2, seed=4)
    fixed = (3 * np.flatnonzero(X[:, 0] < 1e-12)[:, None] + np.arange(3)).ravel()
    asm = ElasticityAssembler(cells, len(X), fixed, E, nu, formulation="bbar")
    rng = np.random.default_rng(7)
    u = asm.to_full(rng.standard_normal(asm.n_free))
    v = asm.to_full(rng.standard_normal(asm.n_free))
    pred = asm.stiffness_shape_contraction(X, u, v)
    h = 1e-6
    for seed in (3, 5):
        V = np.random.default_rng(seed).standard_normal(X.shape) * 0.3
        fd = (v[asm.free] @ (asm.stiffness(X + h * V) @ u[asm.free])
              - v[asm.free] @ (asm.stiffness(X - h * V) @ u[asm.free])) / (2 * h)
        assert abs(fd) > 1e-3
        assert abs(np.sum(pred * V) - fd) <= 1e-6 * abs(fd), (np.sum(pred * V), fd)
    # the B-bar term matters: the standard contraction differs
    std = ElasticityAssembler(cells, len(X), fixed, E, nu).stiffness_shape_contraction(X, u, v)
    assert np.abs(std - pred).max() > 1e-2 * np.abs(pred).max()


def small_problem(nu=0.49, formulation="auto", friction=0.3, **extra):
    upd = {"mesh": {"nx": 8, "ny": 4, "nz": 3}, "state": {"method": "newton", "tol": 1e-12},
           "friction": {"coefficient": friction}, "objective": {"type": "target_normal_force"},
           "material": {"nu": nu, "formulation": formulation}}
    upd.update(extra)
    return ShapeProblem(load_config("example1").with_updates(upd))


def wavy(problem, amp=0.005, phase=0.0):
    a = problem.model.initial_design() + amp * np.sin(np.arange(problem.model.n_design) + phase)
    return a + 0.01 - a.mean()


def test_model_design_contraction_with_bbar_matches_central_differences():
    model = small_problem().model
    asm = model.assembler
    assert asm.formulation == "bbar"
    rng = np.random.default_rng(8)
    alpha = 0.002 + 0.01 * rng.random(model.n_design)
    u = asm.to_full(rng.standard_normal(asm.n_free))
    v = asm.to_full(rng.standard_normal(asm.n_free))
    pred = model.design_contraction(model.mesh.coordinates(alpha), u, v)
    h = 1e-6
    for k in (0, 5, model.n_design - 1):
        e = np.zeros(model.n_design)
        e[k] = h
        p, m = model.assemble(alpha + e), model.assemble(alpha - e)
        fd = (v[asm.free] @ ((p.A - m.A) @ u[asm.free]) - v @ (p.L_full - m.L_full)) / (2 * h)
        assert abs(pred[k] - fd) <= 1e-6 * abs(fd), k


@pytest.mark.parametrize("friction", [0.3, 0.0])
def test_subgradient_with_bbar_at_nu_049_matches_central_differences(friction):
    pr = small_problem(0.49, friction=friction)
    assert pr.model.assembler.formulation == "bbar"
    alpha = wavy(pr)
    rep = check_gradient(pr, alpha, seed=1, n_directions=6)
    assert rep.n_degenerate == 0
    assert np.max(rep.rel_errors) <= 1e-6, rep.rel_errors
    assert rep.taylor_rate >= 1.9


# ---------------------------------------------------------------------- configuration
@pytest.mark.parametrize("nu, formulation, expected", [(0.277, "auto", "standard"), (0.449, "auto", "standard"),
                                                       (0.45, "auto", "bbar"), (0.4999, "auto", "bbar"),
                                                       (0.49, "standard", "standard"), (0.3, "bbar", "bbar")])
def test_formulation_auto_is_bbar_on_hexahedra_from_nu_045(nu, formulation, expected):
    cfg = load_config("example1").with_updates({"mesh": {"nx": 4, "ny": 2, "nz": 2},
                                                "material": {"nu": nu, "formulation": formulation}})
    assert ElasticModel(cfg).assembler.formulation == expected


def test_the_paper_examples_keep_the_standard_formulation():
    for name in ("example1", "example2", "example3"):
        cfg = load_config(name)
        assert cfg["material"].get("formulation", "auto") == "auto" and cfg["material"]["nu"] < 0.45


def test_unknown_formulation_is_a_config_error():
    with pytest.raises(ConfigError, match="material.formulation = 'mixed'"):
        load_config("example1").with_updates({"material": {"formulation": "mixed"}})


def tet_toml(tmp_path, formulation, nu=0.49):
    data = {"name": "tets", "body": {"mesh": str(DATA / "two_groups.msh"), "clamped": "top", "contact": "bottom"},
            "material": {"nu": nu, "formulation": formulation},
            "loads": {"body_force": [0.0, 0.0, -1.0]},
            "design": {"degree": [3, 2], "C0": 0.05, "C2": 0.002, "initial": 0.002},
            "objective": {"target": {"kind": "constant", "value": 0.001}}}
    path = tmp_path / "tets.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def test_bbar_on_tetrahedra_exits_2_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["state", str(tet_toml(tmp_path, "bbar")), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("contactopt: error:")
    assert "material.formulation = 'bbar'" in err and "tetra" in err and "'standard'" in err and "tetra10" in err
    assert not out.exists()
    run = tmp_path / "run"
    assert main(["run", str(tet_toml(tmp_path, "bbar")), "--out", str(run)]) == 2
    assert not run.exists()


def test_linear_tetrahedra_at_high_nu_are_warned_about(tmp_path, caplog):
    with caplog.at_level(logging.WARNING, logger="contactopt"):
        model = ElasticModel(load_config(tet_toml(tmp_path, "auto")))
    assert model.assembler.formulation == "standard"
    assert any("lock" in r.getMessage() and "tetra10" in r.getMessage() for r in caplog.records)


# ---------------------------------------------------------------------- solver paths
def test_bbar_state_is_the_same_on_every_solver_path():
    states = {}
    for path in ("condensation", "delassus", "fullspace"):
        pr = small_problem(0.49, linear_solver={"path": path})
        states[path] = pr.solve_state(wavy(pr, phase=2.0))
    ref = states["condensation"]
    assert np.sum(ref.lam > 0) > 10
    for path, st in states.items():
        assert np.abs(st.lam - ref.lam).max() <= 1e-8 * np.abs(ref.lam).max(), path
        assert np.abs(st.tau - ref.tau).max() <= 1e-8 * np.abs(ref.lam).max(), path
    # the subgradient too: the adjoint and the design term of every path see the B-bar stiffness
    grads = {}
    for path in ("condensation", "fullspace"):
        pr = small_problem(0.49, linear_solver={"path": path})
        grads[path] = subgradient(pr, wavy(pr, phase=2.0)).gradient
    g = grads["condensation"]
    assert np.abs(grads["fullspace"] - g).max() <= 1e-7 * np.abs(g).max()
    # B-bar changes the answer at ν = 0.49 (against the standard element on the same mesh)
    std = small_problem(0.49, "standard")
    lam_std = std.solve_state(wavy(std, phase=2.0)).lam
    assert np.abs(lam_std - ref.lam).max() > 1e-3 * np.abs(ref.lam).max()


def test_distributed_assembly_and_contraction_with_bbar_equal_the_serial_ones():
    from contactopt.fem.distributed import DistributedBody
    model = small_problem(0.49).model
    alpha = wavy(small_problem(0.49))
    asm = model.assemble(alpha)
    A = asm.A.tocsr()
    rng = np.random.default_rng(2)
    u = model.assembler.to_full(rng.standard_normal(model.assembler.n_free))
    v = model.assembler.to_full(rng.standard_normal(model.assembler.n_free))
    serial = model.assembler.stiffness_shape_contraction(asm.coords, u, v)
    serial = model.mesh.contract_dx3(serial[:, 2])
    total = np.zeros_like(serial)
    for rank in range(2):
        db = DistributedBody(model, 2, rank)
        assert db._stiff[0].formulation == "bbar"
        indptr, cols, data = db.owned_stiffness(asm.coords)
        rows = sp.csr_matrix((data, cols, indptr), shape=(db.n_local, db.n))
        # the owned rows in PETSc numbering against A's rows on the free DOFs
        free_rows = np.flatnonzero(~db.fixed[db.rstart:db.rend])
        petsc_of_free = db.dof_of_free
        mine = np.flatnonzero((petsc_of_free >= db.rstart) & (petsc_of_free < db.rend))
        Ap = A[mine][:, np.argsort(petsc_of_free)]                     # columns in PETSc order of the free DOFs
        order = np.argsort(petsc_of_free[mine])
        got = rows[petsc_of_free[mine][order] - db.rstart][:, np.sort(petsc_of_free)]
        assert free_rows.size == mine.size
        assert abs(got - Ap[order]).max() <= 1e-13 * abs(A).max()
        total += db.contraction(model, asm.coords, u, v)
    assert np.abs(total - serial).max() <= 1e-10 * np.abs(serial).max()


# ---------------------------------------------------------------------- Hertz (slow)
def hertz_toml(tmp_path, nu, formulation, fine=4, R=5.0):
    """A block [−1, 1]² × [0, 1] with the bottom x3 = r²/2R in the mesh, cubes of side a/fine under
    the contact (a = 0.1), graded (ratio ≤ 1.35) to the faces; top clamped, frictionless."""
    import meshio
    mesh = tmp_path / "hertz.vtu"
    if not mesh.exists():
        h = 0.1 / fine                      # a = 0.1: the Hertz radius of R = 5, δ = 0.002
        x = list(np.arange(0, int(1.5 * fine) + 1) * h)
        step = h
        while x[-1] < 1.0 - 1e-12:
            step *= 1.35
            x.append(x[-1] + step)
        x = np.array(x)
        core = int(1.5 * fine)
        x[core:] = x[core] + (x[core:] - x[core]) * (1.0 - x[core]) / (x[-1] - x[core])
        xs = np.concatenate([-x[:0:-1], x])
        n, m = xs.size, x.size
        X, Y, Z = np.meshgrid(xs, xs, x, indexing="ij")
        pts = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
        pts[:, 2] += (1.0 - pts[:, 2]) * (pts[:, 0] ** 2 + pts[:, 1] ** 2) / (2 * R)
        i, j, k = (v.ravel() for v in np.meshgrid(np.arange(n - 1), np.arange(n - 1), np.arange(m - 1), indexing="ij"))

        def nid(i, j, k):
            return (i * n + j) * m + k
        cells = np.column_stack([nid(i, j, k), nid(i + 1, j, k), nid(i + 1, j + 1, k), nid(i, j + 1, k),
                                 nid(i, j, k + 1), nid(i + 1, j, k + 1), nid(i + 1, j + 1, k + 1),
                                 nid(i, j + 1, k + 1)])
        meshio.write(mesh, meshio.Mesh(pts, [("hexahedron", cells)]))
    c = 0.15 + 1e-9
    data = {"name": "hertz", "body": {"mesh": str(mesh), "clamped": {"x3": 1.0}, "initial_gap": "mesh",
                                      "contact": {"box": [[-c, c], [-c, c], [-0.01, 0.01]]}},
            "material": {"E": 1.0, "nu": nu, "formulation": formulation}, "friction": {"coefficient": 0.0},
            "loads": {"body_force": [0.0, 0.0, 0.0]},
            "design": {"degree": [1, 1], "C0": 0.01, "C1": 1.0, "C2": 1.0, "initial": 0.0},
            "objective": {"target": {"kind": "constant", "value": 0.0}},
            "linear_solver": {"path": "delassus"}}
    path = tmp_path / "hertz.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def hertz_peak_error(tmp_path, nu, formulation, R=5.0, delta=0.002):
    """|p(0) − p0|/p0 with Hertz's p0 = 3P/(2πa²), a = (3PR/4E*)^(1/3), E* = E/(1 − ν²) of the
    measured force P; p(0) the centre node's force over its tributary area."""
    pr = ShapeProblem(load_config(hertz_toml(tmp_path, nu, formulation)))
    st = pr.solve_state(np.full(pr.model.n_design, -delta))
    P = st.lam.sum()
    a = (3 * P * R * (1 - nu ** 2) / 4) ** (1 / 3)
    p0 = 3 * P / (2 * np.pi * a ** 2)
    centre = np.argmin(np.linalg.norm(pr.model.body.reference.points[pr.model.contact_nodes, :2], axis=1))
    assert 0.09 < a < 0.13
    return abs(st.lam[centre] / pr.model.contact_areas()[centre] - p0) / p0


@pytest.mark.slow
def test_hertz_peak_pressure_does_not_lock_with_bbar(tmp_path):
    """benchmarks/bench_locking.py at --fine 4 (docs/materials.md): B-bar's peak error at ν = 0.499
    within twice its error at ν = 0.3; the standard element's many times larger."""
    b3, b499 = hertz_peak_error(tmp_path, 0.3, "bbar"), hertz_peak_error(tmp_path, 0.499, "bbar")
    s499 = hertz_peak_error(tmp_path, 0.499, "standard")
    assert b3 < 0.02 and b499 <= 2 * b3, (b3, b499)
    assert s499 > 10 * b499, (s499, b499)
