"""Solver paths: how a design's contact states and adjoints are solved (docs/architecture.md).

Every path implements :class:`~contactopt.paths.base.SolverPath`; :func:`select_path` decides
once, from ``[linear_solver]`` and the size of the body, which one a configuration runs on.

======================  ===============================================  =====================
``path``                a design costs                                   for
======================  ===============================================  =====================
``"condensation"``      a sparse factorization of A(α) onto the contact  small and medium meshes
                        DOFs, dense S and the zone's W_Z
``"delassus"``          a sparse Cholesky of A(α), products W r by        large meshes with MKL
                        solves, W_Z on the zone only
``"fullspace"``         semismooth Newton on all DOFs, AMG-preconditioned meshes no factorization
                        GMRES, nothing factorized                        fits
``"petsc"``             the full-space method on PETSc (GAMG, GMRES),    one optimization on
                        the mesh split over MPI ranks                    many cores / machines
======================  ===============================================  =====================

The PETSc path imports petsc4py and mpi4py only when it runs: ``pip install .`` does not need them.
"""

from __future__ import annotations

import logging
from types import MappingProxyType

from .. import _mpi
from ..config.validation import check_interactions
from ..errors import ConfigError
from ..fem.linsolve import pardiso_available
from ..fem.memory import PathEstimates
from ..sensitivity.objectives import FULL_SPACE, constraint_types, objective_types
from .base import Capabilities, Context, Settings, SolverPath, Start
from .condensation import CondensationPath
from .delassus import DelassusPath
from .fullspace import FullSpacePath
from .petsc import PetscPath

log = logging.getLogger(__name__)


PATHS = MappingProxyType({cls.name: cls for cls in (CondensationPath, DelassusPath, FullSpacePath, PetscPath)})
NAMES = tuple(PATHS)

__all__ = ("PATHS", "NAMES", "SolverPath", "Settings", "Context", "Capabilities", "Start", "needs",
           "select_path", "path_estimates", "make_path", "library_for")


def library_for(name: str, library: str) -> str:
    """The sparse solver of a path: its own (``Capabilities.sparse``: "pyamg", "petsc"), else
    ``library`` unless "auto" (then MKL PARDISO where the mkl wheel is installed, else SciPy)."""
    own = PATHS[name].capabilities.sparse
    if own is not None:
        return own
    if library != "auto":
        return library
    return "pardiso" if pardiso_available() else "scipy"


def needs(config, pinned: int = 0, ranks: int = 1, rigid=None) -> dict:
    """What a configuration needs of a path: {feature of :class:`~contactopt.paths.base.Capabilities`: what needs it}.

    ``pinned``: the number of clamped tangential components of contact nodes (a symmetry plane
    through the contact face, ``contactopt.mesh.body``); ``ranks``: the MPI ranks of the run;
    ``rigid``: the rigid motions the clamps leave free (``contactopt.mesh.rigid``), or None."""
    out, foundation = {}, config.foundation is not None
    types = objective_types(config) | constraint_types(config)     # [[constraints]] are objectives too
    if foundation:
        out["foundation"] = "an elastic [foundation]"
        if config.foundation.control != "fixed":
            out["foundation"] = f"an elastic [foundation] with foundation.control = {config.foundation.control!r}"
        if config.foundation.control == "force":     # its translation's search runs where the foundation is
            out["counterpart_force"] = "an elastic [foundation] with foundation.control = 'force'"
    if config.pairs:                    # several pairs, each its elastic or rigid counterpart (fem.counterparts)
        kind = "rigid counterparts" if all(pr.rigid for pr in config.pairs) else "elastic bodies"
        out["foundation"] = out["pairs"] = f"{len(config.pairs)} contact pairs against {kind}"
        if any(pr.rigid and pr.obstacle.control == "force" for pr in config.pairs):    # its translation's search
            out["counterpart_force"] = "a rigid counterpart of several pairs pressed by control = 'force'"
        if any(not pr.rigid and pr.foundation.control == "force" for pr in config.pairs):
            out["counterpart_force"] = "a counterpart body of several pairs pressed by control = 'force'"
    obst = config.obstacle
    obstacle = "plane" if obst is None else obst.shape
    if obst is not None and obst.control == "force":
        obstacle = f"force-controlled {obstacle}"
    elif obst is not None and obst.moves_tangentially:
        obstacle = f"{obstacle} moved tangentially"
    if obstacle != "plane":             # the contact frames rotate the system (paths/condensation.py, ...)
        out["obstacle"] = obstacle
    if rigid is not None:               # clamps that leave rigid motions free (paths/rigid.py)
        out["held_by_contact"] = ", ".join(rigid.names())
    if pinned:
        out["pinned"] = str(pinned)
    if "compliance" in types or config.objective.type == "compliance":
        out["compliance"] = "the compliance objective"
    full = sorted(types & FULL_SPACE)
    if full:
        out["whole_displacement"] = ", ".join(full)
    if config.load_steps or any(case.steps for case in config.load_cases):
        out["load_steps"] = "[[load_steps]]"
        if "obstacle" in out:
            out["obstacle_steps"] = out["obstacle"]
    if ranks > 1:
        out["many_ranks"] = str(ranks)
    return out


