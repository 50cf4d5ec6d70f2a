"""Distance of the default (coarse solve + refinement) propagation from the exact Eq. (4) solve.

``.venv/bin/python benchmarks/propagation_accuracy.py [--sizes 512 1024] [--cache DIR]``

Inputs per size: skimage's astronaut resized as in ``repro.bench`` (its refined sparse measures from
the pipeline at the paper preset, and at the robust preset with the per-edge confidence robust gives
the data term), and a synthetic textured image (the mid-size test image of tests/test_propagation.py
scaled up, 1 % of the pixels measured). Exact = ``propagate_defocus(..., downsample=1, tol=1e-9)``
(cached in ``--cache`` as .npz: ~30 s at 512², ~2.5 min at 1024²). For every refinement variant:
RMS / p99 / max |B − B_exact| in px and the propagation's wall / CPU seconds (best of 2).
Results go to propagation_accuracy.json next to this file.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parents[1] / "report" / "bench"  # where results go
sys.path.insert(0, str(HERE.parents[1]))

VARIANTS = {
    "galerkin (default: max(⌈2.5·s⌉, 20) its)": dict(),
    "galerkin, 24 its (the earlier default)": dict(refine_iterations=24),
    "galerkin, 48 its": dict(refine_iterations=48),
}


def _textured(rng, h, w):
    yy, xx = np.mgrid[0:h, 0:w] / (64.0 * max(h, w) / 320)
    img = np.stack([0.5 + 0.3 * np.sin(3 * xx + np.cos(2 * yy)),
                    0.5 + 0.3 * np.cos(2.5 * yy) * (xx > 2.2),
                    0.3 + 0.4 * ((xx - 2.5) ** 2 + (yy - 2.3) ** 2 < 1.2)], axis=-1)
    return np.clip(img + 0.01 * rng.standard_normal(img.shape), 0.0, 1.0)


def _inputs(kind, size):
    """(guide image, refined measures, per-edge confidence or None) of one benchmark case."""
    if kind in ("astronaut", "astronaut-robust"):
        from method import DefocusParams, estimate_defocus_map
        from method.pipeline import propagation_confidence
        from repro.bench import _test_image

        img = _test_image(size)
        params = DefocusParams.preset("robust" if kind == "astronaut-robust" else "paper")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = estimate_defocus_map(img, params)
        conf = propagation_confidence(res.refined_sigma, params=params, sparse_sigma=res.sparse_sigma,
                                      confidence=res.measure_confidence)
        return img, res.refined_sigma, conf
    rng = np.random.default_rng(20070101)
    img = _textured(rng, size, size)
    mask = rng.random((size, size)) < 0.01
    truth = 1.0 + 3.0 * img[..., 2] + np.linspace(0, 1, size)[None, :]
    return img, np.where(mask, truth, np.nan), None


def _same(a, b):
    """Equal arrays (NaN equal to NaN), or both None."""
    if a is None or b is None:
        return a is None and b is None
    return np.array_equal(a, b, equal_nan=True)


def main(argv=None):
    from method.propagation.defocus import propagate_defocus

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[512, 1024])
    ap.add_argument("--kinds", nargs="+", default=["astronaut", "astronaut-robust", "textured"])
    ap.add_argument("--cache", type=Path, default=Path(os.environ.get("DEFOCUS_CACHE_DIR", Path(__file__).resolve().parents[1] / ".cache")) / "propagation_exact")
    args = ap.parse_args(argv)
    args.cache.mkdir(parents=True, exist_ok=True)
    rows = []
    for kind in args.kinds:
        for size in args.sizes:
            img, bm, conf = _inputs(kind, size)
            path = args.cache / f"{kind}_{size}.npz"
            cached = np.load(path) if path.exists() else None
            if (cached is not None and _same(cached["bm"], bm)
                    and _same(cached["conf"] if "conf" in cached.files else None, conf)):
                exact = cached["exact"]
            else:
                exact = propagate_defocus(bm, img, downsample=1, tol=1e-9, confidence=conf)
                tmp = path.with_suffix(".tmp.npz")
                np.savez(tmp, bm=bm, exact=exact, **({} if conf is None else {"conf": conf}))
                os.replace(tmp, path)
            for name, kw in VARIANTS.items():
                best = None
                for _ in range(2):
                    t, c = time.perf_counter(), time.process_time()
                    out = propagate_defocus(bm, img, confidence=conf, **kw)
                    wall, cpu = time.perf_counter() - t, time.process_time() - c
                    if best is None or wall < best[0]:
                        best = (wall, cpu)
                err = np.abs(out - exact)
                row = {"image": kind, "size": size, "variant": name,
                       "rms_px": float(np.sqrt(np.mean(err**2))), "p99_px": float(np.percentile(err, 99)),
                       "max_px": float(err.max()), "wall_s": best[0], "cpu_s": best[1],
                       "load1": os.getloadavg()[0]}
                rows.append(row)
                print(f"| {kind} | {size}² | {name} | {row['rms_px']:.2g} / {row['p99_px']:.2g} / "
                      f"{row['max_px']:.2g} | {best[0]:.2f} / {best[1]:.2f} | {row['load1']:.1f} |", flush=True)
    (HERE / "propagation_accuracy.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
