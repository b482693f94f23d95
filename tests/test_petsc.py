"""The PETSc path (paths/petsc.py) against the pyamg full-space path: Θ, the state (u, λ, τ) and the
subgradient ξ (with v_λ) at two designs — the second warm-started from the first — on one process
and under ``mpiexec -n 2`` (tests/mpi/compare_paths.py), for Examples 1 and 2 (hexahedra) and the
round pad (tetrahedra from a mesh file). Both paths solve to the same tolerance (Siconos error and
equilibrium ≤ 1e-10), so they agree to 1e-8 relative; Θ and the subgradient, whose error the bundle
method amplifies, to 2e-10 (the adjoint (4.15) is solved to 1e-13; measured ≤ 2.8e-11 on 1 and 2
ranks, docs/scaling.md "The same answer on any number of ranks"). The same comparison, with
central differences, for objectives of the whole displacement (peak stress, friction work; static
and along a load path) and for load paths; runs on 2 ranks resumed after a stop and after kill -9.

Skipped without petsc4py/mpi4py (``pip install .`` does not install them; docs/install.md,
'PETSc and MPI'); ``.ci/run`` installs them and runs this file.
"""

import contextlib
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from contactopt._mpi import petsc_missing
from contactopt.cli import main
from contactopt.config import load_config
from contactopt.io.checkpoint import Checkpoint
from contactopt.problem import ShapeProblem

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "mpi"))
from compare_paths import evaluations, overrides  # noqa: E402

from test_fullspace import plane_press_fit  # noqa: E402  (the block of the pyamg backend's test)

MISSING = petsc_missing()
pytestmark = pytest.mark.skipif(MISSING is not None, reason=f"PETSc path: {MISSING}")

TOL = 1e-8
SUBGRADIENT_TOL = 2e-10                  # value, xi and v_lam keys
CASES = {
    "example1": ("example1", ["mesh.nx=12", "mesh.ny=6", "mesh.nz=4"]),
    "example2": ("example2", ["mesh.nx=12", "mesh.ny=6", "mesh.nz=6"]),
    "round_pad": (str(ROOT / "examples" / "round_pad.toml"), []),
}
_reference = {}


def reference(name):
    """The pyamg full-space path's evaluations of a case (computed once per session)."""
    if name not in _reference:
        src, sets = CASES[name]
        _reference[name] = evaluations(load_config(src).with_updates(overrides(sets)), "fullspace")
    return _reference[name]


def assert_agree(ref, got, what):
    assert set(ref) == set(got)
    for key in sorted(ref):
        x, y = np.atleast_1d(ref[key]), np.atleast_1d(got[key])
        assert x.shape == y.shape, f"{what}: {key} has shape {y.shape}, expected {x.shape}"
        scale = max(float(np.abs(x).max()), 1e-300)
        err = float(np.abs(x - y).max()) / scale
        tol = SUBGRADIENT_TOL if key.startswith(("value", "xi", "v_lam")) else TOL
        assert err <= tol, f"{what}: {key} differs from the pyamg path by {err:.2e} (relative) > {tol:g}"


def mpi_env():
    env = dict(os.environ)
    if hasattr(os, "geteuid") and os.geteuid() == 0:      # OpenMPI refuses root without these
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    env.setdefault("OMPI_MCA_rmaps_base_oversubscribe", "1")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")])
    return env


def mpiexec(n, *args, timeout=600):
    exe = shutil.which("mpiexec")
    if exe is None:
        pytest.skip("mpiexec not found")
    return subprocess.run([exe, "-n", str(n), sys.executable, *args], env=mpi_env(), capture_output=True,
                          text=True, timeout=timeout, cwd=ROOT)


def random_newton_piece(nw, seed):
    """(D, the sliding nodes, their Robin blocks k t tᵀ) of a made-up Newton system of the PETSc
    Newton object ``nw``: 40 sticking and 50 sliding contact nodes drawn with ``seed``, each sliding
    node's direction t at a random angle and k in [1, 5]."""
    cd = nw.cd
    rng = np.random.default_rng(seed)
    nodes = rng.permutation(cd.shape[0])
    stick, slide = nodes[:40], nodes[40:90]
    D = np.zeros(nw.dist.n, dtype=bool)
    D[cd[stick].ravel()] = True
    D[cd[slide, 2]] = True
    angle = rng.uniform(0, 2 * np.pi, slide.size)
    t = np.column_stack((np.cos(angle), np.sin(angle)))
    blk = rng.uniform(1.0, 5.0, slide.size)[:, None, None] * t[:, :, None] * t[:, None, :]
    return D, slide, blk


