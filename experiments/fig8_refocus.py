"""Fig. 8: refocusing — deconvolve a render with its defocus map, re-blur with a virtual-focus map.

The paper deconvolves a photo with its estimated defocus map and applies lens blur "as if the
foreground is focused" (Fig. 8, no numbers). Here one scene is rendered at f/N focused at its
default distance D1 (the input) and the SAME scene, camera, f-number and seed focused at D2 (the
reference a real refocus would produce), so the refocused input can be scored against it.

Same pixel grid at both focus distances
---------------------------------------
Refocusing a thin lens moves the sensor (lens-sensor distance v = fD/(D − f)), so with a fixed
sensor the field of view changes ("focus breathing": portrait, D 0.25 → 1.5 m, v 62.5 → 51.7 mm,
the image shrinks by 17 %) and the two renders are not pixel-aligned. The D2 camera's sensor is
therefore scaled by v2/v1: the field of view, hence the pixel grid, is D1's, and a pixel's angular
blur A·|1/D − 1/S| maps to σ px with the same constant at both focus distances.

Virtual-focus maps
------------------
* ``oracle`` virtual map: σ_gt of the D2 render (what a camera focused at D2 produces; needs depth).
* ``estimated`` virtual map (the paper's setting: no depth, only the map). For a thin lens the
  defocus-only σ is proportional to |1/D − 1/S| (S the depth; Eq. 5 with c = 4σ), the same constant
  for every focus distance at a fixed aperture. For every point on the SAME side of D1 as the new
  focal plane (here: behind it), σ_d(D2) = |σ_d(D1) − σ_t| with σ_t the D1 blur of the new focal
  plane — exact, no depth needed. Points on the other side of D1 get |σ_d − σ_t| instead of
  σ_d + σ_t (too little blur): the map cannot tell front from back, so this is an APPROXIMATION
  that inverts the map's ordering around σ_t. σ_t is "clicked": the median estimated σ_d in a
  small window at ``focus_point_xy`` (a point on the plane to bring into focus, as a user would
  pick it; no depth is read). The estimated map's in-focus floor p_lo (its lower-percentile value:
  edge-blur estimates of sharp texture are ≈ 0.5–1 px, not 0) is removed in quadrature before and
  restored after: σ_d = √(max(B² − p_lo², 0)), virtual σ = √((σ_d − σ_t)² + p_lo²).

Notes
-----
1. Render at f/``f_number`` focused at D1 (the scene's default) and at D2 = ``focus_distance_2_m``,
   and at f/``all_in_focus_f_number`` focused at D1 (near-pinhole: the all-in-focus reference of
   the deconvolution). Images: ``render.image(encoding, quantize_bits)``.
2. Estimate the D1 map (:func:`method.estimate_defocus_map` with the preset's parameters; the
   ``paper`` preset = the paper's defaults) and prepare it as Sec. 5 does
   (:func:`method.preprocess_defocus_map` with the preset's ``map_clip_percent`` and ``map_smoothing``,
   paper: clip 5 %, smooth 0.5 %; clamp at 0) → B.
3. Results (:func:`method.refocus`, ``deconvolution`` filter with λ = ``nsr``, Gaussian re-blur):
   ``refocused_estimated`` (deconvolve with B, re-blur with the estimated virtual map — the paper's
   method), ``refocused_estimated_oracle_virtual`` (deconvolve with B, re-blur with σ_gt(D2): isolates
   the virtual-map approximation) and ``refocused_oracle`` (deconvolve with σ_gt(D1), re-blur with
   σ_gt(D2): isolates the deconvolution/re-blur approximation; an upper bound in spirit, not a
   guaranteed one, since regularised deconvolution is not an exact inverse).
4. Image metrics against the real D2 render (PSNR dB, SSIM): those results and the unchanged D1
   render (lower bound), over all pixels, and over the pixels in focus at D2 (defocus-only
   σ_d(D2) ≤ ``in_focus_sigma_px``, outside the occlusion bands of both renders; SSIM = mean of the
   SSIM map there).
5. Deconvolution quality against the near-pinhole render: D1 deconvolved with B and with the oracle
   √(max(σ_gt(D1)² − σ_gt(pinhole)², 0)) (the blur the pinhole render does not have), and the
   unchanged D1 render; all pixels and outside occlusion bands.
6. Sensitivity to λ: the PSNRs of step 4 (whole image) and 5 for each λ of ``nsr_sweep``.
7. Virtual-map error against σ_gt(D2) (MAE/bias, px) outside occlusion bands, and the depth at the
   click (checked to lie on the D2 plane).
8. Cases (:func:`cases`): per scene set of ``config.scene_sets`` (its scene, D2 and click) a ``stage``
   case (step 1, the oracle results of steps 3 and 5 and their rows), per preset a ``map`` case (step 2,
   the virtual map and step 7) and, needing both, one case per λ of the sweep (step 6; at λ =
   ``config.nsr`` also steps 3–5 with the preset's map).
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "FULL", "QUICK", "Fig8Config", "cases", "compute_case", "virtual_focus_map"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig8Config:
    """Every parameter of Fig. 8."""

    scene_sets: tuple = (("tabletop_stress", "portrait", 1.5, (0.15, 0.3)),
                         ("paper_cameras", "portrait_garden", 10.0, (0.8, 0.15)))
    # per scene set (the first the default): (set name, scene rendered at both focus distances, D2 = the
    # distance to refocus to in m, the "click" on the region to bring into focus as (x, y) fractions of
    # width and height from the top-left corner). portrait: figure at 0.25 m, cat photo at 1.5 m, shelf
    # at 0.6 m, foreground card at 0.125 m, refocused to the photo, clicked on the background left of the
    # figure; portrait_garden: person at 2 m, refocused to the brick house at 10 m, clicked on it.
    presets: tuple[str, ...] = ("paper", "robust")
    # method parameter presets (method.PRESETS) whose maps are refocused, each its own cases (not to be
    # confused with the render `preset`).
    preset: str = "full"
    # render preset: "small" (160x120 px) or "full" (640x480 px).
    f_number: float = 4.0
    # N of both renders (same aperture; only the focus changes).
    focus_window_frac: float = 0.03
    # half-side of the square window around the click whose median estimated σ_d is σ_t, as a
    # fraction of max(H, W).
    all_in_focus_f_number: float = 64.0
    # N of the near-pinhole render used as the all-in-focus reference of the deconvolution.
    encoding: str = "srgb"
    # encoding of the images the method sees and that are compared.
    quantize_bits: int = 8
    # bits per channel of the images (8 = JPEG-like).
    deconvolution: str = "wiener"
    # deconvolution filter (method.magnify.refocusing.DECONVOLUTION_METHODS).
    nsr: float = 1e-2
    # regularisation λ of the deconvolution filter (noise-to-signal power ratio, dimensionless;
    # method.magnify.refocusing.DEFAULT_NSR, chosen there — not tuned on this figure's metrics).
    nsr_sweep: tuple[float, ...] = (1e-3, 3e-3, 1e-2, 3e-2, 1e-1)
    # λ values of the sensitivity sweep reported next to the main result (PSNR only).
    kernel: str = "gaussian"
    # re-blur kernel (method.MAGNIFICATION_KERNELS).
    in_focus_sigma_px: float = 0.5
    # pixels whose defocus-only σ at D2 is ≤ this are "in focus at D2", px.
    render_seed: int = 0
    # Mitsuba sampler seed (same for all renders).


FULL = Fig8Config()
QUICK = Fig8Config(preset="small")


def virtual_focus_map(defocus_map, focus_point_xy, *, window_frac, floor_px) -> tuple[np.ndarray, float]:
    """Virtual-focus σ map from a defocus map alone, by inverting its ordering around a clicked value.

    Parameters
    ----------
    defocus_map : ndarray, HxW, float ≥ 0
        Prepared defocus map B, px.
    focus_point_xy : (float, float)
        Point on the region to bring into focus, fractions of (width, height) from the top-left.
    window_frac : float, keyword-only
        Half-side of the window around the point, fraction of max(H, W).
    floor_px : float, keyword-only
        The map's in-focus floor p_lo ≥ 0, px (removed and restored in quadrature).

    Returns
    -------
    (ndarray, float)
        Virtual map √((σ_d − σ_t)² + p_lo²), px, with σ_d = √(max(B² − p_lo², 0)); and σ_t, px.
        Exact (up to map error) for points on the same side of the old focal plane as the new one;
        points on the other side get |σ_d − σ_t| instead of σ_d + σ_t (see the module docstring).
    """
    x, y = focus_point_xy
    if not (0.0 <= x <= 1.0 and 0.0 <= y <= 1.0):
        raise ValueError(f"focus_point_xy={focus_point_xy!r} is invalid; allowed: fractions in [0, 1]")
    h, w = defocus_map.shape
    sd = np.sqrt(np.maximum(defocus_map**2 - floor_px**2, 0.0))
    cy, cx = round(y * (h - 1)), round(x * (w - 1))
    r = max(1, round(window_frac * max(h, w)))
    sigma_t = float(np.median(sd[max(cy - r, 0):cy + r + 1, max(cx - r, 0):cx + r + 1]))
    return np.sqrt((sd - sigma_t) ** 2 + floor_px**2), sigma_t


def _masked_psnr(test, reference, mask):
    """PSNR (dB, peak 1) over the pixels of ``mask`` (HxW bool; all channels); NaN if empty, inf if equal."""
    if not mask.any():
        return float("nan")
    mse = float(np.mean((np.asarray(test, np.float64)[mask] - np.asarray(reference, np.float64)[mask]) ** 2))
    return float("inf") if mse == 0 else float(10.0 * np.log10(1.0 / mse))


def _masked_ssim(test, reference, mask):
    """Mean of scikit-image's SSIM map over ``mask`` (NaN if empty)."""
    from skimage.metrics import structural_similarity

    if not mask.any():
        return float("nan")
    _, smap = structural_similarity(np.asarray(reference, np.float64), np.asarray(test, np.float64), data_range=1.0,
                                    channel_axis=-1, full=True)
    return float(smap.mean(axis=-1)[mask].mean())


