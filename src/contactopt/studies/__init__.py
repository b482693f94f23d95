"""Design studies: sweeps of independent optimization runs on dask.distributed.

``run_sweep(config, [(key, values), ...], outdir)`` runs the cartesian product of the settings,
one run directory per task, on a LocalCluster or an existing cluster (``scheduler=``), and
writes sweep.csv/sweep.json and comparison plots; ``gather(outdir)`` rebuilds the tables from
the run directories. See :mod:`contactopt.studies.sweep`.
"""

from .settings import SweepTask, build_tasks, parse_settings
from .sweep import RESULT_COLUMNS, SweepResult, gather, run_sweep

__all__ = ["RESULT_COLUMNS", "SweepResult", "SweepTask", "build_tasks", "gather", "parse_settings",
           "run_sweep"]
