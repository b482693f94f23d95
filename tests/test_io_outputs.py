"""Output files: VTU/PVD read back, valid PNGs, all-or-nothing state directories, atomic helpers."""

import json
import os
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from contactopt.config import load_config
from contactopt.contact.state import CLASS_NAMES, SolveStats, State, class_counts
from contactopt.fem.model import ElasticModel
from contactopt.io import atomic, plots, statefiles, vtk

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def model():
    return ElasticModel(load_config("example1").with_updates({"mesh": {"nx": 6, "ny": 3, "nz": 2}}))


def fake_state(model, seed=0):
    """A plausible (not solved) state: distinct values on every contact node, zero u on Γ_u."""
    rng = np.random.default_rng(seed)
    alpha = model.initial_design() + 0.05 * rng.random(model.n_design)
    coords = model.mesh.coordinates(alpha)
    n, p = model.mesh.n_nodes, model.n_contact
    u = 1e-3 * rng.standard_normal((n, 3))
    u[model.mesh.node_sets["clamped"]] = 0.0
    u_c = u[model.contact_nodes]
    lam = 1e-4 * (1.0 + np.arange(p))
    tau = 1e-5 * rng.standard_normal((p, 2))
    classes = np.arange(p) % len(CLASS_NAMES)
    return State(alpha=alpha, coords=coords, u=u.ravel(), u_c=u_c, lam=lam, tau=tau,
                 gap=model.gap_matrix @ alpha, classes=classes, friction=0.3, method="fake",
                 iterations=7, residual=1e-11, complementarity=2e-12, converged=True,
                 timings={"solve": 0.25}, stats=SolveStats(extra={"note": "synthetic", "array": np.zeros(3)}))


def assert_png(path):
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE, path
    # IHDR: width, height big-endian after the signature and chunk header
    width, height = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    assert width > 100 and height > 100 and len(data) > 5000, (path, width, height, len(data))


def no_temporaries(directory):
    return [p.name for p in directory.iterdir() if p.name.startswith(".") or ".tmp" in p.name]


# ------------------------------------------------------------------ VTU / PVD
def test_body_vtu_round_trip(model, tmp_path):
    st = fake_state(model)
    extra = {"lam_target": np.full(model.n_contact, 2.5e-4), "node_index": np.arange(model.mesh.n_nodes)}
    path = vtk.write_body_vtu(tmp_path / "body.vtu", model, st, extra_point_data=extra)
    m = meshio.read(path)
    n, cn = model.mesh.n_nodes, model.contact_nodes
    off = np.setdiff1d(np.arange(n), cn)
    assert np.allclose(m.points, st.coords)
    assert [c.type for c in m.cells] == ["hexahedron"]
    assert np.array_equal(m.cells[0].data, model.mesh.elements)
    pd = m.point_data
    assert {"displacement", "normal_force", "tangential_force", "node_class", "gap", "contact_node",
            "lam_target", "node_index"} <= set(pd)
    for arr in pd.values():
        assert arr.shape[0] == n and np.all(np.isfinite(arr))
    assert np.allclose(pd["displacement"], st.u.reshape(n, 3))
    assert np.allclose(pd["normal_force"][cn], st.lam) and np.all(pd["normal_force"][off] == 0)
    assert np.allclose(pd["tangential_force"][cn, :2], st.tau)
    assert np.all(pd["tangential_force"][:, 2] == 0) and np.all(pd["tangential_force"][off] == 0)
    assert pd["node_class"].dtype.kind == "i"
    assert np.array_equal(pd["node_class"][cn], st.classes) and np.all(pd["node_class"][off] == -1)
    assert np.allclose(pd["gap"][cn], st.gap) and np.all(pd["gap"][off] == 0)
    assert np.allclose(pd["lam_target"][cn], 2.5e-4) and np.all(pd["lam_target"][off] == 0)
    assert np.array_equal(pd["node_index"], np.arange(n))
    # the contact nodes lie on the surface: gap = x3 of the reference coordinates there
    assert np.allclose(pd["gap"][cn], m.points[cn, 2])
    assert no_temporaries(tmp_path) == []


