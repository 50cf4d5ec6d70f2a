"""Fig. 4's analytic images: Gaussian-blurred straight and curved steps and neighbouring edges, exact σ.

Each family is one case per method preset (:func:`analytic_case`): the images of
:mod:`scenes.analytic` for every σ, angle and (for the neighbouring edges) spacing of the config, both
noise-free (``clean``) and camera-like (``noisy``: noise + 8 bits), edge pixels estimated by every
estimator of the preset. The noise seeds run on through the families in a fixed order (straight,
curved, neighbouring), so each family's first seed is known without computing the others
(:func:`family_seed`).

On the procedural test split (``scene_set="procedural_test"``) the straight and curved steps take their
σ from the held-out scenes instead of the config's grid: every surface of each scene
(:func:`scenes.library.procedural.draw_layout`) with σ = c/4 at ``procedural_f_number`` and the full
render width inside the grid's range, and step angles drawn from the scene's seed
(:func:`procedural_steps`).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["CONDITIONS", "FAMILIES", "analytic_case", "family_seed", "pooled_metrics", "procedural_steps"]

#: Analytic conditions: noise-free, and noise + 8-bit quantisation.
CONDITIONS = ("clean", "noisy")
#: The analytic families, in the order their noise seeds are drawn.
FAMILIES = ("straight", "curved", "neighbouring")
#: Domain tag of the angle draw of the procedural steps.
_ANGLE_DOMAIN = 0x0F14_A11E


def pooled_metrics(err_est, err_gt, outlier_px) -> dict:
    """Sparse metrics of concatenated estimates against concatenated σ (``n``, ``mae``, ``median_ae``,
    ``median_rel_error``, ``outlier_fraction``, ``bias``, ``rmse``)."""
    from .metrics import sparse_metrics

    if err_est:
        est, gt = np.concatenate(err_est), np.concatenate(err_gt)
    else:
        est = gt = np.zeros(0)
    m = sparse_metrics(est, gt, outlier_px=outlier_px)
    return {k: m[k] for k in ("n", "mae", "median_ae", "median_rel_error", "outlier_fraction", "bias", "rmse")}


def _scored(sc, estimators, params, config, border):
    """Estimates at the scored edge pixels of one analytic image: {est: values}."""
    from .evaluation import sparse_estimates

    # the analytic steps are Gaussian-blurred in their values: display (sRGB) values, as declared by default
    edges, sig = sparse_estimates(sc.image, estimators, params=params)
    inner = np.zeros(sc.image.shape, dtype=bool)
    inner[border:-border, border:-border] = True
    sel = edges & inner & (np.abs(sc.edge_distance) < config.edge_tolerance_px)
    return {name: s[sel] for name, s in sig.items()}


def _degradation(config, cond, seed):
    if cond == "clean":
        return {}
    return {"noise_std": config.noise_std, "quantize_bits": 8, "rng": int(seed)}


def family_seed(config, family: str) -> int:
    """The noise seed before the first image of ``family`` (the families draw in :data:`FAMILIES` order)."""
    seed = config.noise_seed
    if family == "straight":
        return seed
    seed += len(CONDITIONS) * len(config.analytic_sigmas) * len(config.analytic_angles_deg)
    if family == "curved":
        return seed
    return seed + len(CONDITIONS) * len(config.analytic_sigmas)


def procedural_steps(config, scenes) -> tuple[np.ndarray, np.ndarray, int]:
    """σ (px) and straight-step angles (degrees) drawn from procedural scenes, and their first noise seed.

    Every surface of each scene (subject, objects, background, floor excluded) gives σ = |c|/4 at
    ``config.procedural_f_number`` (c = its CoC at f/2 scaled by 2/N, at the full preset's 640 px
    width); those within [min, max] of ``config.analytic_sigmas`` are kept, in scene order; each gets
    an angle uniform in [0°, 360°) from ``SeedSequence([seed, domain])`` of its scene.
    """
    from scenes.library.procedural import draw_layout, seed_of

    lo, hi = min(config.analytic_sigmas), max(config.analytic_sigmas)
    sigmas, angles = [], []
    for name in scenes:
        seed, _ = seed_of(name)
        layout = draw_layout(seed)
        gen = np.random.default_rng(np.random.SeedSequence([seed, _ANGLE_DOMAIN]))
        cocs = [layout["subject"]["coc_f2_px"], *(o["coc_f2_px"] for o in layout["objects"]),
                layout["background"]["coc_f2_px"]]
        for c in cocs:
            s = abs(float(c)) * 2.0 / config.procedural_f_number / 4.0
            angle = float(gen.uniform(0.0, 360.0))
            if lo <= s <= hi:
                sigmas.append(s)
                angles.append(angle)
    first = seed_of(scenes[0])[0] if scenes else 0
    return np.asarray(sigmas), np.asarray(angles), config.noise_seed + first


def _steps(config, family, sigmas, angles_for, seed):
    """The images of one family: ``[(σ index, condition index, scene, border)]`` in seed order."""
    from scenes.analytic import blurred_disk, step_edge

    out = []
    for ci, cond in enumerate(CONDITIONS):
        for si, s in enumerate(sigmas):
            if family == "straight":
                for a in angles_for(si):
                    seed += 1
                    out.append((si, ci, step_edge(config.analytic_shape, sigma=float(s), angle=math.radians(a),
                                                  offset=0.37, **_degradation(config, cond, seed)),
                                config.analytic_border_px))
            else:
                r = config.disk_radius_factor * s + config.disk_radius_offset_px
                n = int(2 * r + 2 * config.analytic_border_px + 8 * s) | 1
                seed += 1
                out.append((si, ci, blurred_disk((n, n), sigma=float(s), radius=r, center=(n / 2 - 0.3, n / 2 + 0.2),
                                                 **_degradation(config, cond, seed)), 2))
    return out


def _steps_case(config, family, params, ests, *, sigmas, angles_for, seed) -> dict:
    """Straight or curved steps: per condition and estimator the pooled metrics, per σ the median |error|."""
    sigmas = np.asarray(sigmas, dtype=np.float64)
    med = np.full((len(CONDITIONS), len(ests), sigmas.size), np.nan)
    fail = np.full_like(med, np.nan)
    per = {(ci, si): {e: [] for e in ests} for ci in range(len(CONDITIONS)) for si in range(sigmas.size)}
    for si, ci, sc, border in _steps(config, family, sigmas, angles_for, seed):
        for e, v in _scored(sc, ests, params, config, border).items():
            per[(ci, si)][e].append(v)
    groups = []
    for ci, cond in enumerate(CONDITIONS):
        pooled = {e: ([], []) for e in ests}
        for si, s in enumerate(sigmas):
            for ei, e in enumerate(ests):
                v = np.concatenate(per[(ci, si)][e]) if per[(ci, si)][e] else np.zeros(0)
                fail[ci, ei, si] = float(np.mean(~np.isfinite(v))) if v.size else np.nan
                ok = v[np.isfinite(v)]
                med[ci, ei, si] = float(np.median(np.abs(ok - s))) if ok.size else np.nan
                pooled[e][0].append(v)
                pooled[e][1].append(np.full(v.shape, s))
        groups += [({"estimator": e}, {cond: pooled_metrics(*pooled[e], config.outlier_px)}) for e in ests]
    return {"arrays": {"sigmas": sigmas, "median_ae": med, "failure_rate": fail, "estimators": np.asarray(ests)},
            "groups": _merge_groups(groups)}


def _merge_groups(groups):
    """Groups with the same ids merged into one (their metric dicts joined)."""
    out: dict = {}
    for ids, m in groups:
        out.setdefault(tuple(sorted(ids.items())), {}).update(m)
    return [(dict(k), m) for k, m in out.items()]


def _neighbouring_case(config, params, ests, seed) -> dict:
    """Bars and staircases at spacings D = k·σ: per kind, condition, D and estimator the pooled metrics."""
    from scenes.analytic import parallel_edges

    ks = np.asarray(config.bar_spacings, dtype=np.float64)
    rel = np.full((len(config.bar_kinds), len(CONDITIONS), len(ests), ks.size), np.nan)
    groups = []
    for gi, kind in enumerate(config.bar_kinds):
        for ci, cond in enumerate(CONDITIONS):
            for ki, k in enumerate(ks):
                pooled = {e: ([], []) for e in ests}
                for s in config.bar_sigmas:
                    for a in config.bar_angles_deg:
                        seed += 1
                        sc = parallel_edges(config.bar_shape, sigma=float(s), spacing=float(k * s),
                                            angle=math.radians(a), kind=kind, offset=0.3,
                                            **_degradation(config, cond, seed))
                        border = max(config.analytic_border_px, 16)
                        for e, v in _scored(sc, ests, params, config, border).items():
                            pooled[e][0].append(v)
                            pooled[e][1].append(np.full(v.shape, s))
                m = {e: pooled_metrics(*pooled[e], config.outlier_px) for e in ests}
                for ei, e in enumerate(ests):
                    rel[gi, ci, ei, ki] = m[e]["median_rel_error"]
                groups += [({"estimator": e}, {kind: {cond: {f"D={k:g}sigma": m[e]}}}) for e in ests]
    merged: dict = {}
    for ids, m in groups:
        _deep_update(merged.setdefault(ids["estimator"], {}), m)
    return {"arrays": {"bar_spacings": ks, "bar_kinds": np.asarray(config.bar_kinds), "bar_median_rel_error": rel,
                       "estimators": np.asarray(ests)},
            "groups": [({"estimator": e}, m) for e, m in merged.items()]}


def _deep_update(a: dict, b: dict) -> None:
    for k, v in b.items():
        if isinstance(v, dict) and isinstance(a.get(k), dict):
            _deep_update(a[k], v)
        else:
            a[k] = v


def analytic_case(config, case, params, ests) -> dict:
    """One analytic case: ``case.variant`` = ``analytic:<family>``; on the procedural test split the
    steps of :func:`procedural_steps`.

    Returns
    -------
    dict
        Groups per estimator (``estimator`` column): ``<condition>/{n, mae, median_ae, median_rel_error,
        outlier_fraction, bias, rmse}`` (steps) or ``<kind>/<condition>/D=<k>sigma/…`` (neighbouring
        edges); arrays ``sigmas`` (S,) px, ``median_ae`` and ``failure_rate`` (conditions, E, S) or
        ``bar_spacings`` (K,), ``bar_kinds``, ``bar_median_rel_error`` (kinds, conditions, E, K).
    """
    family = case.variant.split(":", 1)[1]
    if family == "neighbouring":
        return _neighbouring_case(config, params, ests, family_seed(config, "neighbouring"))
    if case.scene_set is None:
        grid = config.analytic_angles_deg
        return _steps_case(config, family, params, ests, sigmas=config.analytic_sigmas, angles_for=lambda si: grid,
                           seed=family_seed(config, family))
    from .scene_sets import check_scene_sets

    (_, scenes), = check_scene_sets([(case.scene_set, dict(config.scene_sets)[case.scene_set])])
    sigmas, angles, seed = procedural_steps(config, scenes)
    if family == "curved":
        seed += 7919  # the curved steps' noise differs from the straight ones'
    return _steps_case(config, family, params, ests, sigmas=sigmas, angles_for=lambda si: (angles[si],), seed=seed)
