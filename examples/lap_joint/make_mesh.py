"""The bolt head of examples/lap_joint.toml: a box of hexahedra on the upper plate, as a Gmsh file.

    python examples/lap_joint/make_mesh.py     # writes head.msh here

The head is the box [0.5, 1.0] × [0.25, 0.75] × [0.25, 0.5] (4 × 4 × 2 cells) over the bolt's
place on the upper plate (the built-in block 3 × 1 × 0.25 of the example), with the groups of a
generated box: ``top``, ``bottom`` (the face on the plate), ``left``, ``right``, ``front``,
``back``, and ``head`` (the volume).
"""

import sys
from pathlib import Path

import meshio
import numpy as np

from contactopt.mesh.foundation import foundation_block

HERE = Path(__file__).parent


def main(out=HERE, cells=(4, 4, 2)):
    ref = foundation_block([0.5, 0.5, 0.25], list(cells), [0.5, 0.25])
    names = ("top", "bottom", "left", "right", "front", "back")
    blocks = [("quad", ref.parts[n].faces) for n in names] + [(ref.cell_type, ref.cells)]
    phys = [np.full(len(b[1]), t) for t, b in enumerate(blocks, start=1)]
    fd = {n: np.array([t, 2]) for t, n in enumerate(names, start=1)} | {"head": np.array([len(blocks), 3])}
    path = Path(out) / "head.msh"
    meshio.write(path, meshio.Mesh(ref.points + [0.0, 0.0, 0.5], blocks, cell_data={"gmsh:physical": phys},
                                   field_data=fd), file_format="gmsh22", binary=False)
    return path


if __name__ == "__main__":
    print(main(*sys.argv[1:2]))
