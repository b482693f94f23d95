"""Outputs on six-node contact faces (ten-node tetrahedra): the pressure read in the transformed
basis (contactopt.io.pressure) and the node classes of the maps, on Hertz's sphere pressed into a
quarter block of Gmsh tetrahedra (contactopt.verification.hertz_tets), frictionless.
"""

import numpy as np
import pytest
import scipy.sparse as sp

from contactopt.contact.state import CLASS_CODES
from contactopt.io.pressure import contact_areas, contact_pressure, face_classes, transformed_weights
from contactopt.verification.hertz_tets import A_TARGET, measure, quarter_mesh

pytest.importorskip("gmsh")


@pytest.fixture(scope="module")
def hertz10(tmp_path_factory):
    mesh = quarter_mesh(tmp_path_factory.mktemp("hertz10") / "q.msh", A_TARGET / 4, order=2, growth=0.5)
    return measure(mesh)


def test_the_pressure_on_tet10_faces_is_nonnegative_and_zero_outside_the_contact(hertz10):
    m = hertz10["problem"].model
    r, p, a, p0 = hertz10["r"], hertz10["p"], hertz10["a"], hertz10["p0"]
    assert m.body.contact_face.faces.shape[1] == 6
    assert np.all(p >= -1e-12 * p0)
    # one element: the longest edge of the faces within the fine zone (1.6 a)
    faces = m.body.contact_face.faces
    x = m.body.reference.points
    near = np.hypot(x[faces[:, 0], 0], x[faces[:, 0], 1]) < 1.6 * a
    corners = x[faces[near][:, :3]]
    h = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).max()
    assert np.all(p[r > a + h] == 0.0)
    assert hertz10["rms"] <= 0.03
    # the corners carry pressure inside the contact (their own nodal force is about zero there)
    corner = np.isin(m.contact_nodes, faces[:, :3])
    assert np.all(p[corner & (r < a - h)] > 0.1 * p0)


def test_every_node_of_a_tet10_face_inside_the_contact_is_classed_in_contact(hertz10):
    pr, st = hertz10["problem"], hertz10["state"]
    r, a = hertz10["r"], hertz10["a"]
    faces = pr.model.body.contact_face.faces
    x = pr.model.body.reference.points
    corners = x[faces[:, :3]]
    h = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2)[np.hypot(corners[:, 0, 0], corners[:, 0, 1]) < 1.6 * a].max()
    codes = face_classes(pr.model, st)
    inside, outside = r < a - h, r > a + h
    assert inside.sum() > 20
    assert np.all(codes[inside] == CLASS_CODES["M1"])        # frictionless contact: sliding
    assert np.all(codes[outside] == CLASS_CODES["L"])
    # the state's own classes (its subgradient's) are unchanged
    assert np.array_equal(codes[~np.isin(pr.model.contact_nodes, faces[:, :3])],
                          st.classes[~np.isin(pr.model.contact_nodes, faces[:, :3])])


def test_the_transformed_weights_recover_a_uniform_pressure_and_keep_the_total_force(hertz10):
    m = hertz10["problem"].model
    faces, nodes, coords = m.body.contact_face.faces, m.contact_nodes, m.body.reference.points
    T = transformed_weights(faces, nodes)
    assert sp.issparse(T) and T.shape == (nodes.size, nodes.size)
    a = contact_areas(coords, faces, nodes)
    # uniform p̄: λ = p̄ a, read back exactly; Σ_j (T v)_j = Σ_j v_j (Σ of the transformed functions is 1)
    assert np.allclose(contact_pressure(m, 2.5 * a, coords)[(T @ a) > 0], 2.5, rtol=1e-13)
    # Σ_j N̂_j = Σ_k N_k = 1: every column of T sums to one (every face node is a contact node here)
    assert np.all(np.isin(np.unique(faces), nodes))
    assert np.abs(np.asarray(T.sum(axis=0)).ravel() - 1.0).max() <= 1e-15
