"""Fig. 11: results gallery — input, defocus map, magnified result, for renders and real photos.

Rendered scenes have ground truth, so their dense maps are scored (MAE / bias vs σ_gt, occlusion
bands excluded). The real photographs are the ones shipped inside scikit-image
(``skimage.data``: no download); they have no ground truth, so the figure reports their map
statistics (percentiles of σ, fraction of edge pixels) and the estimator's runtime.

Notes
-----
1. Renders: ``render_scene(name, preset, f_number)``, input ``render.image(encoding="srgb",
   quantize_bits=8)``.
2. Photos: ``skimage.data.<name>()`` (8-bit sRGB) → float in [0, 1]; when its longer side exceeds
   ``photo_max_side`` it is downscaled with :func:`method.magnify.upsampling.downscale_image` (Gaussian
   anti-aliasing prefilter) — every σ of a photo is then in px of the *downscaled* image.
3. :func:`method.estimate_defocus_map` (paper defaults), timed per stage (wall time on a shared
   2-core machine: indicative only).
4. :func:`method.magnify_defocus` with ``factor`` (Sec. 5 preprocessing, Gaussian kernel).
5. Cases (:func:`cases`): one per scene set × scene × method preset of ``config.presets`` (e.g.
   ``robust`` beside ``paper``, Sec. 5 preprocessing with the preset's ``map_clip_percent`` /
   ``map_smoothing``) and one per photo × preset (``variant="photo"``), each scored the same way; the
   means over a set's scenes are the report's and the plot's.
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "FULL", "QUICK", "SUMMARY_KEYS", "Fig11Config", "cases", "compute_case", "load_photo"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig11Config:
    """Every parameter of Fig. 11."""

    scene_sets: tuple = (("paper_cameras", ("portrait_garden", "street_figures", "patio_table", "heron_at_the_lake")),
                         ("tabletop_stress", ("planes", "tilted_plane", "portrait", "clutter", "shadow_gloss")),
                         ("procedural_test", ("procedural_100000", "procedural_100001", "procedural_100002",
                                              "procedural_100003")))
    # (scene set, scenes) pairs (experiments.scene_sets) of rendered scenes scored against σ_gt, the first
    # the default (drawn with the photos).
    preset: str = "full"
    # render preset: "small" (160x120 px) or "full" (640x480 px).
    f_number: float = 8.0
    # N of the renders (the "photo as taken"; magnification then simulates a wider aperture).
    photos: tuple[str, ...] = ("astronaut", "coffee", "chelsea", "rocket")
    # names of skimage.data RGB photos (bundled with scikit-image, no download).
    photo_max_side: int = 640
    # longer side of the processed photo, px; larger photos are downscaled (0 = never downscale).
    factor: float = 2.0
    # defocus magnification k (total blur k·B; 2 = doubling the aperture diameter).
    kernel: str = "gaussian"
    # magnification kernel (method.MAGNIFICATION_KERNELS).
    quantize_bits: int = 8
    # bits per channel of the rendered inputs (8 = JPEG-like).
    texture_threshold: float = 0.02
    # local luminance std above which a rendered pixel is "textured", image units.
    render_seed: int = 0
    # Mitsuba sampler seed.
    presets: tuple[str, ...] = ("paper", "robust")
    # method parameter presets (method.PRESETS), one case per image each (not to be confused with the
    # render `preset`).


FULL = Fig11Config()
#: Quick: small renders of fig7's quick scenes at f/8 (the renders its f/8 inputs are, so no render of its
#: own), one per hand-built set, and three photos.
QUICK = Fig11Config(preset="small", photos=("astronaut", "coffee", "chelsea"), photo_max_side=160,
                    scene_sets=(("paper_cameras", ("portrait_garden",)), ("tabletop_stress", ("portrait",)),
                                ("procedural_test", ("procedural_100000", "procedural_100001"))))


def load_photo(name: str, max_side: int = 0) -> tuple[np.ndarray, float]:
    """An RGB photo bundled with scikit-image, as float in [0, 1], optionally downscaled.

    Parameters
    ----------
    name : str
        Function name in ``skimage.data`` returning an HxWx3 uint8 image (e.g. ``"astronaut"``).
    max_side : int
        Longer side after downscaling, px (0: keep the original size).

    Returns
    -------
    (ndarray, float)
        The image, hxwx3 float64 in [0, 1], and the linear scale s = h / H (1 if not downscaled).

    Raises
    ------
    ValueError
        Unknown name, a non-RGB image, or ``max_side`` < 0.
    """
    import skimage.data

    from method.magnify.upsampling import downscale_image

    loader = getattr(skimage.data, name, None)
    if loader is None or name.startswith("_"):
        raise ValueError(f"photo {name!r} is unknown; allowed: an RGB image function of skimage.data")
    if max_side < 0:
        raise ValueError(f"max_side={max_side!r} is invalid; allowed: integer >= 0")
    img = np.asarray(loader())
    if img.ndim != 3 or img.shape[2] not in (3, 4) or img.dtype != np.uint8:
        raise ValueError(f"photo {name!r} is not an 8-bit RGB image (shape {img.shape}, {img.dtype})")
    img = img[..., :3].astype(np.float64) / 255.0
    H, W = img.shape[:2]
    if max_side and max(H, W) > max_side:
        s = max_side / max(H, W)
        shape = (max(8, round(H * s)), max(8, round(W * s)))
        return downscale_image(img, shape), shape[0] / H
    return img, 1.0


def _run(image, config, params=None):
    from method import DefocusParams, estimate_defocus_map, magnify_defocus

    params = DefocusParams() if params is None else params
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = estimate_defocus_map(image, params)
    t_est = time.perf_counter() - t0
    t0 = time.perf_counter()
    out = magnify_defocus(image, res.defocus_map, factor=config.factor, kernel=config.kernel,
                          clip_percent=params.map_clip_percent, smoothing=params.map_smoothing)
    t_mag = time.perf_counter() - t0
    timings = {f"estimate_{k}_s": float(v) for k, v in res.timings.items()}
    timings.update(estimate_wall_s=t_est, magnify_wall_s=t_mag)
    return res, out, timings


def _map_stats(res):
    m = res.defocus_map
    p = np.percentile(m, [5, 50, 95])
    return {"map_mean_px": float(m.mean()), "map_p5_px": float(p[0]), "map_median_px": float(p[1]),
            "map_p95_px": float(p[2]), "map_max_px": float(m.max()),
            "edge_fraction": float(res.edges.mean()),
            "sparse_median_px": float(np.nanmedian(res.sparse_sigma)) if res.edges.any() else float("nan")}


def cases(config: Fig11Config) -> tuple:
    """One case per scene set × scene × preset (renders) and per photo × preset (``variant="photo"``)."""
    from .cases import Case, method_presets
    from .scene_sets import set_scene_pairs

    presets = method_presets(config.presets)
    out = [Case("fig11", scene_set=s, scene=n, preset=p, aperture=float(config.f_number), encoding="srgb",
                scene_size=config.preset) for s, n in set_scene_pairs(config) for p in presets]
    out += [Case("fig11", scene=name, preset=p, variant="photo") for name in config.photos for p in presets]
    return tuple(out)


def compute_case(config: Fig11Config, case, inputs) -> dict:
    """Estimate and magnify one image with one preset; score a render's map against σ_gt.

    Returns
    -------
    dict
        Arrays ``input`` (H, W, 3), ``map`` (H, W) σ px, ``magnified`` (H, W, 3), ``sparse`` (H, W) σ px at
        edges (NaN elsewhere); for renders also ``gt`` (H, W) σ_gt px and ``occlusion`` (H, W) bool.
        Metrics: map statistics (:func:`_map_stats`); for renders dense MAE / bias per region vs σ_gt
        (``all``, ``textured``, ``edges``), RTF-normalised errors and ``sigma_gt_range_px``; for photos
        ``scale_from_original`` and ``megapixels``. Info: ``shape`` and ``timings``.
    """
    from method import DefocusParams

    from .metrics import dense_metrics, region_masks, rtf_normalized_errors

    params = DefocusParams.preset(case.preset)
    if case.variant == "photo":
        image, scale = load_photo(case.scene, config.photo_max_side)
        res, out, timings = _run(image, config, params)
        metrics = {**_map_stats(res), "scale_from_original": scale,
                   "megapixels": image.shape[0] * image.shape[1] / 1e6}
        arrays = {}
    else:
        from scenes import render_scene

        render = render_scene(case.scene, preset=config.preset, f_number=config.f_number, seed=config.render_seed,
                              progress=False)
        image = render.image(encoding="srgb", quantize_bits=config.quantize_bits)
        gt = np.asarray(render.sigma_px, dtype=np.float64)
        res, out, timings = _run(image, config, params)
        regions = region_masks(image, gt, edges=res.edges, exclude=render.occlusion_boundary,
                               texture_threshold=config.texture_threshold)
        dm = dense_metrics(res.defocus_map, gt, regions=regions)
        metrics = {**{f"{r}_{k}": dm[r][k] for r in dm for k in ("mae", "bias")},
                   **{f"rtf_{k}": v for k, v in rtf_normalized_errors(res.defocus_map, gt, mask=regions["all"]).items()
                      if k != "n"},
                   **_map_stats(res), "sigma_gt_range_px": {"min": float(np.nanmin(gt)), "max": float(np.nanmax(gt))}}
        arrays = {"gt": gt.astype(np.float32), "occlusion": render.occlusion_boundary}
    arrays.update({"input": image.astype(np.float32), "map": res.defocus_map.astype(np.float32),
                   "magnified": out.astype(np.float32), "sparse": res.sparse_sigma.astype(np.float32)})
    return {"arrays": arrays, "metrics": metrics, "info": {"shape": list(image.shape[:2]), "timings": timings}}


#: Scene metrics averaged over a scene set (the report's and the plot's summary).
SUMMARY_KEYS = ("all_mae", "all_bias", "textured_mae", "edges_mae", "rtf_nmae", "rtf_nmse")


FIGURE = Figure(
    name="fig11", plot="experiments.plotting.fig11:plot", configs={"quick": QUICK, "full": FULL},
    cases_fn=cases, case_fn=compute_case, version=4,
    title="Results gallery: input, defocus map, magnified result (renders with MAE; skimage.data photos)",
)
