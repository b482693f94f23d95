"""Contact pressure p = λ / a (issue #24): uniform where the load is, whatever the nodal spacing.

A box on the foundation, frictionless, pressed by a uniform pressure p̄ on its top: symmetry
clamps (u1 = 0 on x1 = 0, u2 = 0 on x2 = 0 above the foundation, u3 = 0 at one bottom corner,
where the exact u3 is 0 anyway) let it expand sideways, so the exact state is linear (σ = −p̄ e3⊗e3) and every element
type reproduces it: λ_m = p̄·a_m exactly, and p_m = p̄ to round-off on an unstructured mesh whose
nodal forces vary from node to node with the tributary areas.
"""

from pathlib import Path

import meshio
import numpy as np
import pytest

from contactopt.config import load_config
from contactopt.io import statefiles, vtk
from contactopt.io.pressure import contact_areas, contact_pressure
from contactopt.problem import ShapeProblem

P_BAR = 0.02


def _box_msh(path: Path, order: int = 1, size: float = 0.23) -> Path:
    gmsh = pytest.importorskip("gmsh")
    from contactopt.io.export import _quiet, gmsh_session
    with gmsh_session():
        gmsh.model.add("box")
        gmsh.model.occ.addBox(0, 0, 0, 1.0, 0.7, 0.5)
        gmsh.model.occ.synchronize()
        faces = {}
        for dim, tag in gmsh.model.getEntities(2):
            x, y, z = gmsh.model.occ.getCenterOfMass(dim, tag)
            name = "bottom" if abs(z) < 1e-9 else "top" if abs(z - 0.5) < 1e-9 else None
            if name:
                faces[name] = tag
        for k, (name, tag) in enumerate(sorted(faces.items()), start=1):
            gmsh.model.addPhysicalGroup(2, [tag], k, name=name)
        gmsh.model.addPhysicalGroup(3, [1], 10, name="box")
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.3 * size)
        gmsh.option.setNumber("Mesh.Algorithm", 6)
        gmsh.option.setNumber("Mesh.RandomSeed", 0.1)
        with _quiet():
            gmsh.model.mesh.generate(3)
            if order == 2:
                gmsh.model.mesh.setOrder(2)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(path))
        gmsh.model.remove()
    return path


def uniform_pressure_config(mesh, friction=0.0):
    return load_config({
        "name": "uniform",
        "body": {"mesh": str(mesh), "contact": "bottom",
                 # symmetry planes above the foundation (a clamped node is no contact node), one
                 # bottom corner held vertically
                 "clamped": [{"on": {"x1": 0.0, "box": [[0, 0], [0, 1], [0.01, 1]]}, "components": [1]},
                             {"on": {"x2": 0.0, "box": [[0, 1], [0, 0], [0.01, 1]]}, "components": [2]},
                             {"on": {"box": [[0, 0], [0, 0], [0, 0]]}, "components": [3]}]},
        "material": {"E": 21.19, "nu": 0.3}, "friction": {"coefficient": friction},
        "loads": {"pressure": [{"on": "top", "value": P_BAR}]},
        "design": {"degree": [2, 2], "C0": 0.05, "C1": 0.5, "C2": 0.0, "initial": 0.0},
        "state": {"tol": 1e-12},
    })


def test_uniform_pressure_gives_a_uniform_pressure_map_on_tetrahedral_faces(tmp_path):
    problem = ShapeProblem(uniform_pressure_config(_box_msh(tmp_path / "box.msh")))
    model = problem.model
    st = problem.solve_state(np.zeros(model.n_design))
    p = contact_pressure(model, st.lam, st.coords)
    assert np.all(st.lam > 0)
    spread = st.lam.max() / st.lam.min()
    assert spread > 2.0                       # the nodal forces are far from uniform ...
    assert np.max(np.abs(p / P_BAR - 1.0)) < 1e-8     # ... the pressure is p̄
    # the lumped areas of all the face's nodes add up to its area
    faces = model.body.contact_face.faces
    all_nodes = np.unique(faces)
    assert abs(contact_areas(st.coords, faces, all_nodes).sum() - 0.7) < 1e-12


