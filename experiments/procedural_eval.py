"""Scoring the method presets on the procedural scene family: the plan, one scene's task, the tables.

An evaluation is a :class:`ProceduralPlan`: N consecutive seeds of one split
(:data:`scenes.library.procedural.SPLITS`), the method presets, the apertures, the render size, the
input encodings and sensor noise levels. :func:`score_scene` is one scene's whole work — render it at
every aperture (through the render cache), give each preset the image each encoding × noise level
makes of it, score every map against σ_gt (:func:`experiments.evaluation.evaluate_result`) — and
returns its rows of the long results table (:mod:`experiments.results_table`) and its timings. It is
a plain module function of JSON-able arguments, so a Dask worker can run it (``repro.evaluate
--procedural``, one case of :data:`experiments.units.PROCEDURAL` per scene in the one case store).

Noise: the sensor noise of an input is drawn from a seed made of the scene seed, the aperture and the
level (:func:`noise_seed`), so every preset sees the same noisy image and a rerun sees it again.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
import traceback
from pathlib import Path

from .results_table import metric_rows, summarise
from .scoring import FAILED_METRIC

__all__ = ["FAILED_METRIC", "PROCEDURAL_EVAL_VERSION", "SOURCE", "ProceduralPlan", "latest_evaluations",
           "noise_seed", "plan_evaluation", "score_scene", "summary_rows"]

#: Version of :func:`score_scene`'s output; part of every scene's case key (:data:`experiments.units.PROCEDURAL`).
PROCEDURAL_EVAL_VERSION = 3  # 2: stored in the one case store; 3: the trivial baselines (experiments.baselines) as rows
#: The ``source`` column of the family's rows.
SOURCE = "procedural"
#: Ground-truth facts of a render stored as rows (metadata ``stats`` key → metric name).
_GT_FACTS = (("sigma_px_min", "gt_sigma_min"), ("sigma_px_median", "gt_sigma_median"),
             ("sigma_px_p95", "gt_sigma_p95"), ("sigma_px_max", "gt_sigma_max"),
             ("depth_min_m", "gt_depth_min_m"), ("depth_max_m", "gt_depth_max_m"),
             ("occlusion_boundary_fraction", "gt_occlusion_boundary_fraction"))


@dataclasses.dataclass(frozen=True)
class ProceduralPlan:
    """A validated evaluation of the procedural family (:func:`plan_evaluation`)."""

    split: str
    start: int
    n: int
    presets: tuple
    f_numbers: tuple
    scene_size: str
    noises: tuple
    encodings: tuple
    spp: int | None
    variant: str | None
    estimators: tuple = (None,)  # None: each preset's own estimator; a name: the preset with that estimator

    @property
    def seeds(self) -> range:
        """The scene seeds, start … start + n − 1."""
        return range(self.start, self.start + self.n)

    def to_dict(self) -> dict:
        """JSON-able fields (``estimators`` only when it is not the presets' own, so such a plan keeps its id)."""
        out = {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(self).items()}
        if self.estimators == (None,):
            del out["estimators"]
        return out

    def runs(self) -> list[tuple[str, str | None]]:
        """``(preset, estimator or None)`` of every run of the method on an input, in table order."""
        return [(p, e) for p in self.presets for e in self.estimators]

    @property
    def evaluation_id(self) -> str:
        """``<split>-<start>-n<N>-<scene size>-<hash>``: the same plan, the same id (and folder)."""
        from defocus_cache import hash_key

        return f"{self.split}-{self.start}-n{self.n}-{self.scene_size}-{hash_key(self.to_dict())[:8]}"

    def command(self) -> list[str]:
        """``repro.evaluate`` arguments that run this plan again (the seeds spelled out)."""
        args = ["--procedural", str(self.n), "--split", self.split, "--scene-seed-start", str(self.start),
                "--preset", *self.presets, "--fnumber", *(f"{n:g}" for n in self.f_numbers),
                "--scene-preset", self.scene_size, "--noise", *self.noises, "--encoding", *self.encodings]
        if self.estimators != (None,):
            args += ["--estimator", *self.estimators]
        if self.spp is not None:
            args += ["--spp", str(self.spp)]
        if self.variant is not None:
            args += ["--variant", self.variant]
        return args


def plan_evaluation(n, *, split, start=None, presets=None, f_numbers=None, scene_size="small", noises=("none",),
                    encodings=("srgb",), spp=None, variant=None, estimators=None) -> ProceduralPlan:
    """Check every option of an evaluation and draw the fresh seeds; nothing is rendered.

    Parameters
    ----------
    n : int
        Number of scenes (> 0).
    split : {"dev", "test", "fresh"}, keyword-only
    start : int, optional, keyword-only
        First seed. Default: the split's first seed (dev, test) or one drawn at run time (fresh,
        :func:`scenes.library.procedural.draw_fresh_start`; recorded in the plan).
    presets : sequence of str, optional, keyword-only
        Keys of :data:`method.PRESETS` (default: all; with ``estimators``: ``paper``).
    f_numbers : sequence of float, optional, keyword-only
        Apertures (default :data:`scenes.library.procedural.PROCEDURAL_F_NUMBERS`: 8, 4, 2).
    scene_size : {"small", "full"}, keyword-only
        Render resolution preset.
    noises : sequence of str, keyword-only
        Names of :data:`scenes.display.NOISE_LEVELS`.
    encodings : sequence of str, keyword-only
        ``"srgb"`` / ``"linear"``.
    spp : int, optional, keyword-only
        Samples per pixel of every render (default: each scene's own, 144 emission-only, 256 lit).
    variant : str, optional, keyword-only
        Mitsuba variant requested.
    estimators : sequence of str, optional, keyword-only
        Keys of :data:`method.BLUR_ESTIMATORS`: every preset runs once with each instead of its own
        (``DefocusParams.preset(p).replace(estimator=e)``; the rows' ``estimator`` column tells them
        apart). Default: each preset's own.

    Raises
    ------
    ValueError
        One line naming the bad value and what is allowed: an unknown split, preset, estimator, noise
        level or encoding; a preset that does not take an estimator; n ≤ 0; seeds reaching outside the
        split (into another one); a bad f-number or spp.
    """
    from method import BLUR_ESTIMATORS, PRESETS, DefocusParams
    from scenes.display import NOISE_LEVELS
    from scenes.library import PRESETS as SIZES
    from scenes.library.procedural import PROCEDURAL_F_NUMBERS, SPLITS, check_seed_range, draw_fresh_start

    from .evaluation import ENCODINGS

    if not isinstance(split, str) or split not in SPLITS:
        raise ValueError(f"--split {split!r} is invalid (unknown split); allowed: {', '.join(SPLITS)}")
    if isinstance(n, bool) or not isinstance(n, int) or n <= 0:
        raise ValueError(f"--procedural {n!r} is invalid; allowed: a number of scenes N > 0")
    if start is None:
        start = draw_fresh_start(n) if SPLITS[split].drawn else SPLITS[split].start
    seeds = check_seed_range(split, start, n)
    if presets is None:
        presets = PRESETS if estimators is None else ("paper",)
    names = tuple(PRESETS.check_all(dict.fromkeys(presets), what="preset"))
    ests = (None,) if estimators is None else tuple(BLUR_ESTIMATORS.check_all(dict.fromkeys(estimators),
                                                                              what="estimator"))
    for name in names:
        for est in ests if estimators is not None else ():
            try:
                DefocusParams.preset(name).replace(estimator=est)
            except ValueError as exc:
                raise ValueError(f"--estimator {est} with --preset {name}: {exc}") from None
    numbers = tuple(dict.fromkeys(float(x) for x in (f_numbers or PROCEDURAL_F_NUMBERS)))
    if any(not (x > 0 and x < float("inf")) for x in numbers):
        raise ValueError(f"--fnumber {numbers} is invalid; allowed: finite numbers > 0")
    if scene_size not in SIZES:
        raise ValueError(f"--scene-preset {scene_size!r} is invalid; allowed: {', '.join(SIZES)}")
    for level in noises:
        if level not in NOISE_LEVELS:
            raise ValueError(f"--noise {level!r} is invalid (unknown noise level); allowed: {', '.join(NOISE_LEVELS)}")
    for enc in encodings:
        if enc not in ENCODINGS:
            raise ValueError(f"--encoding {enc!r} is invalid; allowed: {', '.join(ENCODINGS)}")
    if spp is not None and (isinstance(spp, bool) or not isinstance(spp, int) or spp <= 0):
        raise ValueError(f"--spp {spp!r} is invalid; allowed: an integer > 0")
    return ProceduralPlan(split=split, start=seeds.start, n=len(seeds), presets=names, f_numbers=numbers,
                          scene_size=scene_size, noises=tuple(dict.fromkeys(noises)),
                          encodings=tuple(dict.fromkeys(encodings)), spp=spp, variant=variant, estimators=ests)


def noise_seed(seed: int, f_number: float, noise: str) -> int:
    """Seed of the sensor noise of one input: from the scene seed, the aperture (1/1000 f-stops) and the level."""
    import numpy as np

    from scenes.display import NOISE_LEVELS

    ss = np.random.SeedSequence([int(seed), int(round(float(f_number) * 1000)), list(NOISE_LEVELS).index(noise)])
    return int(ss.generate_state(1, dtype=np.uint32)[0])


def _run_label(preset: str, estimator: str | None) -> str:
    """``preset`` or ``preset+estimator`` (a preset run with another estimator), for timings and messages."""
    return preset if estimator is None else f"{preset}+{estimator}"


def _render_rows(render, ids: dict, plan: ProceduralPlan, seed: int, failures: list,
                 tracebacks: list) -> tuple[list[dict], dict]:
    """Rows of every encoding × noise × preset (× estimator) on one render
    (:func:`experiments.scoring.score_render`), and the seconds spent per run; a run of the method that raises
    gets one :data:`FAILED_METRIC` row of 1, a line in ``failures`` and its traceback in ``tracebacks``."""
    from method import DefocusParams

    from .baselines import baseline_rows
    from .evaluation import input_image
    from .scoring import score_render

    rows, seconds = [], dict.fromkeys((_run_label(p, e) for p, e in plan.runs()), 0.0)
    f_number = ids["aperture"]
    for encoding in plan.encodings:
        for noise in plan.noises:
            image = input_image(render, encoding=encoding, quantize_bits=8, noise=noise,
                                rng=noise_seed(seed, f_number, noise))
            rows += baseline_rows(render, {**ids, "encoding": encoding, "noise": noise}, image=image)
            for preset, estimator in plan.runs():
                t0, label = time.perf_counter(), _run_label(preset, estimator)
                params = DefocusParams.preset(preset)
                if estimator is not None:
                    params = params.replace(estimator=estimator)
                row_ids = {**ids, "preset": preset, "estimator": params.estimator, "encoding": encoding, "noise": noise}
                score = score_render(render, image, encoding=encoding, params=params)
                if score.failed:
                    failures.append(f"{label} on {ids['scene']} f/{f_number:g} {encoding} {noise}: {score.error}")
                    tracebacks.append("".join(traceback.format_exception(score.exception)))
                rows += metric_rows(row_ids, score.flat())
                seconds[label] += time.perf_counter() - t0
    return rows, seconds


def score_scene(seed: int, *, plan: dict, evaluation_id: str) -> dict:
    """One scene of an evaluation: render it at every aperture, score every preset on every input.

    Parameters
    ----------
    seed : int
        Scene seed.
    plan : dict, keyword-only
        :meth:`ProceduralPlan.to_dict` of the evaluation.
    evaluation_id : str, keyword-only
        The ``evaluation_id`` column.

    Returns
    -------
    dict
        ``rows`` (the scene's rows of the results table: ground-truth facts per aperture, then every
        metric per aperture × encoding × noise × preset, :data:`FAILED_METRIC` among them), ``failures`` (one
        line per run of the method that raised: preset, input, exception), ``traceback`` (the first such run's, or
        None), ``timings`` (``lighting``, per aperture the
        seconds this task spent on the render (≈ 0 when cached), the seconds the render took when
        it was made and the seconds of scoring per preset, ``host``, ``pid``) and ``variant`` (Mitsuba's).

    Notes
    -----
    1. The scene :func:`scenes.library.procedural.procedural_scene` of ``seed``.
    2. Per aperture: :func:`scenes.render_scene` (cached), the ground-truth facts of its metadata.
    3. Per encoding × noise level: the input (:func:`experiments.evaluation.input_image`, 8 bits,
       noise seed :func:`noise_seed`); per preset the whole pipeline on one thread and
       :func:`experiments.evaluation.evaluate_result`, flattened into rows (a pipeline that raises is
       recorded as failed, and the other presets and inputs go on).
    """
    from scenes import render_scene
    from scenes.library.procedural import procedural_scene, split_of

    p = ProceduralPlan(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in plan.items()})
    sdef = procedural_scene(int(seed))
    layout = sdef.facts["layout"]
    rows, timings = [], {"lighting": layout["lighting"], "camera": layout["camera_name"], "render_s": {},
                         "render_built_s": {}, "score_s": {}, "host": os.uname().nodename, "pid": os.getpid()}
    variant, failures, tracebacks = None, [], []
    for f_number in p.f_numbers:
        t0 = time.perf_counter()
        render = render_scene(sdef.name, preset=p.scene_size, f_number=f_number, spp=p.spp, variant=p.variant,
                              progress=False)
        key = f"{f_number:g}"
        timings["render_s"][key] = time.perf_counter() - t0
        md = render.metadata
        timings["render_built_s"][key] = sum(float(md.get(k) or 0.0) for k in
                                             ("load_time_s", "render_time_s", "ground_truth_time_s"))
        variant = md.get("variant")
        ids = {"evaluation_id": evaluation_id, "source": SOURCE, "scene": sdef.name, "seed": int(seed),
               "split": split_of(int(seed)), "scene_size": p.scene_size, "camera": layout["camera_name"],
               "lighting": layout["lighting"], "aperture": float(f_number)}
        rows += metric_rows(ids, {name: md["stats"].get(k) for k, name in _GT_FACTS})
        scored, seconds = _render_rows(render, ids, p, int(seed), failures, tracebacks)
        rows += scored
        timings["score_s"][key] = seconds
    return {"rows": rows, "timings": timings, "variant": variant, "failures": failures,
            "traceback": tracebacks[0] if tracebacks else None}


