"""Golden numbers: rows of the quick results table checked into ``tests/golden/*.json``, each with a
tolerance derived from measured spread (``tests/golden/tolerances.json``), and the claim verdicts.

A golden is keyed by table row (:func:`row_key`: the row's set id columns — scene set, scene, preset,
aperture, encoding, noise, estimator, variant — and its metric path), so it watches every preset and
scene set of the quick run, the procedural test split included; :data:`FIGURE_GOLDENS` says which
metrics of each figure are watched.

What is compared
----------------
* numbers: ``|got − golden| ≤ tol`` with a tolerance per metric from ``tolerances.json``;
* booleans and strings (e.g. fig4's ``model_fit_better``, every claim verdict): exactly;
* NaN (stored as ``null``) must stay NaN; a metric missing from the run, or a run metric missing
  from the golden, fails (a new or vanished metric is a deliberate golden update).

How the tolerances were measured
--------------------------------
``python -m tests.golden --regenerate`` computes every quick figure the goldens watch (renders
through the render cache, every case uncached, in one process) in four separate processes: Mitsuba variants
``llvm_ad_rgb`` and ``scalar_rgb`` (different sample streams) × render seeds 0 and 1 (the seed is
forced on every ``render_scene`` call, also for figures without a seed option). For each metric,
``spread`` = max − min over the four runs and ``tol = max(SPREAD_FACTOR × spread, FLOOR_ATOL +
FLOOR_RTOL·|golden|) = max(3 × spread, 1e-6 + 1e-5·|golden|)`` (the floor covers library round-off of metrics that do not depend on the
renders, e.g. fig4's analytic edges). ``tolerances.json`` records, per metric, the spread, the
tolerance and the four values, plus the runs, library versions and the command. The golden values
themselves are the baseline run's (``llvm_ad_rgb``, seed 0: what CI computes on a machine without
a GPU). Booleans and strings that differ between the runs are listed under ``unstable`` (they are
still compared exactly: CI's run is deterministic per variant and seed).

Regenerating (after a deliberate change of the science, new scenes, …)
----------------------------------------------------------------------
One command rewrites every golden, the claim verdicts and the tolerances (four runs of the quick
figures, 7–8 min each at f9fe160 on two busy cores; ``tolerances.json`` records each run's seconds;
commit every change first — the runs read the working tree — then review and commit the diff)::

    .venv/bin/python -m tests.golden --regenerate

``pytest --regen-goldens`` still rewrites only the golden values from a test run (tolerances
unchanged). A missing golden file is an error unless ``--regen-goldens`` is given: a golden is never
created silently by a normal test run. ``model_fit_regression`` (analytic, no render) keeps its
explicit tolerance (``check(..., rtol=, atol=)``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

GOLDEN_DIR = Path(__file__).resolve().parent / "golden"
TOLERANCE_FILE = GOLDEN_DIR / "tolerances.json"
ROOT = GOLDEN_DIR.parents[1]

#: (Mitsuba variant, render seed) of the spread runs; the first is the baseline the goldens store.
SPREAD_RUNS = (("llvm_ad_rgb", 0), ("llvm_ad_rgb", 1), ("scalar_rgb", 0), ("scalar_rgb", 1))
#: tol = max(SPREAD_FACTOR × spread, FLOOR_ATOL + FLOOR_RTOL·|golden|).
#: The floor is for metrics the renders do not change (analytic edges, the photos of fig11): float
#: round-off of the FFTs, BLAS and the iterative Eq. (4) solve (relative tolerance 1e-6) on another CPU.
SPREAD_FACTOR = 3.0
FLOOR_ATOL = 1e-6
FLOOR_RTOL = 1e-5
REGENERATE_COMMAND = ".venv/bin/python -m tests.golden --regenerate"


# --- flattening --------------------------------------------------------------------------------------
def flatten(d, prefix=""):
    """Nested dicts → ``{"a.b.c": value}``; numbers as float, bools and strings kept, None (NaN) kept.

    Lists and other types are ignored (ranges such as ``gt_range_px`` are not watched).
    """
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "."))
        elif isinstance(v, bool) or isinstance(v, str) or v is None:
            out[key] = v
        elif isinstance(v, (int, float)):
            out[key] = float(v)
    return out


def _is_nan(x):
    return x is None or (isinstance(x, float) and math.isnan(x))


def _as_number(x):
    """A flattened value as float when it is a number (NaN for None); None for bools and strings."""
    if _is_nan(x):
        return math.nan
    if isinstance(x, bool) or isinstance(x, str):
        return None
    return float(x)


# --- what each golden watches (shared by the tests and the spread measurement) ------------------------
ESTIMATORS = ("model_fit", "zero_crossing", "gradient_ratio")
#: Id columns of a row that name it in a golden (the metric follows).
KEY_COLUMNS = ("scene_set", "scene", "preset", "aperture", "encoding", "noise", "estimator", "variant")


def row_key(row: dict) -> str:
    """A row's name in a golden: its set id columns joined by ``|``, then ``:`` and the metric."""
    ids = [f"f{row[c]:g}" if c == "aperture" else str(row[c]) for c in KEY_COLUMNS if row.get(c) is not None]
    return "|".join(ids) + ":" + row["metric"]