def compare_on_two_ranks(tmp_path, config, *args):
    """The arrays tests/mpi/compare_paths.py writes for the configuration file ``config`` (its
    further ``args``: settings, ``--differences``) under ``mpiexec -n 2``."""
    out = tmp_path / "petsc.npz"
    proc = mpiexec(2, str(ROOT / "tests" / "mpi" / "compare_paths.py"), str(config), str(out), *args)
    assert proc.returncode == 0, proc.stderr[-3000:]
    with np.load(out) as npz:
        return dict(npz)


@pytest.mark.parametrize("name", sorted(CASES))
def test_one_rank_equals_the_pyamg_path(name):
    src, sets = CASES[name]
    got = evaluations(load_config(src).with_updates(overrides(sets)), "petsc")
    assert_agree(reference(name), got, f"{name}, PETSc path on 1 rank")


@pytest.mark.parametrize("name", sorted(CASES))
def test_two_ranks_equal_the_pyamg_path(name, tmp_path):
    src, sets = CASES[name]
    got = compare_on_two_ranks(tmp_path, src, *sets)
    assert int(got.pop("ranks")) == 2
    assert_agree(reference(name), got, f"{name}, PETSc path on 2 ranks")


def test_the_comparison_sees_a_wrong_subgradient():
    """The agreement test fails for a subgradient off by a relative 1e-9 and a state off by 1e-7."""
    ref = reference("example1")
    with pytest.raises(AssertionError, match="xi0"):
        assert_agree(ref, dict(ref, xi0=ref["xi0"] * (1 + 1e-9)), "perturbed")
    with pytest.raises(AssertionError, match="u1"):
        assert_agree(ref, dict(ref, u1=ref["u1"] * (1 + 1e-7)), "perturbed")


def test_the_coarse_operators_are_galerkin_products_of_the_reference_newton_matrix():
    """The coarse operators the PETSc hierarchy forms for a Newton system from a few changed rows
    (PetscHierarchy.coarse) equal the Galerkin products, level by level, of the whole matrix
    Π(A(α_ref) + K_t)Π + I_D; and those of the plain system (no D, no K_t) those of A(α_ref)."""
    from petsc4py import PETSc

    from contactopt.problem import ShapeProblem

    cfg = load_config("example1").with_updates(overrides(["mesh.nx=24", "mesh.ny=12", "mesh.nz=8",
                                                          "linear_solver.path=petsc"]))
    options = PETSc.Options()
    options.setValue("pc_gamg_coarse_eq_limit", "200")        # three coarse levels on this mesh
    try:
        problem = ShapeProblem(cfg)
        problem.subgradient(problem.model.initial_design())     # the hierarchy, at α_ref = α0
    finally:
        options.delValue("pc_gamg_coarse_eq_limit")
    nw, hier = problem.path.newton, problem.path._hier
    assert len(hier._levels) >= 2, [M.getSize() for M in hier._levels]
    cd = nw.cd
    D, slide, blk = random_newton_piece(nw, 3)
    tt = cd[slide, :2]

    def levels_of(H):
        out, M = [], H
        for P in hier._P:
            M = M.ptap(P)
            out.append(M)
        return out

    def dense(M):
        ip, ind, val = M.getValuesCSR()
        out = np.zeros(M.getSize())
        out[np.repeat(np.arange(ip.size - 1), np.diff(ip)), ind] = val
        return out

    for case in ("plain", "newton"):
        H = nw.A_aij.duplicate(copy=True)
        if case == "newton":
            for i in range(slide.size):
                H.setValues(tt[i].astype(PETSc.IntType), tt[i].astype(PETSc.IntType), blk[i],
                            addv=PETSc.InsertMode.ADD)
            H.assemble()
            H.zeroRowsColumns(np.flatnonzero(D).astype(PETSc.IntType), diag=1.0)
            hier.coarse(D, (tt, blk))
        else:
            hier.coarse(np.zeros(nw.dist.n, dtype=bool))
        for lvl, (want, got) in enumerate(zip(levels_of(H), hier._levels)):
            w, g = dense(want), dense(got)
            err = np.abs(w - g).max() / np.abs(w).max()
            assert err < 1e-12, f"{case}: level {lvl + 1} coarse operator off by {err:.2e}"
        if case == "newton":     # and the comparison sees a wrong one
            assert np.abs(dense(levels_of(nw.A_aij)[0]) - dense(hier._levels[0])).max() > 1e-6 * np.abs(w).max()


