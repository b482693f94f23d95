"""Open a run's exported files in FreeCAD, as a CAD user would (optional; Debian's freecad).

    apt-get install freecad
    CONTACTOPT_RUNS="runs/round_pad runs/bracket" freecadcmd benchmarks/freecad_check.py

For each run directory: the contact surface from STEP and IGES (a valid shape, its faces, area
and bounding box; STEP/IGES are in millimetres) and the body's STL (a closed solid without
non-manifold edges or self-intersections, and its volume). Prints one line per file.
"""

import os

import FreeCAD  # noqa: F401  (FreeCAD's own interpreter)
import Mesh
import Part


def check(run: str) -> None:
    name = os.path.basename(os.path.normpath(run))
    for ext in ("step", "iges"):
        shape = Part.Shape()
        shape.read(os.path.join(run, f"contact_surface.{ext}"))
        bb = shape.BoundBox
        kinds = sorted({type(f.Surface).__name__ for f in shape.Faces})
        print(f"{name} {ext}: valid {shape.isValid()}, {len(shape.Faces)} face(s) {kinds}, area {shape.Area:.6f} mm², "
              f"box [{bb.XMin:.3f}, {bb.XMax:.3f}] × [{bb.YMin:.3f}, {bb.YMax:.3f}] × [{bb.ZMin:.4f}, {bb.ZMax:.4f}] mm")
    m = Mesh.Mesh(os.path.join(run, "optimal_body.stl"))
    print(f"{name} stl: {m.CountFacets} facets, closed solid {m.isSolid()}, non-manifold edges "
          f"{m.hasNonManifolds()}, self-intersections {m.hasSelfIntersections()}, volume {m.Volume:.9f}")


for run in os.environ.get("CONTACTOPT_RUNS", "").split():
    check(run)