def _watch(*patterns):
    """An extractor keeping the rows whose metric matches one of ``patterns`` (regular expressions, full match)."""
    import re

    compiled = [re.compile(p) for p in patterns]

    def values(rows) -> dict:
        return {row_key(r): r["value"] for r in rows if any(p.fullmatch(r["metric"]) for p in compiled)}

    return values


_FIG5_STAGES = "(before|after_bias|after_no_bias)"
_FIG6_MAP = "(all_mae|all_bias|textured_mae|textured_bias|edges_mae|rtf_nmse|rtf_nmae|edge_rms_to_bm)"

#: golden name -> (figure, extractor of the figure's rows); "evaluate_quick" and "claims_quick" are special
#: (repro.evaluate rows; verdicts over CLAIM_FIGURES). Every preset and scene set of the quick run is watched.
FIGURE_GOLDENS = {
    "fig4_quick": ("fig4", _watch(r"(line_spread|erf_fit)/(mae|median_ae|outlier_fraction|bias)",
                                  r"noisy/(mae|median_ae)", r"clean/median_ae", r"bar/noisy/D=[^/]+/median_rel_error")),
    "fig5_quick": ("fig5", _watch(_FIG5_STAGES + r"/mae", _FIG5_STAGES + r"/in_focus_outliers/fraction")),
    "fig6_quick": ("fig6", _watch(r"alpha=[^/]+/" + _FIG6_MAP, r"from_sparse/alpha=[^/]+/(all_mae|all_bias)",
                                  r"map_change_px/(textured_mean|all_mean)", r"energy_terms/.*")),
    "fig7_quick": ("fig7", _watch(r"maps_vs_gt_large/(k_x_gt_small_naive|map_small|k_x_map_small|map_large)/(mae|bias)",
                                  r"image_vs_large/.*", r"k_x_map_small_vs_map_large/(mae|median_rel_error)")),
    "fig8_quick": ("fig8", _watch(r"images_vs_d2/.*", r"deconvolution_vs_pinhole/.*", r"virtual_map_vs_gt_d2/.*",
                                  r"sigma_t_px", r"map_floor_px")),
    "fig11_quick": ("fig11", _watch(r"(all_mae|all_bias|textured_mae|edges_mae|rtf_nmae|map_median_px|map_p95_px|"
                                    r"edge_fraction)")),
}


def golden_values(name: str, rows) -> dict:
    """The values golden ``name`` watches, from its figure's rows of the quick results table."""
    return FIGURE_GOLDENS[name][1](rows)


#: repro.evaluate run of the evaluate golden (tests/test_evaluate.py runs the same through the CLI).
EVALUATE_ARGS = {"estimators": ESTIMATORS, "scene": "planes", "f_number": 8.0, "scene_preset": "small"}
EVALUATE_COLUMNS = ("sparse_mae", "sparse_median_ae", "sparse_outlier_fraction", "refined_mae", "dense_all_mae",
                    "dense_textured_mae", "rtf_nmae")


def evaluate_values(rows):
    return {r["estimator"]: {c: r[c] for c in EVALUATE_COLUMNS} for r in rows}


#: Figures whose quick rows the claims are judged on.
CLAIM_FIGURES = ("fig2", "fig4", "fig5", "fig6", "fig7", "fig8", "fig10", "fig11")