def cases(config: Fig8Config) -> tuple:
    """Per scene set: a ``stage`` case (the renders and the oracle results), one ``map`` case per preset
    (its estimated and virtual maps) and, needing both, one case per λ of ``nsr_sweep`` (and ``nsr``)."""
    from .cases import Case, method_presets
    from .scene_sets import check_scene_sets

    check_scene_sets([(s, (scene,)) for s, scene, _, _ in config.scene_sets])
    presets = method_presets(config.presets)
    lams = tuple(dict.fromkeys([*config.nsr_sweep, config.nsr]))
    out = []
    for set_name, scene, _, _ in config.scene_sets:
        ids = dict(scene_set=set_name, scene=scene, aperture=float(config.f_number), encoding=config.encoding,
                   scene_size=config.preset)
        stage = Case("fig8", variant="stage", **ids)
        out.append(stage)
        for p in presets:
            mcase = Case("fig8", preset=p, variant="map", needs=(stage,), **ids)
            out.append(mcase)
            out += [Case("fig8", preset=p, variant=f"nsr={lam:g}", needs=(stage, mcase), **ids) for lam in lams]
    return tuple(out)


def _set_fields(config, set_name) -> tuple[str, float, tuple]:
    """(scene, D2 in m, click) of a scene set of ``config.scene_sets``."""
    return next((scene, d2, click) for s, scene, d2, click in config.scene_sets if s == set_name)


