"""Failed trials of a run: a trial design whose contact state cannot be had.

The bundle method evaluates Θ at trial points it chooses itself; a state solve can fail at one of
them (its fallbacks exhausted, :mod:`contactopt.contact.fallback`). Such a trial carries no
information about Θ there, so it is answered with non-finite values: the bundle method then treats
the trial as failed, adds no cut, shrinks its trust parameter t and tries a point nearer the
current iterate (a null step without a cut). The run goes on from the current iterate, which was
solved; it stops only when no trial down to the smallest t can be solved, or when the current
iterate itself (the initial design) cannot be.

Every failed trial is logged (WARNING, in run.log) and recorded in ``failed_trials.csv``
(evaluation, iteration, reason) of the run directory; its row of history.csv has ``f = nan``. On
``--resume`` the rows after the checkpoint's evaluations are dropped, as those of history.csv,
so a resumed run records the failed trials of the uninterrupted one.
"""

from __future__ import annotations

import csv
import io
import logging
import time
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_write_text

__all__ = ["FailedTrials", "FILE"]

log = logging.getLogger(__name__)

FILE = "failed_trials.csv"
FIELDS = ("evaluation", "iteration", "reason")


class FailedTrials:
    """The record of a run's failed trials in ``out/failed_trials.csv``."""

    def __init__(self, out: Path):
        self.path = Path(out) / FILE

    def start(self, n_eval: int | None = None) -> None:
        """A new run (``n_eval`` None): no record; a resumed one: keep the failed trials among its
        first ``n_eval`` evaluations."""
        rows = [r for r in self.rows() if n_eval is not None and int(r["evaluation"]) <= n_eval]
        if not rows:
            self.path.unlink(missing_ok=True)
            return
        atomic_write_text(self.path, _csv([FIELDS] + [[r[k] for k in FIELDS] for r in rows]))

    def rows(self) -> list[dict]:
        """The failed trials recorded so far, as dictionaries of FIELDS (evaluation as text)."""
        if not self.path.exists():
            return []
        with open(self.path, newline="") as fh:
            return [r for r in csv.DictReader(fh) if r.get("evaluation", "").isdigit()]

    def record(self, evaluation: int, iteration: int, x, exc: Exception) -> str:
        """Log and record the failed trial ``evaluation`` at the design ``x``; return its reason."""
        reason = " ".join(str(exc).split())
        log.warning("evaluation %d (iteration %d): no state at this trial design (%s); a failed "
                    "trial: the optimizer shrinks its step and goes on from the current design "
                    "(|α|max %.6g)", evaluation, iteration, reason, float(np.max(np.abs(x))))
        new = not self.path.exists()
        with open(self.path, "a", newline="") as fh:
            w = csv.writer(fh)
            if new:
                w.writerow(FIELDS)
            w.writerow([evaluation, iteration, reason])
        return reason

    def answer(self, oracle, x, exc: Exception, n_fields: int, n_constraints: int = 0):
        """The oracle's answer at a failed trial: the evaluation counted, its row of history.csv
        (f = nan), the record, and non-finite values of Θ and its subgradient (and of the
        constraints' values and subgradients when there are ``n_constraints``)."""
        oracle.count += 1
        self.record(oracle.count, oracle.iteration, x, exc)
        row = [oracle.count, oracle.iteration, "nan", "nan", "", "", "", "",
               f"{time.perf_counter() - oracle.t_start:.3f}"]
        row += [""] * (n_fields - len(row))
        oracle.run_dir.append_history(row)
        g = np.full(np.size(x), np.nan)
        if n_constraints:
            return np.nan, g, np.full(n_constraints, np.nan), np.full((n_constraints, np.size(x)), np.nan)
        return np.nan, g

    def summary(self) -> list[dict]:
        """For summary.json: each failed trial's evaluation, iteration and reason."""
        return [{"evaluation": int(r["evaluation"]), "iteration": int(r["iteration"]), "reason": r["reason"]}
                for r in self.rows()]


def _csv(rows) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    return buf.getvalue()