def claims_values(table) -> dict:
    """``{"<preset>/<scene set>": {claim id: verdict}}`` for every column of the claims matrix of ``table``."""
    from experiments.claims import claim_matrix

    return {f"{p}/{s or 'default'}": {c.id: v.verdict for c, v in rows} for (p, s), rows in claim_matrix(table).items()}


RENDER_GOLDENS = (*FIGURE_GOLDENS, "evaluate_quick", "claims_quick")


# --- comparison ----------------------------------------------------------------------------------------
def load_tolerances() -> dict:
    if not TOLERANCE_FILE.exists():
        return {}
    return json.loads(TOLERANCE_FILE.read_text()).get("metrics", {})


def _atomic_json(path: Path, obj) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(obj, indent=1, sort_keys=True, ensure_ascii=False) + "\n")
    tmp.replace(path)


def compare(name: str, flat: dict, golden: dict, tolerances: dict | None, *, rtol=None, atol=None) -> list[str]:
    """The differences of ``flat`` from ``golden`` that exceed their tolerance (empty: no regression).

    ``rtol``/``atol`` given: the explicit rule ``atol + rtol·|golden|`` for every number; otherwise each
    number needs a measured ``tolerances[key]["tol"]``.
    """
    bad = []
    for key in sorted(set(golden) - set(flat)):
        bad.append(f"{key}: in the golden, missing from the run")
    for key in sorted(set(flat) - set(golden)):
        bad.append(f"{key}: new metric (= {flat[key]!r}) not in the golden; regenerate: {REGENERATE_COMMAND}")
    for key in sorted(set(golden) & set(flat)):
        ref, got = golden[key], flat[key]
        if isinstance(ref, (bool, str)) or isinstance(got, (bool, str)):
            if type(ref) is not type(got) or ref != got:
                bad.append(f"{key}: golden {ref!r}, got {got!r} (compared exactly)")
            continue
        if _is_nan(ref) or _is_nan(got):
            if not (_is_nan(ref) and _is_nan(got)):
                bad.append(f"{key}: golden {ref!r}, got {got!r} (NaN must stay NaN)")
            continue
        if math.isinf(ref) or math.isinf(got):  # e.g. the PSNR of equal pixels: infinite must stay equal
            if got != ref:
                bad.append(f"{key}: golden {ref!r}, got {got!r} (an infinity must stay the same)")
            continue
        if rtol is not None or atol is not None:
            allowed = (atol or 0.0) + (rtol or 0.0) * abs(ref)
        else:
            entry = (tolerances or {}).get(key)
            if entry is None:
                bad.append(f"{key}: no measured tolerance in {TOLERANCE_FILE.name}; run {REGENERATE_COMMAND}")
                continue
            allowed = float(entry["tol"])
        if not abs(got - ref) <= allowed:
            bad.append(f"{key}: golden {ref:.6g}, got {got:.6g} (allowed ±{allowed:.3g})")
    return bad


class Goldens:
    """Compare (or, when regenerating, write) named dicts of metrics."""

    def __init__(self, regenerate: bool):
        self.regenerate = regenerate

    def check(self, name: str, values: dict, *, rtol: float | None = None, atol: float | None = None) -> None:
        """Assert ``values`` match ``golden/<name>.json`` (see the module docstring for the rules).

        Nested dicts are flattened to dotted keys. Without ``rtol``/``atol`` every number is compared
        with its measured tolerance from ``golden/tolerances.json``.
        """
        path = GOLDEN_DIR / f"{name}.json"
        flat = flatten(values)
        if self.regenerate:
            _atomic_json(path, flat)
            return
        if not path.exists():
            raise AssertionError(f"no golden file {path}; run pytest --regen-goldens to create it")
        golden = json.loads(path.read_text())
        tolerances = None if (rtol is not None or atol is not None) else load_tolerances().get(name, {})
        bad = compare(name, flat, golden, tolerances, rtol=rtol, atol=atol)
        assert not bad, f"{name} drifted from tests/golden/{name}.json:\n  " + "\n  ".join(bad)


# --- computing the quick data (tests: cached; spread runs: fresh) ---------------------------------------
def quick_config(figure: str, *, seed: int | None = None):
    """The quick config of ``figure``, with its render seed set to ``seed`` when given."""
    from experiments.registry import FIGURES

    config = FIGURES[figure].config("quick")
    if seed is not None:
        names = {f.name for f in dataclasses.fields(config)}
        for field in ("render_seed", "seed"):
            if field in names:
                config = dataclasses.replace(config, **{field: seed})
    return config