# ---------------------------------------------------------------------------- contactopt run
def write_config(directory, name, updates, base="example2"):
    cfg = load_config(base).with_updates({"name": name, **updates})
    file = directory / f"{name}.toml"
    file.write_text(tomli_w.dumps(cfg.data))
    return file


def run_here(*args):
    """``contactopt ARGS`` in this process (one rank): (exit code, stdout + stderr)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        code = main([str(a) for a in args])
    return code, out.getvalue()


def summary(run_dir):
    return json.loads((run_dir / "summary.json").read_text())


SMALL = {"mesh": {"nx": 8, "ny": 4, "nz": 4}}
CASES2 = {"loads": {"right_traction": [0.0, 0.0, 0.0]},
          "load_cases": [{"name": "pull", "right_traction": [5e-2, 0.0, 0.0]},
                         {"name": "push", "right_traction": [-5e-2, 0.0, 0.0]}]}


def test_mpiexec_run_equals_the_run_on_one_process(tmp_path):
    """Two load cases, path "auto" (the PETSc path under mpiexec) against the pyamg path on one
    process: the same J after the same iterations; one run directory, one log, progress from rank 0."""
    mpi = write_config(tmp_path, "mpi", {**SMALL, **CASES2, "linear_solver": {"path": "auto"}})
    one = write_config(tmp_path, "one", {**SMALL, **CASES2, "linear_solver": {"path": "fullspace"}})
    code, out = run_here("run", one, "--out", tmp_path / "one", "--max-iter", 4)
    assert code == 0, out
    proc = mpiexec(2, "-m", "contactopt.cli", "run", str(mpi), "--out", str(tmp_path / "mpi"), "--max-iter", "4")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    ref, got = summary(tmp_path / "one"), summary(tmp_path / "mpi")
    assert got["iterations"] == ref["iterations"] == 4
    assert abs(got["J"] - ref["J"]) <= 1e-6 * abs(ref["J"]), (got["J"], ref["J"])
    assert proc.stdout.count("it    1 ") == 1                    # one progress line per iteration
    log = (tmp_path / "mpi" / "run.log").read_text()
    assert log.count("Θ(α0) =") == 1 and "petsc path" in log


def test_a_checkpoint_resumes_on_another_number_of_ranks(tmp_path):
    """Stopped after 2 iterations on 2 ranks, continued to 4 on one process (and the other way
    round): J as the uninterrupted run's on one process."""
    cfg = write_config(tmp_path, "r", {**SMALL, "linear_solver": {"path": "petsc"}})
    code, out = run_here("run", cfg, "--out", tmp_path / "whole", "--max-iter", 4)
    assert code == 0, out
    J = summary(tmp_path / "whole")["J"]
    proc = mpiexec(2, "-m", "contactopt.cli", "run", str(cfg), "--out", str(tmp_path / "a"), "--max-iter", "2")
    assert proc.returncode == 0, proc.stderr[-3000:]
    code, out = run_here("run", cfg, "--out", tmp_path / "a", "--max-iter", 4, "--resume")
    assert code == 0, out
    code, out = run_here("run", cfg, "--out", tmp_path / "b", "--max-iter", 2)
    assert code == 0, out
    proc = mpiexec(2, "-m", "contactopt.cli", "run", str(cfg), "--out", str(tmp_path / "b"), "--max-iter", "4",
                   "--resume")
    assert proc.returncode == 0, proc.stderr[-3000:]
    for d in ("a", "b"):
        s = summary(tmp_path / d)
        assert s["iterations"] == 4
        assert abs(s["J"] - J) <= 1e-6 * abs(J), (d, s["J"], J)


