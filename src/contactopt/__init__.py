"""contactopt: shape optimization of 3D elastic bodies in contact with Coulomb friction.

Public interface (docs/api.md): :func:`load_config`, :class:`ShapeProblem`, and the
sub-packages ``contactopt.contact`` (``solve_local``) and ``contactopt.optimize``
(``minimize_bundle``).
"""

import os
from importlib.metadata import PackageNotFoundError, version

# MKL's OpenMP threads (PARDISO) spin for 200 ms after each parallel region by default and then
# compete with NumPy's BLAS threads for the same cores: on 2 cores that doubled the time of the
# dense steps that follow a Schur complement. Must be set before libmkl_rt is loaded.
os.environ.setdefault("KMP_BLOCKTIME", "0")

from .config import Config, load_config
from .errors import (
    CheckpointError,
    ConfigError,
    ContactNotConverged,
    ContactOptError,
    InfeasibleDesignError,
    MeshError,
    SolverError,
)

try:
    __version__ = version("contactopt")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0"


def __getattr__(name):
    if name == "ShapeProblem":
        from .problem import ShapeProblem
        return ShapeProblem
    raise AttributeError(name)


__all__ = ["Config", "load_config", "ShapeProblem", "ContactOptError", "ConfigError",
           "ContactNotConverged", "InfeasibleDesignError", "MeshError", "SolverError", "CheckpointError"]
