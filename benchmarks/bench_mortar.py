"""Mortar partners on the elastic foundation: the contact patch test, convergence, cost.

    python benchmarks/bench_mortar.py [--part patch|meshes|hertz|hertz4|tets|tetparts|cost|cost10|all] [--steps 6]
        [--pads 8 12 16 24] [--order 1|2]

patch   The contact patch test of contactopt.verification.patch (overlap loading) with point,
        averaged and mortar partners, F = 0 and 0.3: max and rms of (λ/a − p)/p, max ‖τ‖/(a p).
meshes  The body 12×6×4 of the tests on the slab [−0.5, 2.5]×[−0.5, 1.5]×[−1, 0] (E_f = E/10),
        the slab 0.5, 1, 1.5, 2 times as fine as the body, against a slab 3 times as fine with the
        same partners: max |λ − λ_ref| / max λ_ref and ‖λ − λ_ref‖₂ / ‖λ_ref‖₂, averaged and mortar.
hertz   Two bodies of one material in Hertz contact (E = 1, ν = 0.3, R = 2: the paraboloidal pad
        [0, 2]²×[0, 1] on the slab [0, 2]²×[−1, 0], pressed by a body force, F = 0): the pad n×n on
        a slab 0.7 n and 1.5 n, averaged and mortar partners, against the matching slab (point
        partners, node-to-node): rms of (p − p_match)/p0 over the face (the non-matching bias),
        and rms of (p − p_Hertz)/p0, p = λ/a per node, p_Hertz = p0 √(1 − r²/a²) from Σλ.
hertz4  The same two bodies on tetrahedra: the pad's grid n×n×max(4, n/2) and the slab's split
        into six tetrahedra per hexahedron (Kuhn split, face diagonals along +x1+x2), linear or
        (--order 2) ten-node, the pad n = --pads. The reference: when the two split faces have
        the same nodes and triangles (checked), the matching slab with point partners (ten-node:
        with mortar partners, the same coupling), mortar against point partners on the matching
        faces shown for both; else the slab 1.5 n with mortar partners. a/h the contact radius
        in pad elements; p the nodal pressure of contactopt.io.pressure.contact_pressure (on
        six-node triangles that of the transformed basis).
tets    Hertz on Gmsh tetrahedra (contactopt.verification.hertz_tets): a rigid sphere pressed into a
        quarter block of linear and quadratic tetrahedra of size a/6, a/8, a/10 (--sizes), and of
        the graded grid split into six linear tetrahedra per hexahedron; the
        gap node-wise and dual-weighted ([obstacle] weighting): rms and max of (p − p_Hertz)/p0
        within 1.5 a, the rate of the rms between refinements, the rms within 0.8 a (the interior
        of the contact); and the exact Hertz pressure read
        as the nodal pressure reads λ (∫ N_m p_Hertz dA / a_m), the floor of the nodal reading.
        --growth and --fine: the Gmsh meshes' grading (h + growth·(d − fine·a) beyond fine·a).
tetparts
        What that error is made of (contactopt.verification.hertz_tets.error_parts) on the meshes
        of --mesh (gmsh, split, tet10), sizes --sizes, Gmsh grading --growth, --fine, Poisson's
        ratio --nu (the force that of contact radius a for it): per reading
        of the forces (nodal λ/a, L²-projection M p = λ, hat-weighted mean of λ/a) the rms of
        p(λ) − p_Hertz (total), p(λ) − p(λ_H) (the forces' error, λ_H = ∫ N p_Hertz the forces of
        the exact pressure) and p(λ_H) − p_Hertz (the reading's error), within 1.5 a and 0.8 a,
        relative to p0; the L² reading's least value; the pressure −σ33 of the face's tetrahedra;
        the correlation, within 0.8 a, of the forces' error with the number of tetrahedra per
        face triangle at the node.
cost    examples/example1_elastic.toml (body 32×15×9, slab 24×16×8: non-matching): the time to
        build the partners (segmentation and mortar matrices once per run) and the median time of
        one evaluation (state + subgradient) along a path of small design steps, mortar against
        averaged partners, the two problems taking turns at every design (ratio in one run).
cost10  A tet10 body 8×8×2 on hexahedra 10×10×2 (the patch test's blocks, a sideways pull): the
        median time of one evaluation with mortar partners in the transformed basis against point
        partners, taking turns at every design (ratio in one run).
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from pathlib import Path

import meshio
import numpy as np

from contactopt.config import load_config
from contactopt.fem.elements import tri_rule
from contactopt.fem.foundation import averaged_partners, mortar_partners
from contactopt.problem import ShapeProblem
from contactopt.verification.patch import patch_config, patch_errors

ROOT = Path(__file__).resolve().parents[1]
ELASTIC = ROOT / "examples" / "example1_elastic.toml"
E = 21.19

PATCH = [("7×7 on 7×7, matching", 7, 7, "hexahedron", "hexahedron"),
         ("7×7 on 10×10", 7, 10, "hexahedron", "hexahedron"),
         ("10×10 on 7×7", 10, 7, "hexahedron", "hexahedron"),
         ("8×8 on an offset 8×8", 8, 8, "hexahedron", "offset"),
         ("hexahedra 7×7 on tetrahedra 10×10", 7, 10, "hexahedron", "tetra"),
         ("tetrahedra 7×7 on hexahedra 10×10", 7, 10, "tetra", "hexahedron"),
         ("tetrahedra 10×10 on tetrahedra 7×7", 10, 7, "tetra", "tetra"),
         ("hexahedra 7×7 on tet10 5×5", 7, 5, "hexahedron", "tetra10"),
         ("tet10 4×4 on hexahedra 5×5", 4, 5, "tetra10", "hexahedron"),
         ("tet10 5×5 on tetrahedra 4×4", 5, 4, "tetra10", "tetra"),
         ("tet10 4×4 on tet10 3×3", 4, 3, "tetra10", "tetra10")]


def patch(only=None) -> None:
    print("| body on foundation | partner | F = 0: max / rms | F = 0.3: max / rms | F = 0.3: max ‖τ‖/(a p) |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for label, nb, nf, body, found in PATCH if only is None else [c for c in PATCH if only in c[0]]:
            # six-node triangles: ∫N_m = 0 at the corners, so λ/a is only defined in the transformed
            # basis of mortar partners (averaged partners take linear faces only)
            for partner in ("mortar",) if body == "tetra10" else ("point", "average", "mortar"):
                row = []
                for friction in (0.0, 0.3):
                    pb = ShapeProblem(patch_config(nb, nf, friction, tmp, body=body, foundation=found,
                                                   partner=partner))
                    row.append(patch_errors(pb, pb.solve_state(pb.model.initial_design())))
                print(f"| {label} | {partner} | {row[0]['max']:.1e} / {row[0]['rms']:.1e} | "
                      f"{row[1]['max']:.1e} / {row[1]['rms']:.1e} | {row[1]['shear']:.1e} |", flush=True)


def meshes() -> None:
    base = load_config("example1").with_updates({"mesh": {"nx": 12, "ny": 6, "nz": 4}})
    same = np.array([18, 12, 4])

    def lam(f, partner):
        cells = [max(1, int(round(v))) for v in f * same]
        pb = ShapeProblem(base.with_updates({"foundation": {
            "block": {"size": [3.0, 2.0, 1.0], "cells": cells, "origin": [-0.5, -0.5]},
            "material": {"E": E / 10}, "partner": partner}}))
        return pb.solve_state(pb.model.initial_design()).lam

    print("slab/body   averaged: max, 2-norm        mortar: max, 2-norm")
    refs = {p: lam(3.0, p) for p in ("average", "mortar")}
    for f in (0.5, 1.0, 1.5, 2.0):
        out = []
        for p, ref in refs.items():
            d = lam(f, p) - ref
            out.append(f"{np.abs(d).max() / ref.max():.3e}, {np.linalg.norm(d) / np.linalg.norm(ref):.3e}")
        print(f"{f:6.1f}      {out[0]}        {out[1]}", flush=True)


def _pad(n: int, slab: int, partner: str) -> dict:
    b = np.array([0.25, -0.25, 0.25])            # (x − 1)²/2R on [0, 2] in the Bernstein basis, R = 2
    return {"name": f"pad{n}", "geometry": {"a": 2.0, "b": 2.0, "c": 1.0},
            "mesh": {"nx": n, "ny": n, "nz": max(4, n // 2)}, "body": {"clamped": "top"},
            "material": {"E": 1.0, "nu": 0.3}, "friction": {"coefficient": 0.0},
            "loads": {"top_traction": [0.0] * 3, "right_traction": [0.0] * 3, "body_force": [0.0, 0.0, -0.08]},
            "design": {"degree": [2, 2], "C0": 0.6, "lower": -0.6,
                       "initial": (b[:, None] + b[None, :]).tolist()},
            "objective": {"type": "compliance"}, "state": {"method": "newton", "tol": 1e-12},
            "foundation": {"block": {"size": [2.0, 2.0, 1.0], "cells": [slab, slab, max(4, slab // 2)]},
                           "top": "top", "clamped": "bottom", "partner": partner}}


def hertz(sizes=(12, 16, 24)) -> None:
    from contactopt.io.pressure import contact_areas
    estar = 1.0 / (2 * (1 - 0.3 ** 2))
    print("| pad n | slab | partner | rms (p − p_match)/p0 | rms (p − p_Hertz)/p0 |")
    print("|---|---|---|---|---|")
    for n in sizes:
        def pressure(slab, partner):
            pb = ShapeProblem(load_config(_pad(n, slab, partner)))
            st = pb.solve_state(pb.model.initial_design())
            b = pb.model.body
            x = b.reference.points[b.contact_nodes, :2]
            p = st.lam / contact_areas(b.reference.points, b.contact_face.faces, b.contact_nodes)
            P = st.lam.sum()
            a = (3 * P * 2.0 / (4 * estar)) ** (1 / 3)
            p0 = 3 * P / (2 * np.pi * a * a)
            r2 = ((x - 1.0) ** 2).sum(axis=1)
            return p, p0 * np.sqrt(np.clip(1 - r2 / a ** 2, 0, None)), p0
        pm, ph, p0 = pressure(n, "point")
        print(f"| {n} | {n} (matching) | point | 0 | {np.sqrt(np.mean((pm - ph) ** 2)) / p0:.2e} |", flush=True)
        for slab in (int(round(0.7 * n)), int(round(1.5 * n))):
            for partner in ("average", "mortar"):
                p, ph, p0 = pressure(slab, partner)
                print(f"| {n} | {slab} | {partner} | {np.sqrt(np.mean((p - pm) ** 2)) / p0:.2e} | "
                      f"{np.sqrt(np.mean((p - ph) ** 2)) / p0:.2e} |", flush=True)


def _tet_pad(tmp: Path, n: int, slab: int, partner: str, order: int = 1) -> dict:
    """:func:`_pad` on tetrahedra: the pad's grid n×n×max(4, n/2) split into six tetrahedra per
    hexahedron (face diagonals along +x1+x2), written to ``tmp`` with its contact face x3 = 0 and
    its clamped top x3 = 1; the slab the block split the same way, or (``order`` 2) both of
    ten-node tetrahedra, the slab a mesh file too."""
    from contactopt.mesh.block import block_mesh
    from contactopt.mesh.foundation import foundation_block
    from contactopt.mesh.tetsplit import hex_to_tets, tet4_to_tet10
    data = _pad(n, slab, partner)
    for key in ("geometry", "mesh"):
        data.pop(key)
    ctype = "tetra" if order == 1 else "tetra10"
    pad = Path(tmp, f"pad{n}_{order}.vtu")
    if not pad.exists():
        ref = block_mesh(2.0, 2.0, 1.0, n, n, max(4, n // 2))
        pts, cells = ref.points, hex_to_tets(ref.cells, ref.points)
        if order == 2:
            pts, cells = tet4_to_tet10(pts, cells)
        meshio.write(pad, meshio.Mesh(pts, [(ctype, cells)]))
    data["body"] = {"mesh": str(pad), "contact": {"x3": 0.0}, "clamped": {"x3": 1.0}, "fixed_shape": [{"x3": 1.0}]}
    data["loads"] = {"body_force": data["loads"]["body_force"]}
    data["design"]["domain"] = [[0.0, 2.0], [0.0, 2.0]]
    f = data["foundation"]
    if order == 1:
        f["block"]["element"] = "tetra"
    else:
        cells = f.pop("block")["cells"]
        path = Path(tmp, f"slab{slab}_{order}.vtu")
        if not path.exists():
            ref = foundation_block([2.0, 2.0, 1.0], cells, element="tetra")
            p10, c10 = tet4_to_tet10(ref.points, ref.cells)
            meshio.write(path, meshio.Mesh(p10, [(ctype, c10)]))
        f.update(mesh=str(path), top={"x3": 0.0}, clamped={"x3": -1.0})
    return data


def _matching_faces(n: int) -> bool:
    """Whether the pad's split contact face and the split matching slab's top face have the same
    nodes and the same triangles (compared by their vertices' (x1, x2))."""
    from contactopt.mesh.block import block_mesh
    from contactopt.mesh.foundation import foundation_block
    from contactopt.mesh.tetsplit import hex_to_tets, tet_boundary_faces
    ref = block_mesh(2.0, 2.0, 1.0, n, n, max(4, n // 2))
    bf = tet_boundary_faces(hex_to_tets(ref.cells, ref.points))
    pad = ref.points[bf[np.all(ref.points[bf, 2] == 0.0, axis=1)]][:, :, :2]
    slab = foundation_block([2.0, 2.0, 1.0], [n, n, max(4, n // 2)], element="tetra")
    top = slab.points[slab.parts["top"].faces][:, :, :2]

    def key(tris):
        return {tuple(sorted(map(tuple, t))) for t in np.round(tris * 1e9).astype(np.int64).tolist()}
    nodes = {v for t in key(pad) for v in t}
    nodes_top = {v for t in key(top) for v in t}
    return nodes == nodes_top and key(pad) == key(top)


def hertz4(sizes=(8, 12, 16, 24), order: int = 1) -> None:
    from contactopt.io.pressure import contact_pressure
    estar = 1.0 / (2 * (1 - 0.3 ** 2))
    print("| pad n | a/h | slab | partner | rms (p − p_ref)/p0 | rms (p − p_Hertz)/p0 |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            def pressure(slab, partner):
                pb = ShapeProblem(load_config(_tet_pad(Path(tmp), n, slab, partner, order)))
                st = pb.solve_state(pb.model.initial_design())
                b = pb.model.body
                x = b.reference.points[b.contact_nodes, :2]
                p = contact_pressure(pb.model, st.lam, b.reference.points)
                P = st.lam.sum()
                a = (3 * P * 2.0 / (4 * estar)) ** (1 / 3)
                p0 = 3 * P / (2 * np.pi * a * a)
                r2 = ((x - 1.0) ** 2).sum(axis=1)
                return p, p0 * np.sqrt(np.clip(1 - r2 / a ** 2, 0, None)), p0, a * n / 2.0

            def rms(d, p0):
                return f"{np.sqrt(np.mean(d ** 2)) / p0:.2e}"
            slabs = (int(round(0.7 * n)), int(round(1.5 * n)))
            if _matching_faces(n):
                pm, ph, p0, ah = pressure(n, "point")
                print(f"| {n} | {ah:.1f} | {n} (matching) | point | 0 | {rms(pm - ph, p0)} |", flush=True)
                # mortar partners on the matching faces: point partners' result on linear faces; the
                # transformed basis of six-node triangles is another coupling, so there its matching
                # result is the reference of the non-matching ones
                pq, ph, p0, ah = pressure(n, "mortar")
                print(f"| {n} | {ah:.1f} | {n} (matching) | mortar | {rms(pq - pm, p0)} (against point) | "
                      f"{rms(pq - ph, p0)} |", flush=True)
                if order == 2:
                    pm = pq
            else:                     # no node-to-node reference: the finest slab with mortar partners
                pm, ph, p0, ah = pressure(slabs[1], "mortar")
                print(f"| {n} | {ah:.1f} | {slabs[1]} (reference: faces do not match) | mortar | 0 | "
                      f"{rms(pm - ph, p0)} |", flush=True)
            for slab in slabs:
                # averaged partners take linear faces only
                for partner in ("average", "mortar") if order == 1 else ("mortar",):
                    p, ph, p0, ah = pressure(slab, partner)
                    print(f"| {n} | {ah:.1f} | {slab} | {partner} | {rms(p - pm, p0)} | {rms(p - ph, p0)} |",
                          flush=True)

def tets(sizes=(6, 8, 10), growth=0.25, fine=1.6) -> None:
    from contactopt.fem.elements import face_for
    from contactopt.io.pressure import contact_areas
    from contactopt.verification.hertz_tets import A_TARGET, measure, quarter_mesh, split_mesh

    def floor(res):
        """rms of (∫ N_m p_Hertz dA / a_m − p_Hertz(x_m))/p0 within 1.5 a (linear faces)."""
        m = res["problem"].model
        faces, pts = m.body.contact_face.faces, m.body.reference.points
        ft = face_for(faces)
        q, w = tri_rule(10)
        N, dN = ft.shape(q)
        X = pts[faces]
        T1, T2 = np.einsum("fam,qa->fqm", X, dN[:, :, 0]), np.einsum("fam,qa->fqm", X, dN[:, :, 1])
        dA = np.linalg.norm(np.cross(T1, T2), axis=2) * w
        xq = np.einsum("qa,fam->fqm", N, X)
        rq = np.hypot(xq[..., 0], xq[..., 1])
        pq = res["p0"] * np.sqrt(np.clip(1 - (rq / res["a"]) ** 2, 0, None))
        f = np.bincount(faces.ravel(), weights=np.einsum("fq,qa,fq->fa", dA, N, pq).ravel(), minlength=pts.shape[0])
        pn = f[m.contact_nodes] / contact_areas(pts, faces, m.contact_nodes)
        use = res["r"] < 1.5 * res["a"]
        return float(np.sqrt(np.mean((pn[use] - res["p_hertz"][use]) ** 2)) / res["p0"])

    print("| elements | h | contact nodes | gap | rms (p − p_Hertz)/p0 | max | rate | rms within 0.8 a "
          "| nodal reading of p_Hertz: rms | time |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for order, kind in ((1, "tetra"), (0, "tetra, split grid"), (2, "tetra10")):
            last = {}
            for k in sizes:
                mesh = (split_mesh(Path(tmp) / f"s{k}.msh", A_TARGET / k) if order == 0 else
                        quarter_mesh(Path(tmp) / f"q{order}_{k}.msh", A_TARGET / k, order=order, growth=growth,
                                     fine=fine))
                for weighting in (("node", "mortar") if order < 2 else ("node",)):
                    res = measure(mesh, weighting)
                    rate = (math.log(last[weighting][1] / res["rms"]) / math.log(k / last[weighting][0])
                            if weighting in last else float("nan"))
                    last[weighting] = (k, res["rms"])
                    fl = f"{floor(res):.2e}" if order < 2 else "–"
                    inner = res["r"] < 0.8 * res["a"]
                    ri = np.sqrt(np.mean((res["p"] - res["p_hertz"])[inner] ** 2)) / res["p0"]
                    print(f"| {kind} | a/{k} | {res['contact_nodes']} | {weighting} | {res['rms']:.2e} | "
                          f"{res['max']:.2e} | {'' if math.isnan(rate) else f'{rate:.2f}'} | {ri:.2e} | {fl} | "
                          f"{res['time']:.1f} s |", flush=True)


def tetparts(meshes=("gmsh",), sizes=(6, 8, 10), growth=0.25, fine=1.6, nu=0.3) -> None:
    from contactopt.io.pressure import contact_pressure
    from contactopt.verification import hertz_tets as ht

    def per_face(model):
        """tetrahedra per face triangle at each contact node"""
        n = model.body.reference.points.shape[0]
        tets = np.bincount(np.asarray(model.assembler.elements).ravel(), minlength=n)
        tris = np.bincount(np.asarray(model.body.contact_face.faces).ravel(), minlength=n)
        return (tets / np.maximum(tris, 1))[model.contact_nodes]

    print(f"Gmsh grading: growth {growth}, fine zone {fine} a; ν = {nu}")
    print("| mesh | h | contact nodes | nodal: total / forces / reading | within 0.8 a | "
          "L²: total / forces / reading | L²: least p/p0 (exact forces) | mean: total / reading | "
          "stress −σ33 | corr | time |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for kind in meshes:
            for k in sizes:
                path = Path(tmp) / f"{kind}{k}.msh"
                mesh = (ht.split_mesh(path, ht.A_TARGET / k) if kind == "split" else
                        ht.quarter_mesh(path, ht.A_TARGET / k, order=2 if kind == "tet10" else 1, growth=growth,
                                        fine=fine))
                res = ht.measure(mesh, nu=nu)
                e = ht.error_parts(res)
                m, st = res["problem"].model, res["state"]
                nd, l2 = e["nodal"], e["l2"]
                inner = res["r"] < 0.8 * res["a"]
                linear = kind != "tet10"
                if linear:
                    ps = ht.face_stress_pressure(m, st)
                    use = res["r"] < 1.5 * res["a"]
                    stress = f"{np.sqrt(np.mean((ps - res['p_hertz'])[use] ** 2)) / res['p0']:.2e}"
                    err = contact_pressure(m, st.lam - e["lam_hertz"], st.coords)[inner]
                    corr = f"{np.corrcoef(err, per_face(m)[inner])[0, 1]:+.2f}"
                else:
                    stress = corr = "–"
                mean = f"{e['mean']['total']:.2e} / {e['mean']['reading']:.2e}" if linear else "–"
                print(f"| {kind} | a/{k} | {res['contact_nodes']} | {nd['total']:.2e} / {nd['forces']:.2e} / "
                      f"{nd['reading']:.2e} | {nd['total_in']:.2e} / {nd['forces_in']:.2e} / {nd['reading_in']:.2e} | "
                      f"{l2['total']:.2e} / {l2['forces']:.2e} / {l2['reading']:.2e} | {l2['min']:.3f} "
                      f"({l2['min_exact']:.3f}) | {mean} | {stress} | {corr} | "
                      f"{res['time']:.1f} s |", flush=True)


def cost(steps: int) -> None:
    el = load_config(ELASTIC)
    pbs = {p: ShapeProblem(el.with_updates({"foundation": {**el["foundation"], "partner": p}}))
           for p in ("average", "mortar")}
    body, fm = pbs["mortar"].model.body, pbs["mortar"].model.foundation.mesh
    build = {}
    for name, fn in (("average", averaged_partners), ("mortar", mortar_partners)):
        ts = []
        for _ in range(3):
            t = time.perf_counter()
            fn(body, fm, "bench")
            ts.append(time.perf_counter() - t)
        build[name] = min(ts)
    a = pbs["mortar"].model.initial_design()
    rng = np.random.default_rng(0)
    times = {k: [] for k in pbs}
    for pb in pbs.values():
        pb.evaluate(a)                           # cold
    for _ in range(steps):
        d = rng.standard_normal(a.size)
        a = a + 1e-4 * (d - d.mean())
        for name, pb in pbs.items():
            t = time.perf_counter()
            pb.evaluate(a)
            times[name].append(time.perf_counter() - t)
    med = {k: statistics.median(v) for k, v in times.items()}
    for name in pbs:
        f = pbs[name].model.foundation
        print(f"{name:8s} partners built in {build[name]:.3f} s (once per run), Π {f.Pi.nnz} nonzeros, "
              f"{f.support.size} support nodes; {med[name]:.3f} s per evaluation")
    print(f"mortar / averaged: evaluation ×{med['mortar'] / med['average']:.3f}, "
          f"partners ×{build['mortar'] / build['average']:.2f}")


def cost10(steps: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        pbs = {}
        for partner in ("point", "mortar"):
            Path(tmp, partner).mkdir()
            cfg = patch_config(8, 10, 0.3, Path(tmp, partner), body="tetra10", partner=partner)
            pbs[partner] = ShapeProblem(cfg.with_updates(
                {"design": {"degree": [2, 2], "initial": -0.002},
                 "loads": {"traction": [{"on": {"x3": 1.0}, "value": [0.02, 0.01, 0.0]}]}}))
        a = pbs["mortar"].model.initial_design()
        for pb in pbs.values():
            pb.evaluate(a)                           # cold
        rng = np.random.default_rng(0)
        times = {k: [] for k in pbs}
        for _ in range(steps):
            a = a + 1e-4 * rng.standard_normal(a.size)
            for name, pb in pbs.items():
                t = time.perf_counter()
                pb.evaluate(a)
                times[name].append(time.perf_counter() - t)
    med = {k: statistics.median(v) for k, v in times.items()}
    for name, t in med.items():
        print(f"tet10 body, {name:6s} partners: {t:.3f} s per evaluation")
    print(f"mortar (transformed basis) / point: evaluation ×{med['mortar'] / med['point']:.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--part", default="all",
                    choices=["patch", "meshes", "hertz", "hertz4", "tets", "tetparts", "cost", "cost10", "all"])
    ap.add_argument("--steps", type=int, default=6)
    ap.add_argument("--sizes", type=int, nargs="+", default=[6, 8, 10], help="tets: element sizes a/k")
    ap.add_argument("--pads", type=int, nargs="+", default=[8, 12, 16], help="hertz4: pad divisions n")
    ap.add_argument("--order", type=int, default=1, choices=[1, 2], help="hertz4: 1 linear, 2 ten-node tetrahedra")
    ap.add_argument("--growth", type=float, default=0.25, help="tets, tetparts: Gmsh size growth beyond the fine zone")
    ap.add_argument("--fine", type=float, default=1.6, help="tets, tetparts: radius of the fine zone, in units of a")
    ap.add_argument("--mesh", nargs="+", default=["gmsh"], choices=["gmsh", "split", "tet10"], help="tetparts: meshes")
    ap.add_argument("--nu", type=float, default=0.3, help="tetparts: Poisson's ratio of the block")
    args = ap.parse_args()
    if args.part in ("patch", "all"):
        patch()
    if args.part in ("meshes", "all"):
        meshes()
    if args.part in ("hertz", "all"):
        hertz()
    if args.part in ("hertz4", "all"):
        hertz4(tuple(args.pads), args.order)
    if args.part in ("tets", "all"):
        tets(tuple(args.sizes), args.growth, args.fine)
    if args.part in ("tetparts", "all"):
        tetparts(tuple(args.mesh), tuple(args.sizes), args.growth, args.fine, args.nu)
    if args.part in ("cost", "all"):
        cost(args.steps)
    if args.part in ("cost10", "all"):
        cost10(args.steps)


if __name__ == "__main__":
    main()