def test_more_ranks_than_the_mesh_can_be_split_over(tmp_path):
    cfg = write_config(tmp_path, "tiny", {"mesh": {"nx": 1, "ny": 1, "nz": 1}, "linear_solver": {"path": "petsc"}})
    proc = mpiexec(2, "-m", "contactopt.cli", "run", str(cfg), "--out", str(tmp_path / "out"))
    assert proc.returncode == 2, proc.stderr[-3000:]
    assert "fewer than the ranks" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "out").exists()


def test_a_resumed_run_repeats_the_uninterrupted_one_on_two_ranks(tmp_path):
    """Same number of ranks: the resumed run's history equals the uninterrupted one's bit for bit
    (the GAMG hierarchy is rebuilt at the design the checkpoint names; a solve forms its coarse
    operators from its own data only)."""
    cfg = write_config(tmp_path, "bits", {**SMALL, "linear_solver": {"path": "petsc"}}, base="example1")
    for out, iters, extra in (("whole", "5", ()), ("part", "2", ()), ("part", "5", ("--resume",))):
        proc = mpiexec(2, "-m", "contactopt.cli", "run", str(cfg), "--out", str(tmp_path / out), "--max-iter",
                       iters, *extra)
        assert proc.returncode == 0, proc.stderr[-3000:]

    def values(d):
        rows = (tmp_path / d / "history.csv").read_text().splitlines()
        return [",".join(r.split(",")[:4]) for r in rows]
    assert values("part") == values("whole")


def test_petsc_options_reach_petsc(tmp_path):
    """[linear_solver] petsc_options go to PETSc's options database: -ksp_view shows the GAMG
    preconditioner (printed by rank 0), an option that does not start with '-' is refused."""
    cfg = write_config(tmp_path, "opts", {**SMALL, "linear_solver": {"path": "petsc", "petsc_options": "-ksp_view"}},
                       base="example1")
    proc = mpiexec(2, "-m", "contactopt.cli", "state", str(cfg), "--out", str(tmp_path / "s"))
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "type: gamg" in proc.stdout
    bad = write_config(tmp_path, "bad", {**SMALL, "linear_solver": {"path": "petsc", "petsc_options": "ksp_view"}},
                       base="example1")
    code, out = run_here("state", bad, "--out", tmp_path / "b")
    assert code == 2 and "is not an option" in out, out
    assert not (tmp_path / "b").exists()


# ---------------------------------------------------------------------------- load steps
STEP_MESH = {"mesh": {"nx": 8, "ny": 4, "nz": 3}}
TOP, SIDE = [0.0, 0.0, -8e-2], [5e-2, 0.0, 0.0]
PATH3 = [{"name": "press", "top_traction": TOP},
         {"name": "shear", "top_traction": TOP, "right_traction": SIDE},
         {"name": "back", "top_traction": TOP, "right_traction": [2e-2, 0.0, 0.0], "substeps": 2}]
STEP_PATHS = {"two steps": (PATH3[:2], "last"), "three steps": (PATH3, "sum")}


def step_config(steps, objective):
    """Example 1 on a small mesh, its loads in the steps (press, shear, ...): sliding in the shear."""
    base = load_config("example1").with_updates(STEP_MESH).data
    return load_config({**base, "loads": {**base["loads"], "top_traction": [0.0] * 3, "right_traction": [0.0] * 3},
                        "load_steps": steps, "objective": {**base["objective"], "steps": objective}})


def step_reference(name):
    """The pyamg full-space path's evaluations of a load path, every solve's state included."""
    key = ("steps", name)
    if key not in _reference:
        _reference[key] = evaluations(step_config(*STEP_PATHS[name]), "fullspace")
    return _reference[key]


def assert_differences(got, what):
    """ξ along the directions against central differences of Θ (h = 1e-6), with sliding and no
    degenerate node."""
    assert int(got.pop("fd_M1")) > 0 and int(got.pop("fd_degenerate")) == 0, what
    fd, g = got.pop("fd"), got.pop("fd_xi")
    err = float(np.abs(g - fd).max() / np.abs(fd).max())
    assert err <= 1e-6, f"{what}: ξ against central differences {err:.2e} > 1e-6"


@pytest.mark.parametrize("name", sorted(STEP_PATHS))
def test_load_steps_on_one_rank_equal_the_pyamg_path(name):
    """Every step's state (u, λ, τ) and Θ as the pyamg full-space path's (both solve to 1e-10);
    ξ against central differences."""
    got = evaluations(step_config(*STEP_PATHS[name]), "petsc", differences=True)
    assert sum(k.startswith("u1_step") for k in got) == len(STEP_PATHS[name][0]) + (name == "three steps")
    assert_differences(got, f"{name}, PETSc path on 1 rank")
    assert_agree(step_reference(name), got, f"{name}, PETSc path on 1 rank")


