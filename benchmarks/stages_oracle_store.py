"""CPU seconds the oracle store saves the stages figure: its image cases with the oracle runs computed in
place, then through a cold and a warm store (a temporary folder), and its ablation cases with and without
the oracle runs they do not read.

``.venv/bin/python benchmarks/stages_oracle_store.py [--config quick|full] [--scenes portrait] [--f-numbers 8]``

Renders come from the cache (a missing one is rendered). ``--config quick``: the quick figure's image
cases (``--scenes`` / ``--f-numbers`` narrow them), a warm-up pass first, then its ablation cases;
``--config full``: the full figure's render cases. Prints process CPU seconds per preset and pass.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import tempfile
import time


def _cpu(config, cases) -> dict:
    """Process CPU s of ``compute_case`` per preset, numba and BLAS on one thread (as in the case runner)."""
    from experiments.figS1_stages import compute_case
    from experiments.threads import single_threaded

    per = {}
    with single_threaded():
        for c in cases:
            t = time.process_time()
            compute_case(config, c, {})
            per[c.preset] = per.get(c.preset, 0.0) + time.process_time() - t
    return per


def main(argv=None) -> None:
    import experiments.stage_attribution as sa
    from experiments.figS1_stages import FULL, QUICK, cases

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", choices=("quick", "full"), default="quick")
    ap.add_argument("--scenes", nargs="+")
    ap.add_argument("--f-numbers", nargs="+", type=float)
    args = ap.parse_args(argv)
    config = QUICK if args.config == "quick" else FULL
    narrow = {k: tuple(v) for k, v in (("scenes", args.scenes), ("f_numbers", args.f_numbers)) if v}
    config = dataclasses.replace(config, **narrow)
    images = [c for c in cases(config) if not c.variant.startswith("ablation:")]
    stored = functools.partial(sa.stored_oracle_runs, cache_dir=tempfile.mkdtemp())
    in_place = lambda oracle, rgb, params: sa.oracle_runs(oracle, rgb, params)  # noqa: E731
    passes = (("warm-up", in_place),) if args.config == "quick" else ()
    for label, runs in (*passes, ("in place", in_place), ("cold store", stored), ("warm store", stored)):
        sa.stored_oracle_runs = runs
        per = _cpu(config, images)
        print(f"image cases, {label}: {sum(per.values()):.1f} s CPU", {k: round(v, 1) for k, v in per.items()},
              flush=True)
    ablation = [c for c in cases(config) if c.variant.startswith("ablation:")]
    if args.config == "quick" and ablation:
        real = sa.stage_errors
        for label, fn in (("with the oracle runs", lambda *a, oracles=True, **k: real(*a, **k)), ("without", real)):
            sa.stage_errors = fn
            print(f"{len(ablation)} ablation cases, {label}: {sum(_cpu(config, ablation).values()):.1f} s CPU",
                  flush=True)
        sa.stage_errors = real


if __name__ == "__main__":
    main()
