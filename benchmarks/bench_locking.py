"""Volumetric locking on a Hertz contact: standard against B-bar hexahedra as ν → 1/2.

    python benchmarks/bench_locking.py [--nu 0.3 0.45 0.49 0.499] [--fine 8]

The body: the block [−W, W]² × [0, H] (W = H = 1) whose bottom face is the paraboloid
x3 = r²/2R (R = 5, written into the mesh: ``[body] initial_gap = "mesh"``), its top clamped,
pressed onto the rigid plane by the approach δ = 0.002 (the design ϑ_α = −δ, a constant: the gap
is r²/2R − δ), frictionless. The Hertz contact radius is about a = √(Rδ) = 0.1 = H/10, so the
block is a half-space for the contact. The mesh is graded: cubes of side h = a/``fine`` on
[−1.5a, 1.5a]² × [0, 1.5a], growing geometrically (ratio ≤ 1.35) to the faces of the block;
the contact face is the bottom in r∞ ≤ 1.5a.

Hertz (rigid plane, elastic paraboloid): with the measured total force P = Σ λ_m and
E* = E/(1 − ν²), a = (3PR/4E*)^{1/3}, p0 = 3P/(2πa²), p(r) = p0 √(1 − r²/a²). The nodal pressure
is λ_m/A_m (A_m the tributary area ∫N_m dS of the contact node). Printed per ν and formulation:
the peak error |p(0) − p0|/p0 and the rms error of the profile over the nodes with r < a,
relative to p0 (the brief's measure: near r = a it compares a nodal average with a point value
of a profile whose slope is infinite there, so it is dominated by the few nodes next to the edge
and jumps when one crosses r = a), and the rms of the nodal forces λ_m against the Hertz
pressure's consistent nodal forces ∫N_m p_H dS (per tributary area, relative to p0, over the
nodes either loads), which compares like with like. The same mesh for every row; ν only changes
the material.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import meshio
import numpy as np
import tomli_w

from contactopt.config import load_config
from contactopt.problem import ShapeProblem

W, H, R, DELTA, E = 1.0, 1.0, 5.0, 0.002, 1.0
A_EST = np.sqrt(R * DELTA)


def graded(fine: int, half: float, a: float = A_EST, ratio: float = 1.35) -> np.ndarray:
    """Node coordinates on [0, half]: h = a/fine up to 1.5a, then growing by at most ``ratio``."""
    h = a / fine
    core = np.arange(0, int(round(1.5 * fine)) + 1) * h
    x, step = [core[-1]], h
    while x[-1] < half - 1e-12:
        step *= ratio
        x.append(x[-1] + step)
    outer = np.array(x)
    # stretch the graded part so that it ends exactly at ``half``
    outer = core[-1] + (outer - core[-1]) * (half - core[-1]) / (outer[-1] - core[-1])
    return np.concatenate([core, outer[1:]])


def hertz_mesh(path: Path, fine: int) -> float:
    """The graded block with the paraboloidal bottom as a VTU file of hexahedra; returns h."""
    g = graded(fine, W)
    xs = np.concatenate([-g[:0:-1], g])
    zs = graded(fine, H)
    nx, nz = xs.size, zs.size
    X, Y, Z = np.meshgrid(xs, xs, zs, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    r2 = pts[:, 0] ** 2 + pts[:, 1] ** 2
    pts[:, 2] += (1.0 - pts[:, 2] / H) * r2 / (2 * R)      # bottom: x3 = r²/2R; top stays at H

    def nid(i, j, k):
        return (i * nx + j) * nz + k
    i, j, k = np.meshgrid(np.arange(nx - 1), np.arange(nx - 1), np.arange(nz - 1), indexing="ij")
    i, j, k = i.ravel(), j.ravel(), k.ravel()
    cells = np.column_stack([nid(i, j, k), nid(i + 1, j, k), nid(i + 1, j + 1, k), nid(i, j + 1, k),
                             nid(i, j, k + 1), nid(i + 1, j, k + 1), nid(i + 1, j + 1, k + 1), nid(i, j + 1, k + 1)])
    meshio.write(path, meshio.Mesh(pts, [("hexahedron", cells)]))
    return A_EST / fine


def configuration(mesh: Path, nu: float, formulation: str) -> dict:
    c = 1.5 * A_EST + 1e-9
    return {
        "name": f"hertz_{formulation}_{nu}",
        "body": {"mesh": str(mesh), "clamped": {"x3": H}, "initial_gap": "mesh",
                 "contact": {"box": [[-c, c], [-c, c], [-0.01, 0.01]]}},
        "material": {"E": E, "nu": nu, "formulation": formulation},
        "friction": {"coefficient": 0.0},
        "loads": {"body_force": [0.0, 0.0, 0.0]},
        "design": {"degree": [1, 1], "C0": 0.01, "C1": 1.0, "C2": 1.0, "initial": 0.0},
        "objective": {"type": "target_normal_force", "target": {"kind": "constant", "value": 0.0}},
        "state": {"method": "newton", "tol": 1e-12},
        "linear_solver": {"path": "delassus"},
    }


def hertz_nodal_forces(model, a: float, p0: float, order: int = 12) -> np.ndarray:
    """∫ N_m p_H dS per contact node: the consistent nodal forces of the Hertz pressure on the
    contact face's quadrilaterals (projected on x3 = 0; a Gauss rule of ``order``² points per face)."""
    from contactopt.fem.elements import quad_shape
    faces = np.asarray(model.body.contact_face.faces)
    xy = model.body.reference.points[:, :2]
    g, w = np.polynomial.legendre.leggauss(order)
    q = np.array([(s, t) for t in g for s in g])
    wq = np.outer(w, w).ravel()
    N, dN = quad_shape(q)
    X = xy[faces]                                                # (F, 4, 2)
    x = np.einsum("qa,fam->fqm", N, X)
    J = np.einsum("qak,fam->fqmk", dN, X)
    det = np.abs(J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0])
    ph = p0 * np.sqrt(np.clip(1 - (x[..., 0] ** 2 + x[..., 1] ** 2) / a ** 2, 0, None))
    fe = np.einsum("q,fq,fq,qa->fa", wq, det, ph, N)
    F = np.bincount(faces.ravel(), fe.ravel(), minlength=xy.shape[0])
    return F[model.contact_nodes]


