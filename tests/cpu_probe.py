"""Run the round-off-sensitive problems once and print the verdicts as JSON (one line).

Started by tests/test_cpu_kernels.py in subprocesses with ``OPENBLAS_CORETYPE`` (and
``MKL_ENABLE_INSTRUCTIONS``) set, so that each run uses another BLAS kernel; prints which kernel
ran (threadpoolctl) beside the results.  Usage: ``python tests/cpu_probe.py [OUTDIR]``.
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path


def main(outdir: Path) -> dict:
    from threadpoolctl import threadpool_info

    from contactopt.config import load_config
    from contactopt.optimize import minimize_bundle
    from contactopt.optimize.gallery import goffin_problem, max_linear_problem
    from contactopt.runner import run_optimization

    out = {}
    for prob in (goffin_problem(), max_linear_problem(60)):
        # the certificate's verdict (the f-change test, a default since, off)
        res = minimize_bundle(prob, prob.x0, eps=1e-6, max_iter=3000, tolf=0.0)
        out[prob.name] = {"status": int(res.status), "f": float(res.fun), "f_star": prob.f_star,
                          "nfev": int(res.nfev)}
    cfg = load_config("example2").with_updates({"mesh": {"nx": 18, "ny": 8, "nz": 8},
                                                "name": "probe", "optimizer": {"max_iter": 300}})
    s = run_optimization(cfg, outdir / "example2").summary
    out["example2"] = {"status": int(s["status"]), "success": bool(s["success"]), "J": float(s["J"]),
                       "evaluations": int(s["evaluations"]),
                       "J_tolerance": s["stopping"].get("J_tolerance")}
    info = threadpool_info()          # after the runs: MKL is loaded by the first factorization
    out["kernels"] = sorted({str(i.get("architecture")) for i in info if i.get("internal_api") == "openblas"})
    out["mkl"] = sorted({str(i.get("version")) for i in info if i.get("internal_api") == "mkl"})
    return out


if __name__ == "__main__":
    if len(sys.argv) > 1:
        result = main(Path(sys.argv[1]))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            result = main(Path(tmp))
    print(json.dumps(result))