def test_body_vtu_deformed_and_errors(model, tmp_path):
    st = fake_state(model)
    m = meshio.read(vtk.write_body_vtu(tmp_path / "d.vtu", model, st, deformed=True))
    assert np.allclose(m.points, st.coords + st.u.reshape(-1, 3))
    bad = fake_state(model)
    bad.lam = bad.lam.copy()
    bad.lam[3] = np.nan
    with pytest.raises(ValueError, match="normal_force"):
        vtk.write_body_vtu(tmp_path / "bad.vtu", model, bad)
    with pytest.raises(ValueError, match="shape"):
        vtk.write_body_vtu(tmp_path / "bad.vtu", model, st, extra_point_data={"x": np.zeros(5)})
    assert not (tmp_path / "bad.vtu").exists() and no_temporaries(tmp_path) == []


def test_pvd_is_valid_collection(tmp_path):
    entries = [(0, "iter_0000.vtu"), (1, "iter_0001.vtu"), (2.5, "sub/iter_0002.vtu")]
    path = vtk.write_pvd(tmp_path / "run.pvd", entries)
    root = ET.parse(path).getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection"
    sets = root.find("Collection").findall("DataSet")
    assert [d.get("file") for d in sets] == [e[1] for e in entries]
    assert [float(d.get("timestep")) for d in sets] == [0.0, 1.0, 2.5]
    with pytest.raises(ValueError, match="relative"):
        vtk.write_pvd(tmp_path / "abs.pvd", [(0, str(tmp_path / "x.vtu"))])
    with pytest.raises(ValueError, match="finite"):
        vtk.write_pvd(tmp_path / "nan.pvd", [(float("nan"), "x.vtu")])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.pvd"]


# ------------------------------------------------------------------ plots
def test_plots_write_valid_png(model, tmp_path):
    st = fake_state(model)
    p = model.n_contact
    target = np.where(model.mesh.contact_points()[:, 0] <= 1.0, 2.5e-4, 3e-4)
    files = [
        plots.plot_contact_field(tmp_path / "lam.png", model, st.lam, "normal force", label="λ"),
        plots.plot_node_classes(tmp_path / "classes.png", model, st.classes),
        plots.plot_stress_comparison(tmp_path / "cmp.png", model, target, st.lam, 0.9 * target),
        plots.plot_surface(tmp_path / "surface.png", model, st.alpha),
        plots.plot_history(tmp_path / "history.png", [
            {"iteration": k, "f": 1e-5 * 0.7 ** k, "kind": "serious" if k % 3 else "null",
             "stationarity": 1e-2 * 0.5 ** k if k % 2 else None} for k in range(12)]),
        plots.plot_history(tmp_path / "empty_history.png", []),
    ]
    for f in files:
        assert_png(f)
    assert no_temporaries(tmp_path) == []
    with pytest.raises(ValueError, match="one value per contact node"):
        plots.plot_contact_field(tmp_path / "x.png", model, np.zeros(p + 1), "wrong")
    with pytest.raises(ValueError, match="codes"):
        plots.plot_node_classes(tmp_path / "x.png", model, np.full(p, 6))
    assert not (tmp_path / "x.png").exists()


def test_contact_grid_matches_mesh_order(model):
    X1, X2, grid = plots.contact_grid(model, np.arange(model.n_contact))
    mesh = model.mesh
    assert grid.shape == (mesh.ny + 1, mesh.nx)
    # node (i, j) of the bottom layer is contact node i−1 + nx·j
    assert grid[2, 4] == 4 + mesh.nx * 2
    assert np.isclose(X1[0, 0], model.surface.a / mesh.nx) and np.isclose(X1[0, -1], model.surface.a)
    assert np.isclose(X2[-1, 0], model.surface.b) and np.isclose(X2[0, 0], 0.0)
    edges = plots._dual_edges(X1[0], 0.0, model.surface.a)
    assert np.isclose(edges[0], 0.5 * model.surface.a / mesh.nx) and np.isclose(edges[-1], model.surface.a)


