"""Golden arrays: the paper preset's maps on a small natural image, stored as ``.npz`` and compared at a
tolerance measured across the CPU code paths this machine can take.

A hash of float64 bytes is a property of one CPU (its SIMD width, the BLAS kernel chosen at run time,
the instructions numba emits), not of the code: the same commit gives other last bits on another CPU.
So the regression golden of the paper pipeline stores the arrays themselves and compares them with
``|got − golden| ≤ atol`` (plus the same NaN pattern), while bit-identity stays tested where it *is* a
property of the code (two code paths in one process, 1 vs 2 threads, reruns: tests/test_determinism*.py).

What is stored
--------------
``tests/golden/paper_astronaut.npz``: ``sparse_sigma``, ``refined_sigma`` and ``defocus_map`` (float64,
px) of ``estimate_defocus_map(skimage.data.astronaut()[::4, ::4] / 255, DefocusParams())`` (128 × 128 × 3),
plus ``meta`` (JSON: command, library versions, CPU, UTC time).

How the tolerance is measured (``--cpu-check``)
----------------------------------------------
The maps are computed in one subprocess per configuration of :data:`CPU_CONFIGS` — numba's generic CPU
(no AVX) vs the native one, OpenBLAS kernels forced to other micro-architectures
(``OPENBLAS_CORETYPE``), numpy's SIMD dispatch with AVX-512 / AVX2 turned off
(``NPY_DISABLE_CPU_FEATURES``), and 1 vs 2 threads (numba, OpenMP, OpenBLAS) — each with its own empty
numba cache, and compared with the stored golden: per array the largest absolute difference and whether
the NaN pattern is the same. ``tests/golden/paper_astronaut_tolerance.json`` records the deviations, and
``atol = max(SPREAD_FACTOR × largest deviation, FLOOR_ATOL)``. No render enters this golden (the image is
scikit-image's photograph), so Mitsuba's llvm vs scalar variants cannot move it; the render-fed goldens
(``tests/golden/*_quick.json``) carry tolerances measured over both variants (``tests/golden.py``).

Usage::

    .venv/bin/python -m tests.golden_arrays --cpu-check            # print the deviations of every config
    .venv/bin/python -m tests.golden_arrays --regenerate-arrays    # rewrite the .npz, then measure the tolerance
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

GOLDEN_DIR = Path(__file__).resolve().parent / "golden"
ROOT = GOLDEN_DIR.parents[1]
ARRAY_FILE = GOLDEN_DIR / "paper_astronaut.npz"
TOLERANCE_FILE = GOLDEN_DIR / "paper_astronaut_tolerance.json"
ARRAYS = ("sparse_sigma", "refined_sigma", "defocus_map")
REGENERATE_COMMAND = ".venv/bin/python -m tests.golden_arrays --regenerate-arrays"

#: atol = max(SPREAD_FACTOR × the largest deviation over CPU_CONFIGS, FLOOR_ATOL), px.
SPREAD_FACTOR = 10.0
#: Floor of the tolerance, px: well above float64 round-off of a σ of a few px, far below any change of
#: the method (a perturbation of 1e-6 px of the dense map already fails; tests/test_presets.py).
FLOOR_ATOL = 1e-9

_ONE_THREAD = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
_TWO_THREADS = {"NUMBA_NUM_THREADS": "2", "OMP_NUM_THREADS": "2", "OPENBLAS_NUM_THREADS": "2"}

#: name → environment of one subprocess. The first is the baseline the golden is written from.
CPU_CONFIGS = {
    "native": {},
    "native_1_thread": _ONE_THREAD,
    "native_2_threads": _TWO_THREADS,
    "numba_generic": {"NUMBA_CPU_NAME": "generic"},
    "numba_generic_1_thread": {"NUMBA_CPU_NAME": "generic", **_ONE_THREAD},
    "openblas_Prescott": {"OPENBLAS_CORETYPE": "Prescott"},
    "openblas_Sandybridge": {"OPENBLAS_CORETYPE": "Sandybridge"},
    "openblas_Haswell": {"OPENBLAS_CORETYPE": "Haswell"},
    "openblas_SkylakeX": {"OPENBLAS_CORETYPE": "SkylakeX"},
    "openblas_Zen": {"OPENBLAS_CORETYPE": "Zen"},
    "numpy_no_avx512": {"NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL"},
    "numpy_no_avx2_no_avx512": {"NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL"},
    "all_generic_1_thread": {"NUMBA_CPU_NAME": "generic", "OPENBLAS_CORETYPE": "Prescott",
                             "NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL", **_ONE_THREAD},
}


def paper_astronaut_input() -> np.ndarray:
    """The golden's input: scikit-image's astronaut, every 4th pixel, float64 in [0, 1], 128 × 128 × 3."""
    import skimage.data

    return skimage.data.astronaut()[::4, ::4] / 255.0


def compute_paper_astronaut() -> dict[str, np.ndarray]:
    """``{name: float64 HxW array, px}`` of the paper preset's maps on :func:`paper_astronaut_input`."""
    from method import estimate_defocus_map
    from method.params import DefocusParams

    res = estimate_defocus_map(paper_astronaut_input(), DefocusParams.preset("paper"))
    return {name: np.ascontiguousarray(getattr(res, name), dtype=np.float64) for name in ARRAYS}


