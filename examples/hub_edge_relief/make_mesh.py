"""The meshes of examples/hub_edge_relief.toml: a quarter hub (bore radius 1, outer radius 2,
half-length 0.25) and a quarter shaft of radius 1.001 (the fit's interference δ = 1e-3) and
half-length 0.5, both from their mid-plane x3 = 0, the shaft coarser around than the hub (meshes
that do not match). contactopt.verification.lame writes them.

    python examples/hub_edge_relief/make_mesh.py [NR NT NZ]     # default 8 32 8
"""

import sys
from pathlib import Path

from contactopt.verification import lame

here = Path(__file__).resolve().parent
nr, nt, nz = (int(v) for v in sys.argv[1:4]) if len(sys.argv) > 3 else (8, 32, 8)
lame.quarter_hub_mesh(here / "hub.msh", nr, nt, nz, length=0.25)
lame.quarter_shaft_mesh(here / "shaft.msh", max(3, 3 * nr // 4), 3 * nt // 4, 2 * nz, radius=lame.B + lame.DELTA,
                        length=0.5)