def select_path(config, n_free: int, pinned: int = 0, rigid=None, pinned_held: bool = False) -> tuple[str, str]:
    """(path, library) of a configuration for a body of ``n_free`` free DOFs.

    The paths that take what the configuration needs (:func:`needs`, each path's
    :class:`~contactopt.paths.base.Capabilities`) qualify; ``path = "auto"`` takes among them the PETSc path under
    ``mpiexec`` with more than one rank, else the full-space path from ``crossover`` free DOFs on
    (the measured crossover, docs/large_meshes.md; the Delassus path where pyamg is missing and
    PARDISO is installed), else the condensation. So the compliance objective (it needs the
    condensed load ℓ on every contact DOF), an elastic ``[foundation]`` and a body held only by
    contact stay on the condensation, and "auto" keeps any rigid obstacle there too, force-controlled
    or not (the Delassus and full-space paths take it when asked). A path asked for that lacks a feature is
    refused with what it lacks and the paths that take it; so is one whose libraries are missing.
    Features that exclude each other on every path are refused first
    (:func:`~contactopt.config.validation.check_interactions`; ``pinned_held``: the pinned
    components are clamped at their partners on an elastic foundation too)."""
    from .._mpi import world_size
    check_interactions(config, pinned=pinned, rigid=None if rigid is None else ", ".join(rigid.names()),
                       pinned_held=pinned_held)
    ls = config.linear_solver
    name, ranks = ls.path, world_size()
    need = needs(config, pinned, ranks, rigid)
    fit = [cls for cls in PATHS.values() if not cls.capabilities.lacks(need)]
    off = _off_faces(config, name)
    if off is not None:                 # faces on several bodies: the condensation alone (fem.faces)
        fit = [cls for cls in fit if cls.name in OFF_FACES_PATHS]
        if name != "auto":
            raise ConfigError([off] + (_refusal(name, need) if PATHS[name] not in fit and need else []))
    if name == "auto":
        chosen = _auto(fit, n_free, ls.crossover, ranks, need)
        if chosen is None:
            raise ConfigError(_refusal(name, need))
        log.info("linear solver: %s path for %d DOFs (crossover %d, %d rank(s))", chosen.name, n_free,
                 ls.crossover, ranks)
    else:
        chosen = PATHS[name]
        if chosen not in fit:
            raise ConfigError(_refusal(name, need))
    missing = [why for why in map(missing_library, chosen.capabilities.libraries) if why]
    if missing:
        raise ConfigError([f"linear_solver.path = '{name}'"
                           + (f" under mpiexec with {ranks} ranks" if "many_ranks" in need and name == "auto" else "")
                           + f" needs {why}" for why in missing])
    return chosen.name, library_for(chosen.name, ls.library)


OFF_FACES_PATHS = ("condensation", "fullspace", "petsc")   # the paths that take a pair's face on a counterpart body (fem.faces)


def _off_faces(config, name: str) -> str | None:
    """The refusal of path ``name`` for a model whose faces lie on several bodies (a pair's face on a
    counterpart body of another pair, fem.faces), None where the path takes it or the model has none."""
    if not config.off_faces or name in OFF_FACES_PATHS + ("auto",):
        return None
    where = ", ".join(f"contacts[{k}].face lies on body {body!r}" for k, body in config.off_faces.items())
    return (f"linear_solver.path = '{name}': {where}; a pair whose face lies on a counterpart body of another pair "
            f"is solved on {_on(list(OFF_FACES_PATHS))} only so far; use path {_names(list(OFF_FACES_PATHS) + ['auto'])}")