def quick_data(figure: str, *, cached: bool = True, seed: int | None = None):
    """Every case of the quick config of ``figure`` (:class:`experiments.figure_data.FigureData`), in this
    process, through the figure cache (``cached``) or in memory."""
    import warnings

    from experiments.figure_data import run_figure
    from experiments.registry import FIGURES

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return run_figure(FIGURES[figure], quick_config(figure, seed=seed), mode="quick", use_cache=cached)


def evaluate_rows(*, cached: bool = True) -> list[dict]:
    from experiments.units import evaluate_case
    from repro.evaluate import table_rows

    a = EVALUATE_ARGS
    cases = [evaluate_case(e, a["scene"], f_number=a["f_number"], preset=a["scene_preset"], use_cache=cached)
             for e in a["estimators"]]
    return json.loads(json.dumps(table_rows(cases), default=float))


def _force_seed(seed: int) -> None:
    """Make every render_scene call (package and module attribute) render with ``seed``."""
    import scenes
    import scenes.render

    original = scenes.render.render_scene

    def seeded(*args, **kwargs):
        kwargs["seed"] = seed
        return original(*args, **kwargs)

    scenes.render_scene = seeded
    scenes.render.render_scene = seeded


def _one_run(seed: int, out: Path) -> None:
    """Inside a fresh process with $DEFOCUS_MITSUBA_VARIANT set: every golden's flat values at ``seed``."""
    from tqdm import tqdm

    _force_seed(seed)
    values, rows = {}, {}
    figures = sorted(set(CLAIM_FIGURES) | {f for f, _ in FIGURE_GOLDENS.values()})
    for fig in tqdm(figures, desc=f"{os.environ.get('DEFOCUS_MITSUBA_VARIANT')} seed {seed}", unit="figure"):
        rows[fig] = quick_data(fig, cached=False, seed=seed).rows()
    for name, (fig, extract) in FIGURE_GOLDENS.items():
        values[name] = flatten(extract(rows[fig]))
    values["evaluate_quick"] = flatten(evaluate_values(evaluate_rows(cached=False)))
    values["claims_quick"] = flatten(claims_values([r for f in CLAIM_FIGURES for r in rows[f]]))
    _atomic_json(out, values)


def _git_commit() -> str | None:
    """HEAD of the measured tree, with "+dirty" when its method/scenes/experiments differ from HEAD
    ($GOLDEN_MEASURED_COMMIT when the tree is an exported copy, e.g. ``git archive <commit>``)."""
    if os.environ.get("GOLDEN_MEASURED_COMMIT"):
        return os.environ["GOLDEN_MEASURED_COMMIT"]
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                              text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "method", "scenes", "experiments"], cwd=ROOT,
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None
    return head + ("+dirty" if dirty else "")


def _runs_dir() -> Path:
    from scenes.backend import cache_root

    d = Path(cache_root()) / "golden_spread"
    d.mkdir(parents=True, exist_ok=True)
    return d