@pytest.mark.parametrize("name", sorted(STEP_PATHS))
def test_load_steps_on_two_ranks_equal_the_pyamg_path(name, tmp_path):
    file = tmp_path / "steps.toml"
    file.write_text(tomli_w.dumps(step_config(*STEP_PATHS[name]).data))
    got = compare_on_two_ranks(tmp_path, file)
    assert int(got.pop("ranks")) == 2
    assert_differences(got, f"{name}, PETSc path on 2 ranks")
    assert_agree(step_reference(name), got, f"{name}, PETSc path on 2 ranks")


def test_a_resumed_load_path_run_repeats_the_uninterrupted_one_on_two_ranks(tmp_path):
    """A checkpoint holds every step's context (warm start, zone, displacement): the 3-step run
    stopped after 2 iterations and resumed repeats the uninterrupted run's history bit for bit,
    the steps' own columns included."""
    cfg = tmp_path / "steps.toml"
    cfg.write_text(tomli_w.dumps({**step_config(*STEP_PATHS["three steps"]).data, "name": "steps",
                                  "linear_solver": {"path": "petsc"}}))
    for out, iters, extra in (("whole", "4", ()), ("part", "2", ()), ("part", "4", ("--resume",))):
        proc = mpiexec(2, "-m", "contactopt.cli", "run", str(cfg), "--out", str(tmp_path / out), "--max-iter",
                       iters, *extra)
        assert proc.returncode == 0, proc.stderr[-3000:]
    whole, part = ((tmp_path / d / "history.csv").read_text().splitlines() for d in ("whole", "part"))
    header = whole[0].split(",")
    keep = [i for i, h in enumerate(header) if "time" not in h and "seconds" not in h]
    assert any(h.startswith("f_step_") for h in header), header
    assert len(whole) > 4                                  # the header and an evaluation per row
    assert [[r.split(",")[i] for i in keep] for r in part] == [[r.split(",")[i] for i in keep] for r in whole]


def checkpoint_position(out):
    """(iteration, evaluations) of a run directory's checkpoint, or None without one."""
    if not (out / "checkpoint.npz").exists():
        return None
    ckpt = Checkpoint.read(out / "checkpoint.npz")
    return ckpt.bundle.nit, ckpt.evaluations