def load_golden() -> dict[str, np.ndarray]:
    """The stored arrays (float64, px)."""
    with np.load(ARRAY_FILE) as z:
        return {name: z[name] for name in ARRAYS}


def load_tolerance() -> float:
    """The measured absolute tolerance, px (``tests/golden/paper_astronaut_tolerance.json``)."""
    return float(json.loads(TOLERANCE_FILE.read_text())["atol_px"])


def deviations(got: dict, golden: dict) -> dict[str, dict]:
    """Per array: ``{"max_abs": largest |got − golden| where both are finite (px), "nan_mismatch": number of
    pixels finite in one and NaN in the other, "shape_ok": bool}``."""
    out = {}
    for name in ARRAYS:
        a, b = np.asarray(got[name]), np.asarray(golden[name])
        if a.shape != b.shape:
            out[name] = {"max_abs": float("inf"), "nan_mismatch": -1, "shape_ok": False}
            continue
        fa, fb = np.isfinite(a), np.isfinite(b)
        both = fa & fb
        d = float(np.max(np.abs(a[both] - b[both]))) if both.any() else 0.0
        out[name] = {"max_abs": d, "nan_mismatch": int(np.count_nonzero(fa != fb)), "shape_ok": True}
    return out


def compare(got: dict, golden: dict, atol: float) -> list[str]:
    """Problems (empty when ``got`` matches ``golden`` within ``atol`` px with the same NaN pattern)."""
    problems = []
    for name, d in deviations(got, golden).items():
        if not d["shape_ok"]:
            problems.append(f"{name}: shape {np.shape(got[name])} != golden {np.shape(golden[name])}")
            continue
        if d["nan_mismatch"]:
            problems.append(f"{name}: {d['nan_mismatch']} pixels finite in one and NaN in the other")
        if not d["max_abs"] <= atol:
            problems.append(f"{name}: max |got - golden| = {d['max_abs']:.3g} px > atol {atol:.3g} px")
    return problems


# --- the measurement ----------------------------------------------------------------------------------
def _child(out_path: str) -> None:
    t0 = time.perf_counter()
    arrays = compute_paper_astronaut()
    np.savez(out_path, **arrays, seconds=np.float64(time.perf_counter() - t0))