def hertz_errors(problem, state) -> dict:
    """Peak and rms profile errors of the nodal pressure against Hertz with the measured force;
    ``rms_forces``: the rms of the nodal forces against the Hertz pressure's consistent nodal
    forces over the nodes either of them loads, relative to p0 times the tributary area."""
    model = problem.model
    lam = state.lam
    P = float(lam.sum())
    nu = model.config["material"]["nu"]
    Es = E / (1 - nu ** 2)
    a = (3 * P * R / (4 * Es)) ** (1 / 3)
    p0 = 3 * P / (2 * np.pi * a ** 2)
    xy = model.body.reference.points[model.contact_nodes, :2]
    r = np.hypot(xy[:, 0], xy[:, 1])
    p = lam / model.contact_areas()
    centre = int(np.argmin(r))
    inside = r < a
    ph = p0 * np.sqrt(np.clip(1 - (r / a) ** 2, 0, None))
    FH = hertz_nodal_forces(model, a, p0)
    loaded = (FH > 0) | (lam > 0)
    d = (lam - FH)[loaded] / model.contact_areas()[loaded]
    return {"P": P, "a": a, "p0": p0, "peak": abs(p[centre] - p0) / p0,
            "rms": float(np.sqrt(np.mean((p[inside] - ph[inside]) ** 2)) / p0), "n_in": int(inside.sum()),
            "rms_forces": float(np.sqrt(np.mean(d ** 2)) / p0)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nu", type=float, nargs="+", default=[0.3, 0.45, 0.49, 0.499])
    ap.add_argument("--fine", type=int, default=8, help="elements per contact radius a under the contact")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        mesh = Path(tmp) / "hertz.vtu"
        h = hertz_mesh(mesh, args.fine)
        rows = []
        for nu in args.nu:
            for form in ("standard", "bbar"):
                toml = Path(tmp) / "c.toml"
                toml.write_text(tomli_w.dumps(configuration(mesh, nu, form)))
                pr = ShapeProblem(load_config(toml))
                t0 = time.perf_counter()
                alpha = np.full(pr.model.n_design, -DELTA)
                st = pr.solve_state(alpha)
                e = hertz_errors(pr, st)
                rows.append((nu, form, e, time.perf_counter() - t0))
                print(f"ν = {nu:<6g} {form:9s} P = {e['P']:.5g}  a = {e['a']:.4f}  p0 = {e['p0']:.5f}  "
                      f"peak error {100 * e['peak']:6.2f} %  rms {100 * e['rms']:6.2f} %  "
                      f"rms of the forces {100 * e['rms_forces']:6.2f} %  "
                      f"({e['n_in']} nodes in r < a, {time.perf_counter() - t0:.1f} s)", flush=True)
        n_el = pr.model.assembler.elements.shape[0]
        print(f"\nmesh: {n_el} hexahedra, {pr.model.assembler.n_free} free DOFs, {pr.model.n_contact} contact "
              f"nodes, h = a/{args.fine} = {h:.4g} under the contact\n")
        print("| ν | standard: peak | rms | rms of the forces | B-bar: peak | rms | rms of the forces |")
        print("|---|---|---|---|---|---|---|")
        for nu in args.nu:
            s, b = [e for (n, f, e, _) in rows if n == nu]
            print(f"| {nu:g} | " + " | ".join(f"{100 * x[k]:.2f} %" for x in (s, b)
                                                for k in ("peak", "rms", "rms_forces")) + " |")


if __name__ == "__main__":
    main()
