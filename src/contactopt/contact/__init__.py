"""Contact solvers in local (Delassus) form: ``u = W r + q``, per contact (normal, t1, t2).

``solve_local`` is the entry point; ``LocalResult`` its result. The methods are the semismooth
Newton method (``newton``) and the paper's successive approximations with Kučera's algorithm
for each Tresca problem (``fixed_point``, ``tresca``); ``cones`` has the projections and the
Siconos error measure.
"""

from .cones import complementarity_violations, node_class, siconos_error
from .local import LocalResult, solve_local
from .tresca import TrescaResult, solve_tresca

__all__ = [
    "LocalResult",
    "TrescaResult",
    "complementarity_violations",
    "node_class",
    "siconos_error",
    "solve_local",
    "solve_tresca",
]
