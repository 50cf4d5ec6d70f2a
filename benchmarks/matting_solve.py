"""CPU seconds of Zhuo & Sim's matting-Laplacian solves on the stages figure's ``zhuo_sim`` cases.

``.venv/bin/python benchmarks/matting_solve.py [--scenes portrait planes] [--f-numbers 8 4] [--solver cg_amg]
[--tol TOL] [--step-tol PX] [--preset full]``

For each render case of the stages figure (:mod:`experiments.figS1_stages`, renders from the cache;
a missing render is rendered) it runs ``stage_errors`` with the ``zhuo_sim`` preset once with the
matting solves recorded, then solves every distinct system (the estimate and the oracle inputs)
with the earlier default (``cg_vcycle``, tol 1e-6: the oracle) and with ``--solver`` at ``--tol`` (default:
the ``zhuo_sim`` preset's ``matting_tol``, the tolerance ``stage_errors`` now solves to, and ``--step-tol``,
default its ``matting_step_tol``),
and prints per case: the solves ``stage_errors`` now makes (two: the oracle inputs share one), the
process CPU seconds of the old code (``cg_vcycle`` over its three solves, the oracle's twice) and of
the new one (``--solver`` over the two), and max |Δσ| px between the two solutions. Results are appended to
``report/bench/matting_solve.json``.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "report" / "bench" / "matting_solve.json"


def _record_systems(config, case):
    """The (sparse σ, guide) of every matting solve ``stage_errors`` makes on ``case``."""
    import method.propagation.matting as matting
    from experiments.figS1_stages import _image
    from experiments.stage_attribution import stage_errors
    from method import DefocusParams, NoEdgesWarning

    seen = []
    real = matting.propagate_defocus_matting

    def record(sparse_sigma, reference, **kwargs):
        seen.append((np.array(sparse_sigma), np.array(reference), kwargs))
        return np.zeros(np.shape(sparse_sigma))

    matting.propagate_defocus_matting = record
    try:
        img, gt, valid = _image(config, case)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NoEdgesWarning)
            stage_errors(img, gt, params=DefocusParams.preset("zhuo_sim"), valid=valid)
    finally:
        matting.propagate_defocus_matting = real
    return seen


def _cpu(fn):
    t = time.process_time()
    out = fn()
    return out, time.process_time() - t


def main(argv=None) -> int:
    from experiments.figS1_stages import FULL, cases
    from method.propagation.matting import propagate_defocus_matting

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="+", default=list(FULL.scenes))
    p.add_argument("--f-numbers", nargs="+", type=float, default=list(FULL.f_numbers))
    p.add_argument("--solver", default="cg_amg")
    p.add_argument("--tol", type=float, default=None, help="default: the zhuo_sim preset's matting_tol")
    p.add_argument("--step-tol", type=float, default=None, help="px; default: the zhuo_sim preset's matting_step_tol")
    p.add_argument("--preset", default=FULL.preset, help="render size preset (small / full)")
    args = p.parse_args(argv)
    if args.tol is None:
        from method import DefocusParams

        args.tol = DefocusParams.preset("zhuo_sim").matting_tol
    if args.step_tol is None:
        from method import DefocusParams

        args.step_tol = DefocusParams.preset("zhuo_sim").matting_step_tol
    config = FULL.__class__(**{**FULL.__dict__, "scenes": tuple(args.scenes), "f_numbers": tuple(args.f_numbers),
                               "preset": args.preset})
    rows = []
    for case in cases(config):
        if case.preset != "zhuo_sim" or case.variant != "render":
            continue
        row = {"case": f"{case.scene} f/{case.aperture:g} ({args.preset})", "solver": args.solver, "tol": args.tol,
               "step_tol": args.step_tol,
               "old_cpu_s": 0.0, "new_cpu_s": 0.0, "max_abs_diff_px": 0.0}
        systems = _record_systems(config, case)
        row["solves"] = len(systems)
        for sparse, ref, kw in systems:
            kw = {k: v for k, v in kw.items() if k not in ("tol", "step_tol")}
            old, t_old = _cpu(lambda: propagate_defocus_matting(sparse, ref, solver="cg_vcycle", tol=1e-6, **kw))
            new, t_new = _cpu(lambda: propagate_defocus_matting(sparse, ref, solver=args.solver, tol=args.tol,
                                                                step_tol=args.step_tol, **kw))
            row["old_cpu_s"] += t_old
            row["new_cpu_s"] += t_new
            row["max_abs_diff_px"] = max(row["max_abs_diff_px"], float(np.max(np.abs(new - old))))
        # before, stage_errors solved the oracle system twice (oracle_refine and oracle_propagate,
        # equal inputs without Eq. 3): the old code's CPU counts that second solve
        row["old_cpu_s"] += t_old
        row["load_1min"] = round(__import__("os").getloadavg()[0], 2)
        print(json.dumps(row), flush=True)
        rows.append(row)
    runs = json.loads(OUT.read_text()) if OUT.exists() else []
    runs.append({"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "rows": rows})
    from defocus_cache import atomic_write_text

    atomic_write_text(OUT, json.dumps(runs, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
