"""Read and write FCLIB local frictional-contact problems (HDF5).

FCLIB (Acary, Brémond, Koziniec, Mignon, 2014) stores the local problem ``u = W r + q``,
``K_mu ∋ r ⊥ u + mu ||u_T|| e_N ∈ K_mu*`` with, per contact, the components ordered
(normal, tangent1, tangent2) — the convention of :mod:`contactopt.contact.local`. Layout:

- ``/fclib_local/W/{m, n, nz, nzmax, p, i, x}``: a CSparse matrix; ``nz = -1`` compressed
  columns (``p`` column pointers, ``i`` row indices), ``nz = -2`` compressed rows (``p`` row
  pointers, ``i`` column indices), ``nz >= 0`` triplets (``i`` rows, ``p`` columns, ``nz``
  entries); optional matrix info ``comment, conditioning, sparsity, determinant, rank``;
- ``/fclib_local/vectors/{q, mu}``, ``/fclib_local/spacedim``;
- ``/fclib_local/info/{title, description, math_info}`` (strings; attributes are kept too);
- optional ``/guesses/{number_of_guesses, 1/r, 1/u, ...}`` and ``/solution/{r, u}``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np
import scipy.sparse as sp

from ..contact.local import solve_local
from ..errors import FclibError

__all__ = ["FclibProblem", "read_fclib", "write_fclib", "solve_fclib"]

_INFO_STRINGS = ("title", "description", "math_info")
_MATRIX_INFO = ("comment", "conditioning", "sparsity", "determinant", "rank")


@dataclass
class FclibProblem:
    """An FCLIB local problem: ``u = W r + q`` with ``p = len(mu)`` contacts.

    ``W`` is a scipy sparse matrix (CSR or CSC as stored; triplets are converted to CSR).
    ``info`` holds the problem strings and attributes, ``matrix_info`` the optional info of W,
    ``guesses`` a list of ``{"r": ..., "u": ...}`` and ``solution`` such a dict or ``None``.
    """

    W: sp.spmatrix
    q: np.ndarray
    mu: np.ndarray
    spacedim: int = 3
    info: dict = field(default_factory=dict)
    matrix_info: dict = field(default_factory=dict)
    guesses: list = field(default_factory=list)
    solution: dict | None = None
    path: str | None = None

    @property
    def n_contacts(self) -> int:
        return int(self.mu.size)

    @property
    def name(self) -> str:
        return Path(self.path).stem if self.path else str(self.info.get("title", "fclib"))


def _h5py():

    return h5py


def _scalar(ds):
    v = np.asarray(ds[()])
    return v.reshape(-1)[0].item() if v.size else None


def _string(ds):
    v = ds[()]
    if isinstance(v, bytes):
        return v.decode("utf-8", errors="replace")
    if isinstance(v, np.ndarray):
        v = v.reshape(-1)[0] if v.size else b""
        return v.decode("utf-8", errors="replace") if isinstance(v, bytes) else str(v)
    return str(v)


def _attrs(obj):
    out = {}
    for k, v in obj.attrs.items():
        v = np.asarray(v)
        out[k] = v.reshape(-1)[0].item() if v.size == 1 else v.tolist()
    return out


def _read_matrix(g, where):
    problems = []
    for key in ("m", "n", "nz", "p", "i", "x"):
        if key not in g:
            problems.append(f"{where}/{key} is missing")
    if problems:
        raise FclibError(f"not an FCLIB matrix: {'; '.join(problems)}")
    m, n, nz = (int(_scalar(g[k])) for k in ("m", "n", "nz"))
    p = np.asarray(g["p"][()], dtype=np.int64).reshape(-1)
    i = np.asarray(g["i"][()], dtype=np.int64).reshape(-1)
    x = np.asarray(g["x"][()], dtype=float).reshape(-1)
    try:
        if nz == -1:
            _check_compressed(p, i, x, n, m, where, "column")
            nnz = int(p[-1])
            W = sp.csc_matrix((x[:nnz], i[:nnz], p), shape=(m, n))
        elif nz == -2:
            _check_compressed(p, i, x, m, n, where, "row")
            nnz = int(p[-1])
            W = sp.csr_matrix((x[:nnz], i[:nnz], p), shape=(m, n))
        elif nz >= 0:
            if min(p.size, i.size, x.size) < nz:
                raise FclibError(f"{where}: triplet arrays shorter than nz = {nz}")
            rows, cols = i[:nz], p[:nz]
            if nz and (rows.min() < 0 or rows.max() >= m or cols.min() < 0 or cols.max() >= n):
                raise FclibError(f"{where}: triplet indices out of range for {m} x {n}")
            W = sp.coo_matrix((x[:nz], (rows, cols)), shape=(m, n)).tocsr()
        else:
            raise FclibError(f"{where}/nz = {nz}: unknown sparse format (-1, -2 or >= 0)")
    except ValueError as exc:  # scipy's own consistency checks
        raise FclibError(f"{where}: inconsistent sparse matrix: {exc}") from exc
    info = {k: (_string(g[k]) if k == "comment" else _scalar(g[k])) for k in _MATRIX_INFO
            if k in g}
    info.update(_attrs(g))
    return W, info


def _check_compressed(p, i, x, n_major, n_minor, where, kind):
    if p.size != n_major + 1:
        raise FclibError(f"{where}/p has length {p.size}, expected {n_major + 1} "
                         f"(compressed-{kind} pointers)")
    nnz = int(p[-1])
    if p[0] != 0 or np.any(np.diff(p) < 0) or i.size < nnz or x.size < nnz:
        raise FclibError(f"{where}: invalid compressed-{kind} pointers")
    if nnz and (i[:nnz].min() < 0 or i[:nnz].max() >= n_minor):
        raise FclibError(f"{where}/i has indices out of range")


def read_fclib(path) -> FclibProblem:
    """Read the local problem stored in the FCLIB file ``path``.

    Raises :class:`contactopt.errors.FclibError` when the file is missing, is not HDF5, has no
    ``fclib_local`` group, or has inconsistent shapes.
    """
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FclibError(f"FCLIB file not found: {path}")
    h5py = _h5py()
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise FclibError(f"{path} is not an HDF5 file: {exc}") from exc
    with f:
        if "fclib_local" not in f:
            what = "an FCLIB global problem" if "fclib_global" in f else "not an FCLIB file"
            raise FclibError(f"{path}: no group 'fclib_local' ({what})")
        g = f["fclib_local"]
        problems = [f"fclib_local/{k} is missing" for k in ("W", "vectors/q", "vectors/mu")
                    if k not in g]
        if problems:
            raise FclibError(f"{path}: " + "; ".join(problems))
        W, matrix_info = _read_matrix(g["W"], "fclib_local/W")
        q = np.asarray(g["vectors/q"][()], dtype=float).reshape(-1)
        mu = np.asarray(g["vectors/mu"][()], dtype=float).reshape(-1)
        spacedim = int(_scalar(g["spacedim"])) if "spacedim" in g else 3
        info = {}
        if "info" in g:
            info.update(_attrs(g["info"]))
            for k in _INFO_STRINGS:
                if k in g["info"]:
                    info[k] = _string(g["info"][k])
        guesses = []
        if "guesses" in f:
            count = int(_scalar(f["guesses/number_of_guesses"])) \
                if "guesses/number_of_guesses" in f else 0
            for k in range(1, count + 1):
                if str(k) in f["guesses"]:
                    guesses.append(_read_solution(f["guesses"][str(k)]))
        solution = _read_solution(f["solution"]) if "solution" in f else None
    _check_shapes(W, q, mu, spacedim, path)
    return FclibProblem(W=W, q=q, mu=mu, spacedim=spacedim, info=info,
                        matrix_info=matrix_info, guesses=guesses, solution=solution, path=path)


def _read_solution(g):
    return {k: np.asarray(g[k][()], dtype=float).reshape(-1) for k in ("r", "u", "v", "l")
            if k in g}


def _check_shapes(W, q, mu, spacedim, where):
    problems = []
    if spacedim not in (2, 3):
        problems.append(f"spacedim = {spacedim} (must be 2 or 3)")
    if spacedim != 3:
        problems.append("only 3D problems (spacedim = 3) are supported")
    m, n = W.shape
    if m != n:
        problems.append(f"W is {m} x {n}, not square")
    if q.size != m:
        problems.append(f"q has length {q.size}, W has {m} rows")
    if spacedim and m % spacedim:
        problems.append(f"W has {m} rows, not a multiple of spacedim = {spacedim}")
    elif spacedim and mu.size != m // spacedim:
        problems.append(f"mu has length {mu.size}, expected {m // max(spacedim, 1)} contacts")
    if problems:
        raise FclibError(f"{where}: " + "; ".join(problems))


def write_fclib(path, problem: FclibProblem, *, overwrite: bool = False) -> None:
    """Write ``problem`` to ``path`` in the FCLIB local format.

    CSC matrices are stored column-compressed (``nz = -1``), CSR row-compressed (``nz = -2``),
    any other sparse or dense matrix as triplets. Refuses to replace an existing file unless
    ``overwrite`` is true.
    """
    path = os.fspath(path)
    if os.path.exists(path) and not overwrite:
        raise FclibError(f"{path} exists (pass overwrite=True to replace it)")
    W = problem.W
    q = np.asarray(problem.q, dtype=float).reshape(-1)
    mu = np.asarray(problem.mu, dtype=float).reshape(-1)
    if not sp.issparse(W):
        W = sp.coo_matrix(np.asarray(W, dtype=float))
    _check_shapes(W, q, mu, int(problem.spacedim), path)
    h5py = _h5py()
    i32 = np.int32
    with h5py.File(path, "w") as f:
        g = f.create_group("fclib_local")
        g.create_dataset("spacedim", data=np.array([problem.spacedim], dtype=i32))
        gw = g.create_group("W")
        m, n = W.shape
        if W.format in ("csc", "csr"):
            W = W.copy()
            W.sum_duplicates()
            nz = -1 if W.format == "csc" else -2
            p, i, x = W.indptr, W.indices, W.data
        else:
            W = W.tocoo()
            W.sum_duplicates()
            nz = int(W.nnz)
            p, i, x = W.col, W.row, W.data
        for key, val in (("m", m), ("n", n), ("nz", nz), ("nzmax", x.size)):
            gw.create_dataset(key, data=np.array([val], dtype=i32))
        gw.create_dataset("p", data=np.asarray(p, dtype=i32))
        gw.create_dataset("i", data=np.asarray(i, dtype=i32))
        gw.create_dataset("x", data=np.asarray(x, dtype=float))
        for k, v in problem.matrix_info.items():
            if k in _MATRIX_INFO:
                if k == "comment":
                    gw.create_dataset(k, data=str(v).encode())
                else:
                    gw.create_dataset(k, data=np.array([v], dtype=i32 if k == "rank" else float))
            else:
                gw.attrs[k] = v
        gv = g.create_group("vectors")
        gv.create_dataset("q", data=q)
        gv.create_dataset("mu", data=mu)
        gi = g.create_group("info")
        for k, v in problem.info.items():
            if k in _INFO_STRINGS:
                gi.create_dataset(k, data=str(v).encode())
            else:
                gi.attrs[k] = v
        if problem.guesses:
            gg = f.create_group("guesses")
            gg.create_dataset("number_of_guesses", data=np.array([len(problem.guesses)], i32))
            for k, guess in enumerate(problem.guesses, start=1):
                _write_solution(gg.create_group(str(k)), guess)
        if problem.solution is not None:
            _write_solution(f.create_group("solution"), problem.solution)


def _write_solution(g, sol):
    for k, v in sol.items():
        g.create_dataset(k, data=np.asarray(v, dtype=float))


def solve_fclib(path, method: str = "newton", *, tol: float = 1e-8, **options):
    """Read the FCLIB problem ``path`` and solve it with :func:`contactopt.contact.solve_local`.

    Returns the :class:`contactopt.contact.local.LocalResult`; does not raise when the
    tolerance is not reached (``converged`` tells), so that a command-line tool can report.
    """

    prob = read_fclib(path)
    options.setdefault("raise_on_failure", False)
    return solve_local(prob.W, prob.q, prob.mu, method=method, tol=tol, **options)