# ------------------------------------------------------------------ state directory
def test_write_state_all_files(model, tmp_path):
    st = fake_state(model)
    out = tmp_path / "state"
    cfg = model.config
    written = statefiles.write_state(out, model, st, config=cfg)
    assert sorted(written) == sorted(statefiles.STATE_FILES)
    assert sorted(p.name for p in out.iterdir()) == sorted(statefiles.STATE_FILES)
    assert no_temporaries(tmp_path) == []
    doc = json.loads((out / "state.json").read_text())
    assert doc["summary"]["node_classes"] == class_counts(st.classes)
    assert doc["summary"]["iterations"] == 7 and doc["summary"]["note"] == "synthetic"
    assert np.allclose(doc["alpha"], model.surface.as_matrix(st.alpha))
    assert np.allclose(doc["contact"]["lam"], st.lam) and np.allclose(doc["contact"]["tau"], st.tau)
    assert doc["contact"]["class"][:6] == list(CLASS_NAMES)
    assert doc["config"]["mesh"] == {"nx": 6, "ny": 3, "nz": 2}
    back = statefiles.read_state_npz(out / "state.npz")
    for name in ("alpha", "coords", "u", "u_c", "lam", "tau", "gap", "classes"):
        assert np.array_equal(getattr(back, name), getattr(st, name)), name
    assert (back.method, back.iterations, back.converged, back.friction) == ("fake", 7, True, 0.3)
    assert back.timings == {"solve": 0.25} and back.info == {"note": "synthetic"}
    assert back.summary() == st.summary()
    m = meshio.read(out / "body.vtu")
    assert np.allclose(m.point_data["normal_force"][model.contact_nodes], st.lam)
    assert_png(out / "lambda.png")
    assert_png(out / "classes.png")
    # into an existing directory: same-named files replaced, other files kept
    (out / "keep.txt").write_text("mine")
    st2 = fake_state(model, seed=1)
    st2.lam = 2 * st2.lam
    statefiles.write_state(out, model, st2)
    assert (out / "keep.txt").read_text() == "mine"
    assert np.array_equal(statefiles.read_state_npz(out / "state.npz").lam, st2.lam)
    assert "config" not in json.loads((out / "state.json").read_text())
    assert no_temporaries(tmp_path) == [] and no_temporaries(out) == []


def test_state_data_round_trip_through_its_named_fields(model, tmp_path):
    """A load step's data (step, substep, J, slip, obstacle control, rigid anchor, uniqueness
    bound, path statistics) is written under the keys it always had and read back into the same
    named fields; ``info`` is their read-only dictionary form."""
    from contactopt.contact.state import ObstacleControl, RigidAnchor
    st = fake_state(model, seed=2)
    p = st.lam.size
    st.stats = SolveStats(path="delassus", backend="scipy", zone_nodes=p, zone_misses=1, delassus="formed",
                          sparse_solves=4, adjoint_krylov=9)
    st.step, st.substep, st.objective = "load", 2, 0.125
    st.slip_ref, st.slip = np.zeros((p, 2)), np.full((p, 2), 1e-4)
    st.obstacle = ObstacleControl(translation=-2.5e-3, resultant=0.2, solves=11)
    st.rigid = RigidAnchor(iterations=3, residual=1e-13)
    st.uniqueness_bound, st.uniqueness_reason = 0.7, "estimate"
    keys = {"path", "backend", "zone_nodes", "zone_misses", "delassus", "sparse_solves", "adjoint_krylov",
            "step", "substep", "slip", "objective", "obstacle_translation", "obstacle_resultant", "obstacle_solves",
            "rigid_iterations", "rigid_residual", "uniqueness_bound_F0", "uniqueness_bound_F0_reason"}
    assert set(st.info) == keys and st.info["obstacle_translation"] == -2.5e-3 and st.info["substep"] == 2
    with pytest.raises(TypeError):
        st.info["step"] = "other"                  # a view: the named fields are the data
    out = tmp_path / "st"
    statefiles.write_state(out, model, st)
    doc = json.loads((out / "state.json").read_text())
    assert keys - {"slip"} <= set(doc["summary"]) and doc["summary"]["obstacle_solves"] == 11
    assert np.allclose(doc["contact"]["slip"], 1e-4)
    back = statefiles.read_state_npz(out / "state.npz")
    assert back.stats == st.stats and back.obstacle == st.obstacle and back.rigid == st.rigid
    assert (back.step, back.substep, back.objective) == ("load", 2, 0.125)
    assert (back.uniqueness_bound, back.uniqueness_reason) == (0.7, "estimate")
    assert dict(back.info) == {k: v for k, v in st.info.items() if k != "slip"}


def _boom(*args, **kwargs):
    raise RuntimeError("simulated plotting failure")