def compute_case(config: Fig8Config, case, inputs) -> dict:
    """One case of :func:`cases` (see the module Notes).

    Returns
    -------
    dict
        ``stage``: arrays ``image_d1``, ``image_d2``, ``image_pinhole`` (HxWx3), ``gt_d1``, ``gt_d2``,
        ``gt_pinhole``, ``oracle_deblur`` (σ px), ``refocused_oracle``, ``deconvolved_oracle``, bool
        ``mask``, ``in_focus_d2``, ``occlusion_pinhole``, ``focus_point_px`` (x, y); metrics
        ``images_vs_d2`` / ``deconvolution_vs_pinhole`` of the unchanged and oracle images, the click depth,
        focus distances, σ_gt ranges and pixel counts. ``map``: arrays ``map_estimated`` (B, px) and
        ``virtual_map_estimated`` (px); metrics ``sigma_t_px``, ``map_floor_px``, ``virtual_map_vs_gt_d2``.
        ``nsr=<λ>``: metrics ``nsr`` and the four PSNRs of the λ sweep; at λ = ``config.nsr`` also the
        estimated-map rows of ``images_vs_d2`` / ``deconvolution_vs_pinhole`` and arrays
        ``deconvolved_estimated``, ``refocused_estimated``, ``refocused_estimated_oracle_virtual``.
    """
    if case.variant == "stage":
        return _stage(config, case)
    if case.variant == "map":
        return _map_case(config, case, inputs[case.needs[0]].arrays())
    stage, mcase = case.needs
    lam = float(case.variant.split("=", 1)[1])
    return _refocus_case(config, inputs[stage].arrays(), inputs[mcase].arrays(), lam)


