"""The checkpoint of an optimization run: what a resumed run needs to repeat the uninterrupted one.

This module alone writes and reads ``checkpoint.npz``. A checkpoint is one npz archive whose
keys name a part and a field, ``<part>/<field>``:

``format/version``
    ``VERSION``, the one version number of the whole file; a checkpoint of another version
    is refused with a message (start the run again with ``--overwrite``).
``run/…``
    the evaluations, the elapsed time, the scale Θ(α0) of the objective the optimizer sees,
    the stopping parameters ``eps`` and ``max_iter``, the design α when the optimizer works on
    reduced variables β, and the number of load cases and of load steps of each case.
``config/json``
    the resolved configuration, flattened to dotted keys (``optimizer.max_iter`` aside, which a
    resume may change): a resume with another configuration is refused naming the keys that
    differ.
``bundle/…``
    the :class:`~contactopt.optimize.bundle.BundleState` (its fields, without a version of their own).
``penalty/…``
    the :class:`~contactopt.optimize.constrained.PenaltyState` of a run with [[constraints]].
``result/…``
    the optimizer's verdict once it has stopped (a resumed finished run writes its outputs again
    without another iteration).
``case<k>/step<j>/…``
    what the state solver of load case k carries from design to design at load step j (warm
    starts, a kept Delassus block, the design of an AMG hierarchy), as the solver path exports
    it; k and j count from 0, and a run without load cases or load path has case0/step0 only.
    The warm start ``warm`` is the contact force r, shape (p, 3): one row per contact node in
    the model's order, components (t1, t2, ν) — ν the normal force, positive in compression
    (λ ≥ 0) — and ``zone`` the contact nodes (indices into that order) of the next solve.
``initial/case<k>/step<j>/…``
    the same arrays as they stood when the initial design α0 was solved, so that a resumed run
    repeats that solve bit for bit for its outputs (absent when no solve at α0 was recorded).
``iterate/alpha``, ``iterate/case<k>/step<j>/…``
    the design α of the optimizer's current iterate and the arrays as they stood when it was
    solved: where the run ends at that iterate, a resumed run repeats its solve for the outputs.

Writes are atomic (``contactopt.io.atomic.atomic_savez``): a killed writer leaves the
previous checkpoint whole.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import CheckpointError, ContactOptError
from ..optimize.bundle import _STATE_VERSION, BundleState
from ..optimize.constrained import PenaltyState
from .atomic import atomic_savez

log = logging.getLogger(__name__)

__all__ = ["VERSION", "CHECKPOINT_NAME", "Checkpoint", "SavedResult", "flatten_config"]

VERSION = 8
"""The format of the file (the numbering goes on from the optimizer state's six earlier ones;
8 added the solves of the initial design and of the iterate)."""

CHECKPOINT_NAME = "checkpoint.npz"


def flatten_config(data: dict, prefix: str = "") -> dict:
    """A nested configuration as ``{"section.key": value}`` (lists of tables numbered:
    ``constraints.0.name``), values as JSON gives them back."""
    out = {}
    items = data.items() if isinstance(data, dict) else enumerate(data)
    for key, value in items:
        name = f"{prefix}{key}"
        if isinstance(value, dict) or (isinstance(value, list) and value and all(isinstance(v, dict)
                                                                                for v in value)):
            out.update(flatten_config(value, name + "."))
        else:
            out[name] = value
    return json.loads(json.dumps(out, default=str))


@dataclass(frozen=True)
class SavedResult:
    """The optimizer's verdict at its stop: ``status``, ``message``, ``criterion`` (None when
    the status has none) and the realised ``relative_decrease``."""

    status: int
    message: str
    criterion: str | None
    relative_decrease: float


@dataclass
class Checkpoint:
    """The state of a run after one finished iteration.

    ``contexts[k][j]``: the arrays of load case k at load step j (``len(contexts)`` is the
    number of load cases); ``alpha`` the design α when the optimizer works on β (else None);
    ``config`` the flattened configuration (``flatten_config``); ``initial`` the contexts of the
    solve of α0 and ``iterate`` (α, contexts) of the solve of the current iterate, in the layout
    of ``contexts`` (None: not recorded)."""

    bundle: BundleState
    evaluations: int
    elapsed: float
    scale: float
    eps: float
    max_iter: int
    config: dict
    contexts: list = field(default_factory=list)
    alpha: np.ndarray | None = None
    penalty: PenaltyState | None = None
    result: SavedResult | None = None
    initial: list | None = None
    iterate: tuple | None = None

    # ------------------------------------------------------------------ where the run stands
    @property
    def iteration(self) -> int:
        """Iterations finished, those of earlier penalty weights σ included."""
        return self.bundle.nit + (self.penalty.nit if self.penalty is not None else 0)

    @property
    def finished(self) -> bool:
        return self.result is not None

    # ------------------------------------------------------------------ writing
    def arrays(self) -> dict:
        """The archive's arrays, keyed ``<part>/<field>``."""
        out = {"format/version": np.array(VERSION),
               "run/evaluations": np.array(int(self.evaluations)), "run/elapsed": np.array(float(self.elapsed)),
               "run/scale": np.array(float(self.scale)), "run/eps": np.array(float(self.eps)),
               "run/max_iter": np.array(int(self.max_iter)),
               "run/n_cases": np.array(len(self.contexts)),
               "run/n_steps": np.array([len(c) for c in self.contexts], dtype=np.int64),
               "config/json": np.array(json.dumps(self.config, sort_keys=True))}
        bundle = self.bundle.to_dict()
        del bundle["version"]          # the file's version covers it
        out.update({f"bundle/{k}": np.asarray(v) for k, v in bundle.items()})
        if self.alpha is not None:
            out["run/alpha"] = np.asarray(self.alpha, dtype=float)
        if self.penalty is not None:
            out.update({f"penalty/{k}": np.asarray(v) for k, v in self.penalty.to_dict().items()})
        if self.result is not None:
            r = self.result
            out.update({"result/status": np.array(int(r.status)), "result/message": np.array(r.message),
                        "result/criterion": np.array(r.criterion or ""),
                        "result/relative_decrease": np.array(float(r.relative_decrease))})
        out.update(_context_arrays("", self.contexts))
        if self.initial is not None:
            out.update(_context_arrays("initial/", self.initial))
        if self.iterate is not None:
            out["iterate/alpha"] = np.asarray(self.iterate[0], dtype=float)
            out.update(_context_arrays("iterate/", self.iterate[1]))
        return out

    def write(self, path) -> Path:
        """Write the checkpoint to ``path`` atomically."""
        return atomic_savez(Path(path), **self.arrays())

    # ------------------------------------------------------------------ reading
    @classmethod
    def read(cls, path) -> "Checkpoint":
        """The checkpoint at ``path``; :class:`~contactopt.errors.CheckpointError` when it is
        missing, unreadable, of another version or inconsistent."""
        path = Path(path)
        if not path.exists():
            raise CheckpointError(f"no checkpoint in {path.parent} (expected {path.name})")
        data = _load(path)
        version = int(data["format/version"]) if "format/version" in data else None
        if version != VERSION:
            said = ("an older contactopt" if version is None or version < VERSION else "a newer contactopt")
            raise CheckpointError(f"checkpoint {path} was written by {said} (format "
                                  f"{'without a version' if version is None else version}, this one reads "
                                  f"{VERSION}); it cannot be resumed: start the run again with --overwrite")
        try:
            return cls._from_arrays(data)
        except (KeyError, TypeError, ValueError, ContactOptError) as exc:
            raise CheckpointError(f"checkpoint {path} is incomplete or inconsistent ({exc}); start the run "
                                  "again with --overwrite") from None

    @classmethod
    def peek(cls, path) -> "Checkpoint | None":
        """:meth:`read`, None where there is no usable checkpoint (``--resume`` says why)."""
        try:
            return cls.read(path)
        except CheckpointError:
            return None

    @classmethod
    def _from_arrays(cls, data: dict) -> "Checkpoint":
        part = _parts(data)
        bundle = BundleState.from_dict({**part.get("bundle", {}), "version": _STATE_VERSION})
        pen = PenaltyState.from_dict(part["penalty"]) if "penalty" in part else None
        res = None
        if "result" in part:
            r = part["result"]
            res = SavedResult(int(r["status"]), str(r["message"]), str(r["criterion"]) or None,
                              float(r["relative_decrease"]))
        run = part["run"]
        n_steps = np.atleast_1d(run["n_steps"]).astype(int)
        if n_steps.size != int(run["n_cases"]):
            raise ValueError(f"{int(run['n_cases'])} load cases but the steps of {n_steps.size}")
        contexts = [[part.get(f"case{k}/step{j}", {}) for j in range(n)] for k, n in enumerate(n_steps)]

        def recorded(prefix):
            return [[part.get(f"{prefix}case{k}/step{j}", {}) for j in range(n)] for k, n in enumerate(n_steps)]
        initial = recorded("initial/") if any(k.startswith("initial/") for k in part) else None
        iterate = ((np.array(part["iterate"]["alpha"], dtype=float), recorded("iterate/"))
                   if "iterate" in part else None)
        return cls(bundle=bundle, evaluations=int(run["evaluations"]), elapsed=float(run["elapsed"]),
                   scale=float(run["scale"]), eps=float(run["eps"]), max_iter=int(run["max_iter"]),
                   config=json.loads(str(part["config"]["json"])), contexts=contexts,
                   alpha=np.array(run["alpha"], dtype=float) if "alpha" in run else None, penalty=pen,
                   result=res, initial=initial, iterate=iterate)

    # ------------------------------------------------------------------ checks of a resume
    def require_config(self, config: dict, path) -> None:
        """Refuse a resume whose flattened configuration ``config`` differs from the
        checkpoint's, naming the keys that differ."""
        keys = sorted(k for k in set(config) | set(self.config) if config.get(k) != self.config.get(k))
        if keys:
            shown = ", ".join(f"{k} ({_show(self.config, k)} → {_show(config, k)})" for k in keys[:5])
            more = f" and {len(keys) - 5} more" if len(keys) > 5 else ""
            raise CheckpointError(f"checkpoint {path} belongs to a run with another configuration: {shown}{more}")

    def require_shape(self, n_steps: list, path) -> None:
        """Refuse a resume whose load cases (``n_steps[k]`` load steps of case k) differ."""
        have = [len(c) for c in self.contexts]
        if len(have) != len(n_steps):
            raise CheckpointError(f"checkpoint {path}: holds the warm starts of {len(have)} load case(s), "
                                  f"the configuration has {len(n_steps)}")
        if have != list(n_steps):
            raise CheckpointError(f"checkpoint {path}: holds {have} load steps per case, the configuration "
                                  f"has {list(n_steps)}")

    def saved_result(self, max_iter: int) -> SavedResult | None:
        """The verdict of a finished run resumed with the same ``max_iter`` (else None: it goes on)."""
        return self.result if self.result is not None and self.max_iter == max_iter else None


def _context_arrays(prefix: str, contexts: list) -> dict:
    """``{<prefix>case<k>/step<j>/<name>: array}`` of per-case, per-step context arrays."""
    return {f"{prefix}case{k}/step{j}/{name}": np.asarray(v) for k, steps in enumerate(contexts)
            for j, arrays in enumerate(steps) for name, v in arrays.items()}


def _show(config: dict, key: str) -> str:
    return "absent" if key not in config else json.dumps(config[key])


def _load(path: Path) -> dict:
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except Exception as exc:         # a truncated or damaged zip surfaces as many exception types
        raise CheckpointError(f"checkpoint {path} is truncated or corrupt ({exc}); it cannot be resumed: "
                              "start the run again with --overwrite") from None


def _parts(data: dict) -> dict:
    """``{"bundle": {"x": …}, "case0/step1": {"warm": …}, …}`` from the archive's keys."""
    out: dict = {}
    for key, value in data.items():
        where, _, name = key.rpartition("/")
        out.setdefault(where, {})[name] = value
    return out

