"""Nodal contact forces λ against the contact pressure p = λ/a at the optimal designs of the round
pad and the bracket (issue #24): docs/figures/pressure_<name>.png and a roughness ratio.

    PYTHONPATH=src python benchmarks/pressure_figures.py [--runs DIR] [--out docs/figures] [--refine 0.5,0.35]

Optimizes both examples (or reuses DIR/<name> when it holds a finished run) and prints, for each,
the roughness of λ and of p: the mean over the contact face's edges between two loaded nodes of
|f_i − f_j| / mean(f) — how much a field jumps from a node to its neighbour.

``--refine``: the round pad's optimal design (a Bézier surface: it does not depend on the mesh) on
the example's mesh and on meshes of its .geo with the element sizes scaled by these factors:
roughness and scatter of p — the rms of p minus its patch mean (Σ_n M_mn p_n / Σ_n M_mn, M the
face mass matrix) relative to mean p — which measure the node-to-node scatter of linear
tetrahedra's contact forces; docs/figures/pressure_round_pad_refined.png shows the finest map.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from contactopt.config import load_config
from contactopt.io.plots import plot_force_and_pressure
from contactopt.io.pressure import contact_areas, contact_pressure, face_mass
from contactopt.problem import ShapeProblem
from contactopt.runner import run_optimization

ROOT = Path(__file__).resolve().parent.parent


def roughness(model, values) -> float:
    faces = np.asarray(model.body.contact_face.faces)
    nc = 4 if faces.shape[1] == 4 else 3
    index = np.full(model.mesh.n_nodes, -1)
    index[model.contact_nodes] = np.arange(model.n_contact)
    e = np.unique(np.sort(np.concatenate([faces[:, [k, (k + 1) % nc]] for k in range(nc)]), axis=1), axis=0)
    e = index[e]
    e = e[np.all(e >= 0, axis=1)]
    v = np.asarray(values, float)
    loaded = (v[e[:, 0]] > 0) & (v[e[:, 1]] > 0)
    e = e[loaded]
    return float(np.mean(np.abs(v[e[:, 0]] - v[e[:, 1]])) / np.mean(v[v > 0]))


def scatter(model, lam, coords) -> float:
    """rms of p − (its patch mean) over the loaded nodes, relative to mean p (module docstring)."""
    faces = model.body.contact_face.faces
    p = contact_pressure(model, lam, coords)
    mean = (face_mass(coords, faces, model.contact_nodes) @ p) / contact_areas(coords, faces, model.contact_nodes)
    on = lam > 0
    return float(np.sqrt(np.mean((p - mean)[on] ** 2)) / p[on].mean())


def refined_round_pad(alpha, factors, out: Path) -> None:
    import tempfile

    import gmsh
    geo = (ROOT / "examples" / "round_pad" / "round_pad.geo").read_text()
    base = load_config(ROOT / "examples" / "round_pad.toml")
    print("round pad, optimal design: mesh size factor, DOFs, contact nodes, roughness of λ and p, scatter of p")
    with tempfile.TemporaryDirectory() as tmp:
        for f in (1.0, *factors):
            cfg = base
            if f != 1.0:
                g = geo.replace("Mesh.MeshSizeMax = 0.055;", f"Mesh.MeshSizeMax = {0.055 * f};")
                g = g.replace("Mesh.MeshSizeMin = 0.02;", f"Mesh.MeshSizeMin = {0.02 * f};")
                src, msh = Path(tmp) / f"pad{f}.geo", Path(tmp) / f"pad{f}.msh"
                src.write_text(g)
                gmsh.initialize()
                gmsh.option.setNumber("General.Terminal", 0)
                gmsh.open(str(src))
                gmsh.model.mesh.generate(3)
                gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
                gmsh.write(str(msh))
                gmsh.finalize()
                cfg = base.with_updates({"body": {"mesh": str(msh)}})
            problem = ShapeProblem(cfg)
            m = problem.model
            st = problem.solve_state(alpha)
            p = contact_pressure(m, st.lam, st.coords)
            print(f"  {f:5.2f}  {m.assembler.n_free:7d}  {m.n_contact:5d}  {roughness(m, st.lam):.3f}  "
                  f"{roughness(m, p):.3f}  {scatter(m, st.lam, st.coords):.4f}", flush=True)
        path = plot_force_and_pressure(out / "pressure_round_pad_refined.png", m, st.lam, p,
                                       title=f"round_pad: the same optimal design, element sizes × {f}")
        print(f"  {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", default="runs", help="directory of the runs (reused when finished)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures"))
    ap.add_argument("--refine", default="", help="mesh size factors for the round pad, e.g. 0.5,0.35")
    args = ap.parse_args()
    for name in ("round_pad", "bracket"):
        run = Path(args.runs) / name
        if not (run / "summary.json").is_file():
            run_optimization(ROOT / "examples" / f"{name}.toml", run, overwrite=True)
        alpha = np.asarray(json.loads((run / "alpha.json").read_text())["alpha"], float).ravel()
        problem = ShapeProblem(load_config(ROOT / "examples" / f"{name}.toml"))
        st = problem.solve_state(alpha)
        p = contact_pressure(problem.model, st.lam, st.coords)
        path = plot_force_and_pressure(Path(args.out) / f"pressure_{name}.png", problem.model, st.lam, p,
                                       title=f"{name}: optimal design ({problem.model.mesh.cell_type} mesh)")
        print(f"{name}: roughness of lambda {roughness(problem.model, st.lam):.3f}, of p "
              f"{roughness(problem.model, p):.3f}; scatter of p {scatter(problem.model, st.lam, st.coords):.4f}; "
              f"p in [{p[p > 0].min():.4g}, {p.max():.4g}]; {path}")
        if name == "round_pad" and args.refine:
            refined_round_pad(alpha, [float(v) for v in args.refine.split(",")], Path(args.out))


if __name__ == "__main__":
    main()