def test_write_state_failure_leaves_nothing(model, tmp_path, monkeypatch):
    st = fake_state(model)
    monkeypatch.setattr(plots, "plot_node_classes", _boom)   # the last file built
    new = tmp_path / "new"
    with pytest.raises(RuntimeError, match="simulated"):
        statefiles.write_state(new, model, st)
    assert not new.exists()
    assert os.listdir(tmp_path) == []
    # an existing directory keeps its previous content untouched
    old = tmp_path / "old"
    old.mkdir()
    (old / "state.json").write_text("previous")
    with pytest.raises(RuntimeError, match="simulated"):
        statefiles.write_state(old, model, st)
    assert os.listdir(old) == ["state.json"] and (old / "state.json").read_text() == "previous"
    assert sorted(os.listdir(tmp_path)) == ["old"]


def test_write_state_refuses_nan(model, tmp_path):
    st = fake_state(model)
    st.u = st.u.copy()
    st.u[5] = np.inf
    with pytest.raises(ValueError, match="state.u"):
        statefiles.write_state(tmp_path / "s", model, st)
    assert os.listdir(tmp_path) == []


# ------------------------------------------------------------------ atomic helpers
def test_atomic_helpers(tmp_path):
    p = atomic.atomic_write_text(tmp_path / "a.txt", "héllo\n")
    assert p.read_text(encoding="utf-8") == "héllo\n"
    assert (p.stat().st_mode & 0o777) == 0o644
    atomic.atomic_write_bytes(tmp_path / "b.bin", b"\x00\x01")
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    atomic.atomic_write_json(tmp_path / "c.json", {"x": np.arange(3), "y": np.float32(0.5), "t": (1, 2)})
    assert json.loads((tmp_path / "c.json").read_text()) == {"x": [0, 1, 2], "y": 0.5, "t": [1, 2]}
    atomic.atomic_savez(tmp_path / "d.data", a=np.eye(2))   # exact name, no ".npz" appended
    with np.load(tmp_path / "d.data") as z:
        assert np.array_equal(z["a"], np.eye(2))
    atomic.atomic_savez_compressed(tmp_path / "e.npz", b=np.ones(4))
    with np.load(tmp_path / "e.npz") as z:
        assert np.array_equal(z["b"], np.ones(4))
    # a failed write keeps the previous content and leaves no temporary file
    with pytest.raises(ValueError, match=r"\$\.r\[1\]"):
        atomic.atomic_write_json(tmp_path / "c.json", {"r": [1.0, float("nan")]})
    with pytest.raises(TypeError):
        atomic.atomic_write_json(tmp_path / "c.json", {"f": object()})
    assert json.loads((tmp_path / "c.json").read_text())["x"] == [0, 1, 2]
    with pytest.raises(RuntimeError):
        with atomic.atomic_output(tmp_path / "a.txt") as tmp:
            tmp.write_text("partial")
            raise RuntimeError("writer crashed")
    assert (tmp_path / "a.txt").read_text(encoding="utf-8") == "héllo\n"
    assert sorted(os.listdir(tmp_path)) == ["a.txt", "b.bin", "c.json", "d.data", "e.npz"]


@pytest.mark.parametrize("element", ["hexahedron", "tetra", "tetra10"])
def test_cell_stresses_pass_the_patch_test(element):
    """A displacement linear in x (u = H x) has the same strain in every cell of any element
    type: every cell's stress is λ tr(ε) I + 2με, ε = (H + Hᵀ)/2, to round-off."""
    from contactopt.fem.elasticity import ElasticityAssembler, lame
    from contactopt.mesh.block import block_mesh
    from contactopt.mesh.tetsplit import hex_to_tets, tet4_to_tet10
    ref = block_mesh(2.0, 1.0, 0.5, 4, 2, 2)
    rng = np.random.default_rng(3)
    points = ref.points + 0.02 * rng.standard_normal(ref.points.shape)       # distorted cells
    cells = ref.cells
    if element != "hexahedron":
        cells = hex_to_tets(ref.cells, points)
    if element == "tetra10":
        points, cells = tet4_to_tet10(points, cells)
    H = rng.standard_normal((3, 3)) * 1e-3
    asm = ElasticityAssembler(cells, points.shape[0], [], 21.19, 0.277, element=element)
    s = asm.cell_stresses(points, (points @ H.T).ravel())
    lam, mu = lame(21.19, 0.277)
    eps = 0.5 * (H + H.T)
    sig = lam * np.trace(eps) * np.eye(3) + 2 * mu * eps
    expect = np.array([sig[0, 0], sig[1, 1], sig[2, 2], sig[1, 2], sig[0, 2], sig[0, 1]])
    assert np.abs(s - expect).max() <= 1e-12 * np.abs(expect).max()
