"""What the Hertz pressure error on linear tetrahedra is made of
(contactopt.verification.hertz_tets.error_parts): a rigid sphere pressed into a quarter block of Gmsh
tetrahedra at a/6, frictionless; the computed forces λ against the forces of the exact pressure,
λ_H = ∫ N p_Hertz dA, each read as a pressure three ways.

Sign convention: λ ≥ 0 the normal force of the sphere on the body at a contact node (frame t1, t2, n).
"""

import numpy as np
import pytest

from contactopt.io.pressure import contact_areas
from contactopt.verification.hertz import resultant
from contactopt.verification.hertz_tets import (
    A_TARGET,
    READINGS,
    error_parts,
    face_stress_pressure,
    measure,
    quarter_mesh,
    read_pressure,
)

pytest.importorskip("gmsh")


@pytest.fixture(scope="module")
def hertz4(tmp_path_factory):
    res = measure(quarter_mesh(tmp_path_factory.mktemp("hertz4") / "q.msh", A_TARGET / 6))
    res["parts"] = error_parts(res)
    return res


def test_every_reading_recovers_a_uniform_pressure_exactly(hertz4):
    m, st = hertz4["problem"].model, hertz4["state"]
    areas = contact_areas(st.coords, m.body.contact_face.faces, m.contact_nodes)
    for reading in READINGS:
        p = read_pressure(m, 2.5 * areas, st.coords, reading)
        assert np.abs(p - 2.5).max() <= 1e-12 * 2.5, reading
    with pytest.raises(ValueError, match="'smooth'"):
        read_pressure(m, areas, st.coords, "smooth")


def test_the_exact_forces_carry_the_force_and_read_back_inside_the_contact(hertz4):
    parts = hertz4["parts"]
    P = float(resultant(hertz4["problem"], hertz4["state"])[2])          # the quarter's force
    assert abs(parts["lam_hertz"].sum() - P) <= 1e-3 * P
    # the exact forces read node-wise: coarse only at the edge of the contact
    assert parts["nodal"]["reading_in"] <= 0.01
    assert parts["nodal"]["reading"] > parts["nodal"]["reading_in"]


def test_on_linear_tetrahedra_the_error_is_in_the_forces_not_in_their_reading(hertz4):
    nodal, l2 = hertz4["parts"]["nodal"], hertz4["parts"]["l2"]
    assert nodal["forces_in"] >= 5 * nodal["reading_in"]
    assert nodal["forces"] >= 1.5 * nodal["reading"]
    # the L²-projection undoes the lumping that hides part of the forces' scatter: worse than the
    # nodal reading, and negative (the nodal reading of λ ≥ 0 is not)
    assert l2["total"] >= 2 * nodal["total"]
    assert l2["min"] < -0.1 and nodal["min"] >= 0.0
    # the body's stress reads the same pressure as its forces, to the same error
    p = face_stress_pressure(hertz4["problem"].model, hertz4["state"])
    use = hertz4["r"] < 1.5 * hertz4["a"]
    rms = np.sqrt(np.mean((p - hertz4["p_hertz"])[use] ** 2)) / hertz4["p0"]
    assert 0.5 * nodal["total"] <= rms <= 2 * nodal["total"]