def killed_at(seconds, *args):
    """``mpiexec -n 2 contactopt ARGS`` in a session of its own, its whole process group killed
    (SIGKILL: mpiexec and both ranks at once, nothing flushed) ``seconds`` after the start: True,
    or False where the run ended first."""
    exe = shutil.which("mpiexec")
    if exe is None:
        pytest.skip("mpiexec not found")
    proc = subprocess.Popen([exe, "-n", "2", sys.executable, "-m", "contactopt.cli", *map(str, args)], env=mpi_env(),
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        proc.wait(timeout=seconds)
        return False
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        return True
    finally:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:      # the ranks leave the group's table after their parent
            try:
                os.killpg(proc.pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.05)
        else:
            pytest.fail("processes of the killed mpiexec group are still alive")


N_KILLS = 2


def history_outcome(run_dir):
    """(J, iterations, evaluations, alpha.json, history.csv without the time columns) of a run."""
    s = summary(run_dir)
    rows = (run_dir / "history.csv").read_text().splitlines()
    header = rows[0].split(",")
    keep = [i for i, h in enumerate(header) if "time" not in h and "seconds" not in h]
    return (s["J"], s["iterations"], s["evaluations"], (run_dir / "alpha.json").read_text(),
            [[r.split(",")[i] for i in keep] for r in rows])


def assert_kills_resume_bit_for_bit(tmp_path, cfg, iters, seed, n_kills=N_KILLS):
    """The run of ``cfg`` on 2 ranks to ``iters`` iterations, then ``n_kills`` runs killed (kill -9
    of the whole mpiexec group, :func:`killed_at`) at moments drawn by ``random.Random(seed)``
    within its measured duration and resumed on 2 ranks: each outcome (:func:`history_outcome`)
    bit for bit the uninterrupted run's; a run killed before its first checkpoint is refused by
    --resume and started anew with --overwrite. Returns the uninterrupted outcome."""
    import random
    iters = str(iters)
    t0 = time.perf_counter()
    proc = mpiexec(2, "-m", "contactopt.cli", "run", str(cfg), "--out", str(tmp_path / "whole"), "--max-iter", iters)
    wall = time.perf_counter() - t0
    assert proc.returncode == 0, proc.stderr[-3000:]
    whole = history_outcome(tmp_path / "whole")
    assert whole[1] == int(iters) and len(whole[4]) > int(iters)
    rng = random.Random(seed)
    killed = 0
    for n in range(n_kills):
        out, moment = tmp_path / f"kill{n}", rng.uniform(0.0, wall)
        t1 = time.perf_counter()
        hit = killed_at(moment, "run", cfg, "--out", out, "--max-iter", iters)
        killed += hit
        position = checkpoint_position(out)
        resumed = mpiexec(2, "-m", "contactopt.cli", "run", str(cfg), "--out", str(out), "--max-iter", iters,
                          "--resume")
        if not (out / "checkpoint.npz").exists() or resumed.returncode == 2:
            assert resumed.returncode == 2 and "no checkpoint" in resumed.stderr, resumed.stderr[-3000:]
            resumed = mpiexec(2, "-m", "contactopt.cli", "run", str(cfg), "--out", str(out), "--max-iter", iters,
                              "--overwrite")
        assert resumed.returncode == 0, resumed.stderr[-3000:]
        got = history_outcome(out)
        assert got[0] == whole[0], (n, moment, got[0], whole[0])
        assert got == whole, (n, moment)
        print(f"\nkill -9 at {moment:.2f} s of {wall:.2f} s ({'killed' if hit else 'it had ended'}, "
              f"{time.perf_counter() - t1:.1f} s with the resume): checkpoint "
              f"{'none' if position is None else 'at iteration %d (%d evaluations)' % position}; bit-identical")
    assert killed, "every run ended before its moment"
    return whole


def test_a_load_path_run_killed_at_random_moments_resumes_bit_for_bit_on_two_ranks(tmp_path):
    """kill -9 of the whole mpiexec group at seeded random moments within the measured duration of
    the 3-step run, then ``--resume`` on 2 ranks: J, α (summary.json, alpha.json) and history.csv
    (every column but the times) bit for bit the uninterrupted run's; a run killed before its first
    checkpoint is refused by --resume and started anew with --overwrite."""
    cfg = tmp_path / "steps.toml"
    cfg.write_text(tomli_w.dumps({**step_config(*STEP_PATHS["three steps"]).data, "name": "steps",
                                  "linear_solver": {"path": "petsc"}, "optimizer": {"ftol": 0.0, "eps": 1e-8}}))
    assert_kills_resume_bit_for_bit(tmp_path, cfg, 4, "kill -9 a PETSc load path")


# ---------------------------------------------------------------------------- load steps on tetrahedra
SLOPE = [0.0, 0.0, -1.0]
TET_PATH3 = [{"name": "press", "body_force": SLOPE},
             {"name": "shear", "body_force": SLOPE, "pressure": [{"on": {"x1": 1.0}, "value": 0.05}]},
             {"name": "ease", "body_force": SLOPE, "pressure": [{"on": {"x1": 1.0}, "value": 0.03}], "substeps": 2}]
TET_PATHS = {"two steps": (TET_PATH3[:2], "last"), "three steps": (TET_PATH3, "sum")}


def tet_step_config(steps, objective):
    """A box of 288 nodes and linear tetrahedra read from a Gmsh file (tests/data/two_groups.msh),
    clamped on top, pressed by its weight and sheared by a pressure on its end x = 1: sliding in
    the shear and in the easing."""
    return load_config({
        "name": "box",
        "body": {"mesh": str(ROOT / "tests" / "data" / "two_groups.msh"), "clamped": "top", "contact": "bottom"},
        "design": {"degree": [3, 2], "C0": 0.05, "C2": 0.002, "initial": 0.002},
        "objective": {"target": {"kind": "constant", "value": 0.001}, "steps": objective},
        "load_steps": steps})


def tet_step_reference(name):
    key = ("tet steps", name)
    if key not in _reference:
        _reference[key] = evaluations(tet_step_config(*TET_PATHS[name]), "fullspace")
    return _reference[key]


@pytest.mark.parametrize("ranks", [1, 2])
@pytest.mark.parametrize("name", sorted(TET_PATHS))
def test_load_steps_on_tetrahedra_equal_the_pyamg_path(name, ranks, tmp_path):
    """The 2- and 3-step paths on tetrahedra: every solve's state and Θ as the pyamg full-space
    path's, ξ against central differences, on 1 rank and under mpiexec -n 2."""
    from contactopt.problem import ShapeProblem

    cfg = tet_step_config(*TET_PATHS[name])
    assert ShapeProblem(cfg).model.mesh.cell_type == "tetra"
    if ranks == 1:
        got = evaluations(cfg, "petsc", differences=True)
    else:
        file = tmp_path / "steps.toml"
        file.write_text(tomli_w.dumps(cfg.data))
        got = compare_on_two_ranks(tmp_path, file)
        assert int(got.pop("ranks")) == 2
    solves = sum(s.get("substeps", 1) for s in TET_PATHS[name][0])
    assert sum(k.startswith("u1_step") for k in got) == solves
    what = f"{name} on tetrahedra, PETSc path on {ranks} rank(s)"
    assert_differences(got, what)
    assert_agree(tet_step_reference(name), got, what)


# ---------------------------------------------------------------------------- objectives of the whole displacement
# peak stress and friction work: ∂J/∂u on every DOF, the interior rows of the adjoint get −g_i
# (docs/objectives.md); on hexahedra (Example 1, 8×4×3) and tetrahedra (the round pad), static
# and along a 2-step path (press, then shear: sliding in the shear)
PEAK = {"type": "peak_stress"}
KS = {"type": "peak_stress", "aggregate": "ks", "rho": 50.0}
WORK = {"type": "frictional_dissipation"}
WHOLE = {"hex max": ("hex", PEAK), "hex ks": ("hex", KS), "hex work": ("hex", WORK),
         "tet max": ("tet", PEAK), "tet ks": ("tet", KS), "tet work": ("tet", WORK),
         "hex 2 steps max": ("steps", PEAK), "hex 2 steps work": ("steps", WORK)}


def whole_config(name):
    body, objective = WHOLE[name]
    if body == "tet":
        cfg = load_config(str(ROOT / "examples" / "round_pad.toml"))
    elif body == "hex":
        cfg = load_config("example1").with_updates(STEP_MESH)
    else:
        cfg = step_config(PATH3[:2], "last")
    return cfg.with_updates({"objective": {**cfg.data["objective"], **objective}})


def whole_reference(name):
    key = ("whole", name)
    if key not in _reference:
        _reference[key] = evaluations(whole_config(name), "fullspace")
    return _reference[key]


def whole_evaluations(name, ranks, tmp_path):
    """The PETSc path's evaluations of a case of WHOLE, central differences included."""
    cfg = whole_config(name)
    if ranks == 1:
        return evaluations(cfg, "petsc", differences=True)
    file = tmp_path / "whole.toml"
    file.write_text(tomli_w.dumps(cfg.data))
    got = compare_on_two_ranks(tmp_path, file, "--differences")
    assert int(got.pop("ranks")) == 2
    return got


@pytest.mark.parametrize("ranks", [1, 2])
@pytest.mark.parametrize("name", list(WHOLE))
def test_objectives_of_the_whole_displacement_equal_the_pyamg_path(name, ranks, tmp_path):
    """Peak stress (max, KS) and friction work: Θ, the states and ξ as the pyamg full-space path's,
    ξ against central differences (≤ 1e-6), on 1 rank and under mpiexec -n 2."""
    got = whole_evaluations(name, ranks, tmp_path)
    what = f"{name}, PETSc path on {ranks} rank(s)"
    fd = np.abs(got["fd_xi"] - got["fd"]).max() / np.abs(got["fd"]).max()
    assert_differences(got, what)
    assert_agree(whole_reference(name), got, what)
    ref = whole_reference(name)

    def largest(*prefixes):
        return max(float(np.abs(ref[k] - got[k]).max() / max(np.abs(ref[k]).max(), 1e-300))
                   for k in ref if k.startswith(prefixes))
    print(f"\n{what}: states {largest('u', 'lam', 'tau'):.1e}, Θ {largest('value'):.1e}, "
          f"ξ {largest('xi'):.1e}, ξ vs central differences {fd:.1e}")


def test_a_sum_with_the_peak_stress_under_a_friction_work_constraint_runs_on_two_ranks_as_on_one_process(tmp_path):
    """`contactopt run` of a sum with a peak-stress term (KS, a region) under a [[constraints]] limit
    on the friction work, infeasible at α0: under mpiexec -n 2 on the PETSc path as on the pyamg path
    in one process — the same iterations and evaluations, J, the terms and the constraint's value to
    1e-6 (the tolerance of the run comparison above)."""
    upd = {**SMALL, "objective": {"type": "sum", "terms": [
        {"type": "target_normal_force", "weight": 1.0},
        {"type": "peak_stress", "aggregate": "ks", "rho": 50.0, "region": {"box": [[0, 2], [0, 1], [0, 0.2]]},
         "weight": 1e-3}]}, "constraints": [{"type": "frictional_dissipation", "max": 2.3e-5}]}
    one = write_config(tmp_path, "one", {**upd, "linear_solver": {"path": "fullspace"}}, base="example1")
    mpi = write_config(tmp_path, "mpi", {**upd, "linear_solver": {"path": "petsc"}}, base="example1")
    code, out = run_here("run", one, "--out", tmp_path / "one", "--max-iter", 4)
    assert code == 0, out
    proc = mpiexec(2, "-m", "contactopt.cli", "run", str(mpi), "--out", str(tmp_path / "mpi"), "--max-iter", "4")
    assert proc.returncode == 0, proc.stderr[-3000:]
    ref, got = summary(tmp_path / "one"), summary(tmp_path / "mpi")
    assert (got["iterations"], got["evaluations"]) == (ref["iterations"], ref["evaluations"]) and ref["iterations"] == 4
    c_ref, c_got = (s["constraints"]["responses"]["frictional_dissipation"] for s in (ref, got))
    assert c_ref["initial"]["margin"] < 0                       # infeasible at α0
    pairs = [(got["J"], ref["J"]), (c_got["value"], c_ref["value"])] + [
        (got["objective"]["J"]["terms"][t]["value"], ref["objective"]["J"]["terms"][t]["value"])
        for t in ("target_normal_force", "peak_stress")]
    print(f"\nsum under a constraint, 2 ranks vs one process: J, c, terms within "
          f"{max(abs(x - y) / abs(y) for x, y in pairs):.1e} (relative)")
    for x, y in pairs:
        assert abs(x - y) <= 1e-6 * abs(y), pairs


def test_the_differences_see_the_adjoint_without_its_interior_rows(monkeypatch):
    """Dropped, the adjoint's interior right-hand side −g_i (only ∂J/∂u_c left) gives a ξ that
    central differences refuse: the check above cannot pass without it."""
    from contactopt.contact.fullspace.petsc import PetscNewton
    adjoint = PetscNewton.adjoint

    def contact_only(self, hier, stick, slide, free_lam, u_c, lam, y_u, *args, **kw):
        y_u = np.asarray(y_u)
        return adjoint(self, hier, stick, slide, free_lam, u_c, lam,
                       y_u[self.cd.ravel()] if y_u.size == self.dist.n else y_u, *args, **kw)

    monkeypatch.setattr(PetscNewton, "adjoint", contact_only)
    with pytest.raises(AssertionError, match="central differences"):
        assert_differences(evaluations(whole_config("hex max"), "petsc", differences=True), "dropped")


# ------------------------------------------------------------------ a press fit without load
@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_a_press_fit_without_load_on_the_petsc_path_equals_the_condensation(tmp_path, friction):
    # L = 0: the residuals against the overlap's force, as on the pyamg backend
    cond, pets = (ShapeProblem(plane_press_fit(tmp_path, path, friction)) for path in ("condensation", "petsc"))
    assert pets.path.name == "petsc"
    alpha = cond.model.initial_design()
    sc, sp_ = cond.solve_state(alpha), pets.solve_state(alpha)
    assert sp_.converged and np.array_equal(sc.classes, sp_.classes)
    assert np.abs(sp_.lam - sc.lam).max() <= 1e-8 * sc.lam.max()
    assert np.abs(sp_.u - sc.u).max() <= 1e-8 * np.abs(sc.u).max()