def test_uniform_pressure_on_hexahedra_and_on_a_designed_surface(tmp_path):
    # the block of hexahedra as a file body with the same symmetry clamps; on a lifted (curved)
    # contact surface the areas are those of the current faces
    from contactopt.mesh.block import block_mesh
    ref = block_mesh(1.0, 0.7, 0.5, 6, 5, 3)
    ftype = "quad"
    cells = [("hexahedron", ref.cells), (ftype, ref.parts["contact"].faces), (ftype, ref.parts["top"].faces)]
    m = meshio.Mesh(ref.points, cells, cell_data={"gmsh:physical": [np.full(len(c[1]), k + 1) for k, c in enumerate(cells)],
                                                  "gmsh:geometrical": [np.full(len(c[1]), k + 1) for k, c in enumerate(cells)]},
                    field_data={"box": np.array([1, 3]), "bottom": np.array([2, 2]), "top": np.array([3, 2])})
    meshio.write(tmp_path / "hex.msh", m, file_format="gmsh22", binary=False)
    problem = ShapeProblem(uniform_pressure_config(tmp_path / "hex.msh"))
    model = problem.model
    st = problem.solve_state(np.zeros(model.n_design))
    p = contact_pressure(model, st.lam, st.coords)
    assert st.lam.max() / st.lam.min() > 3.5      # edge and corner nodes carry half and a quarter
    assert np.max(np.abs(p / P_BAR - 1.0)) < 1e-8
    # areas on the current coordinates: a lifted surface has more area than its projection
    alpha = np.linspace(0.0, 0.04, model.n_design)
    x = model.mesh.coordinates(alpha)
    faces = model.body.contact_face.faces
    a_flat = contact_areas(ref.points, faces, model.contact_nodes)
    a_lift = contact_areas(x, faces, model.contact_nodes)
    assert np.all(a_lift >= a_flat - 1e-15) and a_lift.sum() > a_flat.sum()


def test_quadratic_faces_use_the_projection(tmp_path):
    # on P2 faces λ vanishes at the face corners: the pressure is the projection M p = λ, exact
    # when no node of the face is clamped. The box held at its top (u3 = 0) and pushed δ into the
    # foundation (α = −δ: the gap is −δ) is in uniaxial compression, p = E δ / (c + δ) uniform
    cfg = uniform_pressure_config(_box_msh(tmp_path / "box2.msh", order=2, size=0.3))
    body = dict(cfg["body"])
    body["clamped"] = body["clamped"][:2] + [{"on": "top", "components": [3]}]
    problem = ShapeProblem(cfg.with_updates({"body": body, "loads": {"pressure": []}}))
    model = problem.model
    assert model.body.contact_face.faces.shape[1] == 6
    delta = 1e-3
    st = problem.solve_state(np.full(model.n_design, -delta))
    p = contact_pressure(model, st.lam, st.coords)
    p_exact = 21.19 * delta / (0.5 + delta)
    corners = np.isin(model.contact_nodes, model.body.contact_face.faces[:, :3])
    assert np.max(np.abs(st.lam[corners])) < 1e-10 * st.lam.max()    # λ/a would be 0/0 there
    assert np.max(np.abs(p / p_exact - 1.0)) < 1e-8


def test_pressure_in_the_vtu_and_the_state_files(tmp_path):
    problem = ShapeProblem(uniform_pressure_config(_box_msh(tmp_path / "box.msh", size=0.35)))
    model = problem.model
    st = problem.solve_state(np.zeros(model.n_design))
    pd = vtk.body_point_data(model, st)
    cn = model.contact_nodes
    assert np.allclose(pd["contact_pressure"][cn], P_BAR, rtol=1e-8)
    off = np.setdiff1d(np.arange(model.mesh.n_nodes), cn)
    assert np.all(pd["contact_pressure"][off] == 0)
    written = statefiles.write_state(tmp_path / "s", model, st)
    assert "pressure.png" in written and (tmp_path / "s" / "pressure.png").stat().st_size > 1000
    z = np.load(tmp_path / "s" / "state.npz")
    assert np.allclose(z["pressure"], P_BAR, rtol=1e-8)