def _stage(config: Fig8Config, case) -> dict:
    """Renders of the set's scene at D1, D2 and the near-pinhole aperture, and the oracle results."""
    from method.magnify.refocusing import deconvolve_defocus, refocus
    from scenes import SCENES, render_scene
    from scenes.render import FILTER_SIGMA_PX

    scene_name, d2_m, click_xy = _set_fields(config, case.scene_set)
    scene = SCENES[scene_name]

    def render(f_number, **changes):
        cam = scene.camera(config.preset, f_number=f_number, **changes)
        return render_scene(scene_name, camera=cam, preset=config.preset, seed=config.render_seed, progress=False)

    r1 = render(config.f_number)
    # same field of view at D2: scale the sensor by v2/v1 (lens-sensor distances), see the module docstring
    cam1 = scene.camera(config.preset, f_number=config.f_number)
    v_ratio = (scene.camera(config.preset, f_number=config.f_number, focus_distance_m=d2_m)
               .lens_sensor_distance_m / cam1.lens_sensor_distance_m)
    r2 = render(config.f_number, focus_distance_m=d2_m,
                sensor_width_mm=cam1.sensor_width_mm * v_ratio, sensor_height_mm=cam1.sensor_height_mm * v_ratio)
    rp = render(config.all_in_focus_f_number)
    img1, img2, imgp = (r.image(encoding=config.encoding, quantize_bits=config.quantize_bits) for r in (r1, r2, rp))
    gt1, gt2, gtp = (np.asarray(r.sigma_px, dtype=np.float64) for r in (r1, r2, rp))
    finite = np.isfinite(gt1) & np.isfinite(gt2) & np.isfinite(gtp)
    gt1, gt2, gtp = (np.where(finite, g, 0.0) for g in (gt1, gt2, gtp))
    mask = finite & ~r1.occlusion_boundary & ~r2.occlusion_boundary
    sf = FILTER_SIGMA_PX
    in_focus = mask & (np.sqrt(np.maximum(gt2**2 - sf**2, 0.0)) <= config.in_focus_sigma_px)
    opts = {"method": config.deconvolution, "nsr": config.nsr}
    oracle_deblur = np.sqrt(np.maximum(gt1**2 - gtp**2, 0.0))
    refocused_oracle = refocus(img1, gt1, gt2, kernel=config.kernel, **opts)
    deconv_oracle = deconvolve_defocus(img1, oracle_deblur, **opts)
    h, w = img1.shape[:2]
    click = (round(click_xy[0] * (w - 1)), round(click_xy[1] * (h - 1)))
    r_win = max(1, round(config.focus_window_frac * max(h, w)))
    win = np.s_[max(click[1] - r_win, 0):click[1] + r_win + 1, max(click[0] - r_win, 0):click[0] + r_win + 1]
    arrays = {"image_d1": img1, "image_d2": img2, "image_pinhole": imgp, "gt_d1": gt1, "gt_d2": gt2,
              "gt_pinhole": gtp, "oracle_deblur": oracle_deblur, "refocused_oracle": refocused_oracle,
              "deconvolved_oracle": deconv_oracle, "mask": mask, "in_focus_d2": in_focus,
              "occlusion_pinhole": np.asarray(rp.occlusion_boundary, dtype=bool),
              "focus_point_px": np.asarray(click, dtype=np.int64)}
    metrics = {
        "images_vs_d2": {name: _vs_d2(im, img2, in_focus) for name, im in
                         (("unchanged_d1", img1), ("refocused_oracle", refocused_oracle))},
        "deconvolution_vs_pinhole": {name: _vs_pinhole(im, imgp, mask & ~arrays["occlusion_pinhole"]) for name, im in
                                     (("unchanged_d1", img1), ("deconvolved_oracle", deconv_oracle))},
        "click_depth_m": float(np.median(np.asarray(r1.depth)[win])),
        "focus_distance_1_m": float(scene.focus_distance_m),
        "focus_distance_2_m": float(d2_m),
        "gt_range_px": {"d1": [float(gt1.min()), float(gt1.max())], "d2": [float(gt2.min()), float(gt2.max())],
                        "pinhole": [float(gtp.min()), float(gtp.max())]},
        "nonfinite_gt_pixels": int((~finite).sum()),
        "evaluated_pixels": int(mask.sum()),
        "in_focus_d2_pixels": int(in_focus.sum()),
    }
    return {"arrays": arrays, "metrics": metrics}


def _vs_d2(im, img2, in_focus) -> dict:
    from .metrics import image_quality

    q = image_quality(im, img2)
    q["psnr_in_focus_db"] = _masked_psnr(im, img2, in_focus)
    q["ssim_in_focus"] = _masked_ssim(im, img2, in_focus)
    return q


