"""Accuracy of the exported files (issue #24), at the optimal designs of runs or at given designs.

    PYTHONPATH=src python benchmarks/export_accuracy.py [--runs DIR]

For the round pad (P1 tetrahedra, trimmed disc), the bracket (Q1 hexahedra) and Example 1's block
(Q1, at a random design of U): the STEP and IGES surfaces read back by OpenCASCADE against ϑ_α at
1000 random points; the STL's watertightness, orientation and enclosed volume against the FE
volume (the file's 32-bit floats and the double-precision triangulation; for hexahedra also what
two triangles per warped face would give); the exported body's state at α = 0 against the design's.
DIR/<name>/alpha.json is used where it exists (benchmarks/pressure_figures.py makes the runs).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from contactopt.config import load_config
from contactopt.io import export
from contactopt.problem import ShapeProblem

ROOT = Path(__file__).resolve().parent.parent


def surface_error(path, model, alpha, rng) -> float:
    s = model.surface
    with export.gmsh_session() as gmsh:
        gmsh.model.add("readback")
        with export._quiet():
            gmsh.model.occ.importShapes(str(path))
        gmsh.model.occ.synchronize()
        tag = gmsh.model.getEntities(2)[0][1]
        uv = rng.random((1000, 2))
        X = np.array(gmsh.model.getValue(2, tag, uv.ravel())).reshape(-1, 3)
        gmsh.model.remove()
    return float(np.max(np.abs(X[:, 2] - s.evaluate(alpha, X[:, 0], X[:, 1]))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", default="runs")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    cases = [("round_pad", load_config(ROOT / "examples" / "round_pad.toml")),
             ("bracket", load_config(ROOT / "examples" / "bracket.toml")),
             ("example1", load_config("example1"))]
    for name, cfg in cases:
        problem = ShapeProblem(cfg.with_updates({"state": {"tol": 1e-12}}))
        model = problem.model
        saved = Path(args.runs) / name / "alpha.json"
        if saved.is_file():
            alpha, what = np.asarray(json.loads(saved.read_text())["alpha"], float).ravel(), f"optimum of {saved}"
        else:
            alpha = model.initial_design() + 0.2 * cfg["design"]["C0"] * rng.random(model.n_design)
            what = "a random design near α0"
        x = model.mesh.coordinates(alpha)
        with tempfile.TemporaryDirectory() as tmp:
            res = export.export_design(model, alpha, tmp)
            e_step = surface_error(Path(tmp) / "contact_surface.step", model, alpha, rng)
            e_iges = surface_error(Path(tmp) / "contact_surface.iges", model, alpha, rng)
            vol = export.fe_volume(model, x)
            fp, ft = export.read_stl(Path(tmp) / "optimal_body.stl")
            fchk = export.triangle_mesh_check(fp, ft)
            dchk = export.triangle_mesh_check(*export.stl_triangles(model, x))
            st = problem.solve_state(alpha)
            again = ShapeProblem(load_config(Path(tmp) / "optimal_body.toml"))
            st0 = again.solve_state(np.zeros(again.model.n_design))
        print(f"{name} ({model.mesh.cell_type}, {what}; mesh {res['mesh_format']}, "
              f"surface {'trimmed' if res.get('surface_trimmed') else 'untrimmed'}):")
        print(f"  STEP |z - theta| max {e_step:.2e}, IGES {e_iges:.2e} (1000 random points)")
        print(f"  STL {fchk['triangles']} triangles, every edge in two: {fchk['edges_ok']}, consistently "
              f"oriented: {fchk['oriented']}, volume > 0 (outward): {fchk['volume'] > 0}")
        print(f"  volume FE {vol:.12g}; STL file rel. diff {abs(fchk['volume'] - vol) / vol:.2e}, "
              f"triangulation in double {abs(dchk['volume'] - vol) / vol:.2e}")
        if model.mesh.cell_type == "hexahedron":
            faces = model.body.reference.boundary_faces()
            two = np.concatenate([faces[:, [0, 1, 2]], faces[:, [0, 2, 3]]])
            v2 = export.triangle_mesh_check(x, two)["volume"]
            print(f"  two triangles per face instead of four: volume rel. diff {abs(v2 - vol) / vol:.2e} "
                  "(the warped faces)")
        rel = {f: float(np.max(np.abs(np.asarray(getattr(st, f)) - np.asarray(getattr(st0, f))))
                        / max(np.abs(np.asarray(getattr(st, f))).max(), 1e-300)) for f in ("lam", "u", "gap")}
        print("  round trip at alpha = 0: max rel. diff " + ", ".join(f"{k} {v:.1e}" for k, v in rel.items())
              + f" (max lambda {st.lam.max():.3g})")


if __name__ == "__main__":
    main()