def measure_spread(runs=SPREAD_RUNS, *, resume: bool = False) -> tuple[dict, dict]:
    """Run every (variant, seed) in its own process; returns (baseline values, tolerance document)."""
    from tqdm import tqdm

    from experiments.registry import library_versions

    from experiments.cache_keys import code_fingerprint

    per_run = []
    # one file per run, named by the code fingerprint: --resume reuses the runs an interrupted
    # measurement finished (same code only); without it every run is recomputed.
    runs_dir = _runs_dir()
    for variant, seed in tqdm(runs, desc="spread runs", unit="run"):
        out = runs_dir / f"{code_fingerprint()[:16]}_{variant}_{seed}.json"
        meta = out.with_suffix(".seconds")
        if not (resume and out.exists()):
            env = {**os.environ, "DEFOCUS_MITSUBA_VARIANT": variant}
            t0 = time.perf_counter()
            proc = subprocess.run([sys.executable, "-m", "tests.golden", "--one-run", str(seed), str(out)],
                                  cwd=ROOT, env=env)
            if proc.returncode != 0:
                raise RuntimeError(f"the {variant} seed {seed} run failed (exit {proc.returncode}; its traceback "
                                   "is above); finished runs are kept for --resume")
            meta.write_text(f"{time.perf_counter() - t0:.1f}\n")
        seconds = float(meta.read_text()) if meta.exists() else None
        per_run.append({"variant": variant, "seed": seed, "seconds": seconds, "values": json.loads(out.read_text())})
    baseline = per_run[0]["values"]
    metrics, unstable = {}, {}
    for name in RENDER_GOLDENS:
        metrics[name] = {}
        for key, ref in baseline[name].items():
            vals = [r["values"].get(name, {}).get(key) for r in per_run]
            if isinstance(ref, (bool, str)):
                if len({json.dumps(v) for v in vals}) > 1:
                    unstable.setdefault(name, {})[key] = vals
                continue
            nums = [_as_number(v) for v in vals]
            finite = [x for x in nums if x is not None and math.isfinite(x)]
            spread = (max(finite) - min(finite)) if len(finite) == len(nums) else None
            ref_num = _as_number(ref)
            floor = FLOOR_ATOL + FLOOR_RTOL * (abs(ref_num) if ref_num is not None and math.isfinite(ref_num) else 0.0)
            if spread is None:  # NaN/inf in some run: NaN must stay NaN; the finite ones still get a bound
                spread = (max(finite) - min(finite)) if finite else 0.0
            metrics[name][key] = {"spread": spread, "tol": max(SPREAD_FACTOR * spread, floor), "values": nums}
    doc = {
        "how": ("every quick figure the goldens watch (and repro.evaluate's planes f/8 small case) computed in "
                "one process per (Mitsuba variant, render seed) — the seed forced on every render_scene call — "
                "figure results uncached; spread = max − min of a metric over the runs"),
        "rule": f"tol = max({SPREAD_FACTOR:g} × spread, {FLOOR_ATOL:g} + {FLOOR_RTOL:g}·|golden|); booleans and "
                "strings compared exactly",
        "command": REGENERATE_COMMAND,
        "runs": [{k: r[k] for k in ("variant", "seed", "seconds")} for r in per_run],
        "baseline": {"variant": runs[0][0], "seed": runs[0][1]},
        "code_fingerprint": code_fingerprint(),
        "git_commit": _git_commit(),
        "measured_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "library_versions": library_versions(),
        "unstable": unstable,
        "metrics": metrics,
    }
    return baseline, doc


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.golden", description=__doc__.split("\n\n")[0])
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--regenerate", action="store_true",
                   help="measure the spread and rewrite tests/golden/<render goldens>.json and tolerances.json")
    g.add_argument("--measure-spread", action="store_true",
                   help="measure the spread and rewrite tolerances.json only (goldens unchanged)")
    g.add_argument("--one-run", nargs=2, metavar=("SEED", "OUT"), help=argparse.SUPPRESS)
    ap.add_argument("--runs", nargs="+", metavar="VARIANT:SEED",
                    default=[f"{v}:{s}" for v, s in SPREAD_RUNS],
                    help="the spread runs, the first the baseline (default: %(default)s)")
    ap.add_argument("--resume", action="store_true",
                    help="reuse the runs an interrupted measurement finished (same code fingerprint)")
    args = ap.parse_args(argv)
    if args.one_run:
        _one_run(int(args.one_run[0]), Path(args.one_run[1]))
        return 0
    try:
        runs = [(r.split(":")[0], int(r.split(":")[1])) for r in args.runs]
    except (IndexError, ValueError):
        ap.error(f"--runs {' '.join(args.runs)} is invalid; allowed: VARIANT:SEED ...")
    if len(runs) < 2:
        ap.error("--runs needs at least two runs to measure a spread")
    try:
        baseline, doc = measure_spread(runs, resume=args.resume)
    except RuntimeError as exc:
        print(f"python -m tests.golden: {exc}", file=sys.stderr)
        return 2
    _atomic_json(TOLERANCE_FILE, doc)
    if args.regenerate:
        for name in RENDER_GOLDENS:
            _atomic_json(GOLDEN_DIR / f"{name}.json", baseline[name])
    n = sum(len(v) for v in doc["metrics"].values())
    print(f"wrote {TOLERANCE_FILE} ({n} tolerances; unstable booleans/strings: "
          f"{sum(len(v) for v in doc['unstable'].values())})" + (" and the render goldens" if args.regenerate else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