def _vs_pinhole(im, imgp, keep) -> dict:
    from .metrics import image_quality

    q = image_quality(im, imgp)
    q["psnr_no_occlusion_db"] = _masked_psnr(im, imgp, keep)
    return q


def _map_case(config: Fig8Config, case, stage: dict) -> dict:
    """Steps 2 and 7 of the module Notes with one preset: its prepared map B, the virtual map, their errors."""
    from method import DefocusParams, estimate_defocus_map, preprocess_defocus_map

    from .metrics import dense_metrics

    params = DefocusParams.preset(case.preset)
    _, _, click_xy = _set_fields(config, case.scene_set)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        est = estimate_defocus_map(stage["image_d1"], params, encoding=config.encoding).defocus_map
    t_est = time.perf_counter() - t0
    b = preprocess_defocus_map(est, clip_percent=params.map_clip_percent, smoothing=params.map_smoothing,
                               floor="clamp")
    floor_px = max(float(np.percentile(est, params.map_clip_percent)), 0.0)
    virtual, sigma_t = virtual_focus_map(b, click_xy, window_frac=config.focus_window_frac, floor_px=floor_px)
    regions = {"all": stage["mask"], "in_focus_d2": stage["in_focus_d2"]}
    vmaps = {name: dense_metrics(m, stage["gt_d2"], regions=regions) for name, m in
             (("estimated", virtual), ("d1_map_unchanged", b))}
    vmaps = {name: {reg: {"mae": v["mae"], "bias": v["bias"]} for reg, v in d.items()} for name, d in vmaps.items()}
    return {"arrays": {"map_estimated": b, "virtual_map_estimated": virtual},
            "metrics": {"virtual_map_vs_gt_d2": vmaps, "sigma_t_px": sigma_t, "map_floor_px": floor_px},
            "info": {"estimate_seconds": t_est}}


def _refocus_case(config: Fig8Config, stage: dict, maps: dict, lam: float) -> dict:
    """Steps 3–6 of the module Notes at one λ with one preset's maps (all rows at λ = ``config.nsr``)."""
    from method.magnify.refocusing import deconvolve_defocus, refocus

    from .metrics import image_quality

    img1, img2, imgp, gt1, gt2 = (stage[k] for k in ("image_d1", "image_d2", "image_pinhole", "gt_d1", "gt_d2"))
    b, virtual = maps["map_estimated"], maps["virtual_map_estimated"]
    o = {"method": config.deconvolution, "nsr": lam}
    refocused_est = refocus(img1, b, virtual, kernel=config.kernel, **o)
    deconv_est = deconvolve_defocus(img1, b, **o)
    metrics = {
        "nsr": float(lam),
        "refocused_estimated_psnr_db": image_quality(refocused_est, img2)["psnr_db"],
        "refocused_oracle_psnr_db": image_quality(refocus(img1, gt1, gt2, kernel=config.kernel, **o), img2)["psnr_db"],
        "deconvolved_estimated_psnr_db": image_quality(deconv_est, imgp)["psnr_db"],
        "deconvolved_oracle_psnr_db": image_quality(deconvolve_defocus(img1, stage["oracle_deblur"], **o),
                                                    imgp)["psnr_db"],
    }
    if lam != config.nsr:
        return {"metrics": metrics}
    refocused_est_ov = refocus(img1, b, gt2, kernel=config.kernel, **o)
    keep = stage["mask"] & ~stage["occlusion_pinhole"]
    metrics["images_vs_d2"] = {name: _vs_d2(im, img2, stage["in_focus_d2"]) for name, im in
                               (("refocused_estimated", refocused_est),
                                ("refocused_estimated_oracle_virtual", refocused_est_ov))}
    metrics["deconvolution_vs_pinhole"] = {"deconvolved_estimated": _vs_pinhole(deconv_est, imgp, keep)}
    arrays = {"deconvolved_estimated": deconv_est, "refocused_estimated": refocused_est,
              "refocused_estimated_oracle_virtual": refocused_est_ov}
    return {"arrays": {k: v.astype(np.float32) for k, v in arrays.items()}, "metrics": metrics}


FIGURE = Figure(
    name="fig8",
    title="Refocusing: deconvolve a render focused at D1 with its map, re-blur to focus at D2, vs the real D2 render",
    plot="experiments.plotting.fig8:plot",
    configs={"quick": QUICK, "full": FULL},
    cases_fn=cases, case_fn=compute_case, version=3,
)
