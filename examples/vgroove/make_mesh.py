"""The wedge and the V-groove of examples/vgroove.toml:

    python examples/vgroove/make_mesh.py      # writes examples/vgroove/wedge.msh and groove.stl

A wedge (a prism along x2, 0 ≤ x2 ≤ 0.5) whose flanks x1 = ±x3 tan 30° from x3 = 0.25 to 1 sit on the
flanks of a rigid V-groove of half-angle 30° with its apex at the origin. The mesh is the half
x1 ≥ 0 (the symmetry plane x1 = 0 through the wedge's middle), 6 × 16 × 2 hexahedra (across, up,
along x2), groups flank, top, wedge; the groove is a closed STL, longer than the wedge along x2.
The geometry: contactopt.verification.vgroove.
"""

from pathlib import Path

from contactopt.verification import vgroove

HERE = Path(__file__).resolve().parent

if __name__ == "__main__":
    print("wrote", vgroove.wedge_mesh(HERE / "wedge.msh", 6, 16, 2, half=True))
    print("wrote", vgroove.groove_stl(HERE / "groove.stl"))
