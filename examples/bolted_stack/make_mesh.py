"""The plates and the nut of examples/bolted_stack.toml, as Gmsh files.

    python examples/bolted_stack/make_mesh.py     # writes plate1.msh, plate2.msh and nut.msh here

Under the bolt head (the built-in block [0, 1]² × [0, 0.5] of the example) two plates 0.25 thick
lap over each other and the nut holds them from below:

- ``plate1.msh``: [−0.5, 2.5] × [−0.5, 1.5] × [−0.25, 0], 15 × 10 × 2 cells (it runs out to the
  right, where it is clamped);
- ``plate2.msh``: [−1.5, 1.5] × [−0.5, 1.5] × [−0.5, −0.25], 13 × 9 × 2 cells (out to the left);
- ``nut.msh``: [0, 1]² × [−1, −0.5], 7 × 7 × 3 cells.

Every mesh its own grid, so that no two faces' nodes meet (mortar partners). Each file has the
groups of a generated box: ``top``, ``bottom``, ``left``, ``right``, ``front``, ``back`` and the
volume.
"""

import sys
from pathlib import Path

import meshio
import numpy as np

from contactopt.mesh.foundation import foundation_block

HERE = Path(__file__).parent
BOXES = {  # name: (size, cells, origin (x1, x2), top x3)
    "plate1": ([3.0, 2.0, 0.25], [15, 10, 2], [-0.5, -0.5], 0.0),
    "plate2": ([3.0, 2.0, 0.25], [13, 9, 2], [-1.5, -0.5], -0.25),
    "nut": ([1.0, 1.0, 0.5], [7, 7, 3], [0.0, 0.0], -0.5),
}


def box(path, size, cells, origin, top):
    """A box of hexahedra whose top lies at x3 = ``top``, with the groups of a generated box."""
    ref = foundation_block(size, cells, origin)
    names = ("top", "bottom", "left", "right", "front", "back")
    blocks = [("quad", ref.parts[n].faces) for n in names] + [(ref.cell_type, ref.cells)]
    phys = [np.full(len(b[1]), t) for t, b in enumerate(blocks, start=1)]
    fd = {n: np.array([t, 2]) for t, n in enumerate(names, start=1)} | {path.stem: np.array([len(blocks), 3])}
    meshio.write(path, meshio.Mesh(ref.points + [0.0, 0.0, top], blocks, cell_data={"gmsh:physical": phys},
                                   field_data=fd), file_format="gmsh22", binary=False)
    return path


def main(out=HERE):
    return [box(Path(out) / f"{name}.msh", *spec) for name, spec in BOXES.items()]


if __name__ == "__main__":
    for p in main(*sys.argv[1:2]):
        print(p)