def summary_rows(rows) -> list[dict]:
    """:func:`experiments.results_table.summarise` per split, scene size, preset, estimator, aperture, encoding and
    noise."""
    return summarise(rows, by=("split", "scene_size", "preset", "estimator", "aperture", "encoding", "noise", "metric"))


def latest_evaluations(root) -> dict:
    """The newest finished evaluation of each split and render size under ``root`` (folders holding
    ``summary.json`` and ``results.csv``, which ``repro.evaluate --procedural`` writes last).

    Returns
    -------
    dict
        ``{split: {scene_size: {"path": Path of results.csv, "meta": the summary's metadata}}}``, the
        newest by ``finished_utc``; empty when there is none. Unreadable folders are skipped.
    """
    best: dict[str, dict] = {}
    for path in sorted(Path(root).glob("*/summary.json")) if Path(root).is_dir() else []:
        try:
            meta = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        plan = meta.get("plan", {}) if isinstance(meta, dict) else {}
        split, size = plan.get("split"), plan.get("scene_size")
        csv_path = path.parent / "results.csv"
        if not split or not csv_path.is_file():
            continue
        meta = {k: v for k, v in meta.items() if k != "summary"}
        old = best.setdefault(split, {}).get(size)
        if old is None or meta.get("finished_utc", "") > old["meta"].get("finished_utc", ""):
            best[split][size] = {"path": csv_path, "meta": meta}
    return best