def path_estimates(config, name: str, body) -> PathEstimates:
    """The memory estimate of path ``name``, which will run, and those of the other paths that
    take a configuration and its ``body`` (pinned components, free rigid motions) on this run's
    ranks (:func:`needs`) with their libraries installed, which a memory refusal names (fem.memory)."""
    need = needs(config, int(body.pinned_dofs.size), _mpi.world_size(), body.rigid)
    return PathEstimates(PATHS[name].memory_estimate, {
        n: cls.memory_estimate for n, cls in PATHS.items() if n != name and not cls.capabilities.lacks(need)
        and (not config.off_faces or n in OFF_FACES_PATHS)
        and not any(map(missing_library, cls.capabilities.libraries))}, name)


def _auto(fit: list, n_free: int, crossover: int, ranks: int, need=()):
    """The path ``"auto"`` takes among those that ``fit`` (:func:`select_path`), or None: those
    that avoid a feature needed (``Capabilities.auto_avoids``) only where no other fits."""
    fit = [cls for cls in fit if not set(cls.capabilities.auto_avoids) & set(need)] or fit
    def installed(cls):
        c = cls.capabilities
        return not any(map(missing_library, c.libraries + c.auto_libraries))

    if ranks > 1:
        return next((cls for cls in fit if cls.capabilities.auto == "ranks"), None)
    large = sorted((cls for cls in fit if cls.capabilities.auto == "large" and installed(cls)),
                   key=lambda cls: cls.capabilities.auto_order)
    small = [cls for cls in fit if cls.capabilities.auto == "small"]
    order = (large + small) if n_free >= crossover else (small + large)
    return next(iter(order + [cls for cls in fit if cls.capabilities.auto != "ranks" and installed(cls)]), None)


def _refusal(name: str, need: dict) -> list:
    """The problems of path ``name`` with the features ``need``: each feature it lacks, with the
    paths that take it ("auto": the features no path takes), and a summary of what is needed,
    what the path lacks and which paths take it all."""
    def takers(feature):
        return [n for n, cls in PATHS.items() if getattr(cls.capabilities, feature)]

    fit = [n for n, cls in PATHS.items() if not cls.capabilities.lacks(need)]
    labels = ", ".join(Capabilities.label(f) for f in need)
    if name == "auto":
        shown = [f for f in need if not takers(f)]
        lacks = "; ".join(f"'{n}' lacks {', '.join(Capabilities.label(f) for f in cls.capabilities.lacks(need))}"
                          for n, cls in PATHS.items())
        summary = f"no solver path takes this configuration, which needs {labels} ({lacks})"
    else:
        shown = PATHS[name].capabilities.lacks(need)
        lacking = ", ".join(Capabilities.label(f) for f in shown)
        summary = (f"this configuration needs {labels}; the '{name}' path lacks {lacking}; "
                   + (f"{_names(fit, 'and')} take{'s' if len(fit) == 1 else ''} it all" if fit else "no path takes it all"))
    problems = []
    for f in shown:
        names = [n for n in fit if n in takers(f)] or takers(f)
        sentence = Capabilities.refusal(f).format(path=name, detail=need[f], takers=_names(names), on=_on(names))
        if sentence not in problems:       # two features the same paths take say the same
            problems.append(sentence)
    return problems + [f"linear_solver.path = '{name}': {summary}"]


def _names(names: list, conjunction: str = "or") -> str:
    """'a', 'b' or 'c'."""
    quoted = [f"'{n}'" for n in names] or ["none"]
    return quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + f" {conjunction} " + quoted[-1]


def _on(names: list) -> str:
    return f"the {_names(names, 'and')} path" + ("s" if len(names) > 1 else "")


def missing_library(library: str) -> str | None:
    """None where ``library`` (of ``Capabilities.libraries``) imports, else why not."""
    if library == "petsc4py":
        missing = _mpi.petsc_missing()
        return f"petsc4py and mpi4py: {missing}" if missing else None
    if library == "pyamg":
        return None if _have_pyamg() else "pyamg: it is not installed (pip install pyamg)"
    if library == "pardiso":
            return None if pardiso_available() else "MKL PARDISO: the mkl wheel is not installed"
    raise ValueError(f"unknown library {library!r}")


def make_path(config, model, name: str, library: str, start: Start | None = None) -> SolverPath:
    """The path ``name`` for a model, with the configuration's [state] settings."""
    settings = Settings.from_config(config.state, config.friction, library, config.linear_solver.threads)
    return PATHS[name](model, settings, start)


def _have_pyamg() -> bool:
    try:
        import pyamg  # noqa: F401
    except ImportError:
        return False
    return True