def _run_config(name: str, env_extra: dict, folder: Path) -> dict[str, np.ndarray]:
    out = folder / f"{name}.npz"
    env = {**os.environ, **env_extra, "NUMBA_CACHE_DIR": str(folder / f"numba_{name}")}
    for k in ("NUMBA_CPU_NAME", "OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES", "NUMBA_NUM_THREADS",
              "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        if k not in env_extra:
            env.pop(k, None)
    subprocess.run([sys.executable, "-m", "tests.golden_arrays", "--child", str(out)], cwd=ROOT, env=env,
                   check=True)
    with np.load(out) as z:
        return {k: z[k] for k in z.files}


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def cpu_check(*, write_tolerance: bool) -> dict:
    """Compute the maps under every :data:`CPU_CONFIGS` entry; print and return the deviations."""
    from defocus_cache import atomic_write_text, library_versions

    golden = load_golden()
    runs = {}
    with tempfile.TemporaryDirectory(prefix="golden_arrays_") as tmp:
        for name, env_extra in CPU_CONFIGS.items():
            got = _run_config(name, env_extra, Path(tmp))
            dev = deviations(got, golden)
            runs[name] = {"env": env_extra, "seconds": round(float(got["seconds"]), 2), "deviations": dev}
            print(f"{name:26s} " + "  ".join(f"{k} {v['max_abs']:.3g} px (NaN≠ {v['nan_mismatch']})"
                                                for k, v in dev.items()), flush=True)
    largest = max(v["max_abs"] for r in runs.values() for v in r["deviations"].values())
    nan_mismatch = max(v["nan_mismatch"] for r in runs.values() for v in r["deviations"].values())
    atol = max(SPREAD_FACTOR * largest, FLOOR_ATOL)
    print(f"largest deviation {largest:.3g} px, NaN-pattern mismatches {nan_mismatch} -> atol {atol:.3g} px")
    result = {
        "atol_px": atol,
        "rule": f"atol = max({SPREAD_FACTOR:g} x largest max|got - golden| over the runs, {FLOOR_ATOL:g} px)",
        "largest_deviation_px": largest,
        "largest_nan_mismatch": nan_mismatch,
        "runs": runs,
        "cpu": _cpu_model(),
        "library_versions": library_versions(),
        "measured_utc": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M"),
        "how": ".venv/bin/python -m tests.golden_arrays --cpu-check --write-tolerance",
    }
    if write_tolerance:
        atomic_write_text(TOLERANCE_FILE, json.dumps(result, indent=1, sort_keys=True) + "\n")
        print(f"wrote {TOLERANCE_FILE.relative_to(ROOT)}")
    return result


def regenerate() -> None:
    """Rewrite the golden arrays from a baseline subprocess (native CPU, default threads)."""
    import io

    from defocus_cache import atomic_write_bytes, library_versions

    with tempfile.TemporaryDirectory(prefix="golden_arrays_") as tmp:
        arrays = _run_config("native", CPU_CONFIGS["native"], Path(tmp))
    meta = {"command": REGENERATE_COMMAND, "library_versions": library_versions(), "cpu": _cpu_model(),
            "utc": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M")}
    buf = io.BytesIO()
    np.savez_compressed(buf, **{k: arrays[k] for k in ARRAYS}, meta=np.array(json.dumps(meta, sort_keys=True)))
    atomic_write_bytes(ARRAY_FILE, buf.getvalue())
    print(f"wrote {ARRAY_FILE.relative_to(ROOT)} ({ARRAY_FILE.stat().st_size} bytes)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.golden_arrays", description=__doc__.split("\n\n")[0])
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--cpu-check", action="store_true", help="compute under every CPU config and print deviations")
    g.add_argument("--regenerate-arrays", action="store_true",
                   help="rewrite tests/golden/paper_astronaut.npz, then measure and write the tolerance")
    g.add_argument("--child", metavar="OUT", help=argparse.SUPPRESS)
    ap.add_argument("--write-tolerance", action="store_true", help="with --cpu-check: rewrite the tolerance file")
    args = ap.parse_args(argv)
    if args.child:
        _child(args.child)
        return 0
    if args.regenerate_arrays:
        regenerate()
        cpu_check(write_tolerance=True)
        return 0
    cpu_check(write_tolerance=args.write_tolerance)
    return 0


if __name__ == "__main__":
    sys.exit(main())
