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
8. Method presets (``config.presets``, the first ``"paper"``): steps 2–7 with each preset's map
   (renders and the oracle results shared); further presets under ``metrics["presets"][name]``.
9. Scene sets: steps 1–8 on the default set's scene (``scene_set``, flat keys) and on each of
   ``other_scene_sets`` (its own scene, D2 and click; ``metrics["scene_sets"][name]``, with its own
   ``"presets"``; arrays ``<set>__<key>``).
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "FULL", "QUICK", "Fig8Config", "compute", "virtual_focus_map"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig8Config:
    """Every parameter of Fig. 8."""

    scene: str = "portrait"
    # scene rendered at both focus distances (portrait: figure at 0.25 m, cat photo at 1.5 m,
    # shelf at 0.6 m, foreground card at 0.125 m); in ``scene_set``.
    scene_set: str = "tabletop_stress"
    # name of the scenes.SCENE_SETS entry ``scene`` belongs to (the flat metrics describe it).
    other_scene_sets: tuple = (("paper_cameras", (("scene", "portrait_garden"), ("focus_distance_2_m", 10.0),
                                                  ("focus_point_xy", (0.8, 0.15)))),)
    # further scene sets: (set name, ((config field, value), ...)) overrides of ``scene``,
    # ``focus_distance_2_m`` and ``focus_point_xy`` (portrait_garden: person at 2 m, refocused to the
    # brick house at 10 m, clicked on it at the top right); metrics["scene_sets"][name], arrays "<name>__<key>".
    presets: tuple[str, ...] = ("paper", "robust")
    # method parameter presets (method.PRESETS) whose maps are refocused; the first is "paper"
    # (= DefocusParams(), the top-level metrics), the others go to metrics["presets"][name]
    # (not to be confused with the render `preset`).
    preset: str = "full"
    # render preset: "small" (160x120 px) or "full" (640x480 px).
    f_number: float = 4.0
    # N of both renders (same aperture; only the focus changes).
    focus_distance_2_m: float = 1.5
    # D2, the distance to refocus to, m (portrait: the background photo; D1 is the scene's default).
    focus_point_xy: tuple[float, float] = (0.15, 0.3)
    # the "click" on the region to bring into focus: (x, y) as fractions of width and height from
    # the top-left corner (portrait: the background, left of the figure).
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


def compute(config: Fig8Config) -> dict:
    """Refocusing experiment (see the module Notes) for every preset and scene set.

    Parameters
    ----------
    config : Fig8Config

    Returns
    -------
    dict
        HxW(x3) float32 arrays ``image_d1``, ``image_d2``, ``image_pinhole``, ``map_estimated`` (B, px),
        ``virtual_map_estimated``, ``gt_d1``, ``gt_d2``, ``gt_pinhole`` (σ, px), ``deconvolved_estimated``,
        ``deconvolved_oracle``, ``refocused_estimated``, ``refocused_estimated_oracle_virtual``,
        ``refocused_oracle``; bool ``mask`` (outside occlusion bands) and ``in_focus_d2``;
        ``focus_point_px`` (x, y); and ``metrics``: ``images_vs_d2.<image>.{psnr_db, ssim,
        psnr_in_focus_db, ssim_in_focus}``, ``deconvolution_vs_pinhole.<image>.{psnr_db, ssim,
        psnr_no_occlusion_db}``, ``virtual_map_vs_gt_d2.<map>.<region>.{mae, bias}``, ``nsr_sweep.nsr=<λ>.*_psnr_db``, ``sigma_t_px``,
        ``map_floor_px``, ``click_depth_m``, pixel counts, timings — the paper preset on the default
        scene set; ``presets.<P>`` the same keys for preset P (its map: ``<P>__map_estimated``,
        ``<P>__virtual_map_estimated``, ``<P>__deconvolved_estimated``, ``<P>__refocused_estimated``);
        ``scene_set``; ``scene_sets.<set>`` the same for each further set (arrays ``<set>__<key>``).
    """
    from .fig6_alpha_sweep import method_presets
    from .scene_sets import scene_set_configs

    presets = method_presets(config.presets)
    sets = scene_set_configs(config)
    data = metrics = None
    nested = {}
    for set_name, cfg in sets:
        arrays, m = _compute_set(cfg, presets)
        m["scene_set"] = set_name
        if data is None:
            data, metrics = arrays, m
        else:
            nested[set_name] = m
            data.update({f"{set_name}__{k}": v for k, v in arrays.items()})
    metrics["scene_sets"] = nested
    data["metrics"] = metrics
    return data


def _compute_set(config: Fig8Config, presets: dict) -> tuple[dict, dict]:
    """Renders of ``config.scene`` and the refocusing of every preset's map: (arrays, metrics)."""
    from method.magnify.refocusing import deconvolve_defocus, refocus
    from scenes import SCENES, render_scene
    from scenes.render import FILTER_SIGMA_PX

    t_start = time.perf_counter()
    scene = SCENES[config.scene]

    def render(f_number, **changes):
        cam = scene.camera(config.preset, f_number=f_number, **changes)
        return render_scene(config.scene, camera=cam, preset=config.preset, seed=config.render_seed, progress=False)

    r1 = render(config.f_number)
    # same field of view at D2: scale the sensor by v2/v1 (lens-sensor distances), see the module docstring
    cam1 = scene.camera(config.preset, f_number=config.f_number)
    v_ratio = (scene.camera(config.preset, f_number=config.f_number, focus_distance_m=config.focus_distance_2_m)
               .lens_sensor_distance_m / cam1.lens_sensor_distance_m)
    r2 = render(config.f_number, focus_distance_m=config.focus_distance_2_m,
                sensor_width_mm=cam1.sensor_width_mm * v_ratio, sensor_height_mm=cam1.sensor_height_mm * v_ratio)
    rp = render(config.all_in_focus_f_number)
    img1, img2, imgp = (r.image(encoding=config.encoding, quantize_bits=config.quantize_bits) for r in (r1, r2, rp))
    gt1, gt2, gtp = (np.asarray(r.sigma_px, dtype=np.float64) for r in (r1, r2, rp))
    finite = np.isfinite(gt1) & np.isfinite(gt2) & np.isfinite(gtp)
    gt1, gt2, gtp = (np.where(finite, g, 0.0) for g in (gt1, gt2, gtp))
    mask = finite & ~r1.occlusion_boundary & ~r2.occlusion_boundary
    sf = FILTER_SIGMA_PX
    in_focus = mask & (np.sqrt(np.maximum(gt2**2 - sf**2, 0.0)) <= config.in_focus_sigma_px)
    t_renders = time.perf_counter() - t_start

    opts = {"method": config.deconvolution, "nsr": config.nsr}
    oracle_deblur = np.sqrt(np.maximum(gt1**2 - gtp**2, 0.0))
    refocused_oracle = refocus(img1, gt1, gt2, kernel=config.kernel, **opts)
    deconv_oracle = deconvolve_defocus(img1, oracle_deblur, **opts)
    h, w = img1.shape[:2]
    click = (round(config.focus_point_xy[0] * (w - 1)), round(config.focus_point_xy[1] * (h - 1)))
    r_win = max(1, round(config.focus_window_frac * max(h, w)))
    win = np.s_[max(click[1] - r_win, 0):click[1] + r_win + 1, max(click[0] - r_win, 0):click[0] + r_win + 1]
    shared = {"config": config, "img1": img1, "img2": img2, "imgp": imgp, "gt1": gt1, "gt2": gt2, "gtp": gtp,
              "mask": mask, "in_focus": in_focus, "occl_p": rp.occlusion_boundary, "opts": opts,
              "oracle_deblur": oracle_deblur, "refocused_oracle": refocused_oracle, "deconv_oracle": deconv_oracle}
    common = {
        "click_depth_m": float(np.median(np.asarray(r1.depth)[win])),
        "focus_distance_1_m": float(scene.focus_distance_m),
        "focus_distance_2_m": float(config.focus_distance_2_m),
        "gt_range_px": {"d1": [float(gt1.min()), float(gt1.max())], "d2": [float(gt2.min()), float(gt2.max())],
                        "pinhole": [float(gtp.min()), float(gtp.max())]},
        "nonfinite_gt_pixels": int((~finite).sum()),
        "evaluated_pixels": int(mask.sum()),
        "in_focus_d2_pixels": int(in_focus.sum()),
    }
    names = list(presets)
    per_preset = {}
    for pname in names:
        t0 = time.perf_counter()
        p_arrays, p_metrics = _refocus_one(shared, presets[pname])
        p_metrics.update(common)
        p_metrics["compute_seconds"] = time.perf_counter() - t0 + (t_renders if pname == names[0] else 0.0)
        per_preset[pname] = (p_arrays, p_metrics)
    arrays, metrics = per_preset[names[0]]
    metrics["presets"] = {p: per_preset[p][1] for p in names[1:]}
    arrays = {
        "image_d1": img1, "image_d2": img2, "image_pinhole": imgp,
        "gt_d1": gt1, "gt_d2": gt2, "gt_pinhole": gtp,
        "deconvolved_oracle": deconv_oracle, "refocused_oracle": refocused_oracle, **arrays,
    }
    data = {k: np.asarray(a, dtype=np.float32) for k, a in arrays.items()}
    for p in names[1:]:
        data.update({f"{p}__{k}": np.asarray(a, dtype=np.float32) for k, a in per_preset[p][0].items()})
    data["mask"] = mask
    data["in_focus_d2"] = in_focus
    data["focus_point_px"] = np.asarray(click, dtype=np.int64)
    return data, metrics


def _refocus_one(shared: dict, params) -> tuple[dict, dict]:
    """Steps 2–7 of the module Notes with one preset's map: (its arrays, its metrics)."""
    from method import estimate_defocus_map, preprocess_defocus_map
    from method.magnify.refocusing import deconvolve_defocus, refocus

    from .metrics import dense_metrics, image_quality

    config = shared["config"]
    img1, img2, imgp, gt1, gt2 = (shared[k] for k in ("img1", "img2", "imgp", "gt1", "gt2"))
    mask, in_focus, opts = shared["mask"], shared["in_focus"], shared["opts"]
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        est = estimate_defocus_map(img1, params).defocus_map
    t_est = time.perf_counter() - t0
    b = preprocess_defocus_map(est, clip_percent=params.map_clip_percent, smoothing=params.map_smoothing,
                               floor="clamp")
    floor_px = max(float(np.percentile(est, params.map_clip_percent)), 0.0)
    virtual, sigma_t = virtual_focus_map(b, config.focus_point_xy, window_frac=config.focus_window_frac,
                                         floor_px=floor_px)
    t0 = time.perf_counter()
    refocused_est = refocus(img1, b, virtual, kernel=config.kernel, **opts)
    t_refocus = time.perf_counter() - t0
    refocused_est_ov = refocus(img1, b, gt2, kernel=config.kernel, **opts)
    deconv_est = deconvolve_defocus(img1, b, **opts)

    results = {
        "unchanged_d1": img1,
        "refocused_estimated": refocused_est,
        "refocused_estimated_oracle_virtual": refocused_est_ov,
        "refocused_oracle": shared["refocused_oracle"],
    }
    vs_d2 = {}
    for name, im in results.items():
        q = image_quality(im, img2)
        q["psnr_in_focus_db"] = _masked_psnr(im, img2, in_focus)
        q["ssim_in_focus"] = _masked_ssim(im, img2, in_focus)
        vs_d2[name] = q
    deconv = {}
    for name, im in (("unchanged_d1", img1), ("deconvolved_estimated", deconv_est),
                     ("deconvolved_oracle", shared["deconv_oracle"])):
        q = image_quality(im, imgp)
        q["psnr_no_occlusion_db"] = _masked_psnr(im, imgp, mask & ~shared["occl_p"])
        deconv[name] = q
    sweep = []
    for lam in config.nsr_sweep:
        o = {"method": config.deconvolution, "nsr": lam}
        sweep.append({
            "nsr": float(lam),
            "refocused_estimated_psnr_db": image_quality(refocus(img1, b, virtual, kernel=config.kernel, **o), img2)["psnr_db"],
            "refocused_oracle_psnr_db": image_quality(refocus(img1, gt1, gt2, kernel=config.kernel, **o), img2)["psnr_db"],
            "deconvolved_estimated_psnr_db": image_quality(deconvolve_defocus(img1, b, **o), imgp)["psnr_db"],
            "deconvolved_oracle_psnr_db": image_quality(
                deconvolve_defocus(img1, shared["oracle_deblur"], **o), imgp)["psnr_db"],
        })
    regions = {"all": mask, "in_focus_d2": in_focus}
    vmaps = {name: dense_metrics(m, gt2, regions=regions) for name, m in
             (("estimated", virtual), ("d1_map_unchanged", b))}
    vmaps = {name: {reg: {"mae": v["mae"], "bias": v["bias"]} for reg, v in d.items()} for name, d in vmaps.items()}
    metrics = {
        "images_vs_d2": vs_d2,
        "deconvolution_vs_pinhole": deconv,
        "virtual_map_vs_gt_d2": vmaps,
        "nsr_sweep": {f"nsr={row['nsr']:g}": row for row in sweep},
        "sigma_t_px": sigma_t,
        "map_floor_px": floor_px,
        "estimate_seconds": t_est,
        "refocus_seconds": t_refocus,
    }
    arrays = {"map_estimated": b, "virtual_map_estimated": virtual, "deconvolved_estimated": deconv_est,
              "refocused_estimated": refocused_est, "refocused_estimated_oracle_virtual": refocused_est_ov}
    return arrays, metrics


FIGURE = Figure(
    name="fig8",
    title="Refocusing: deconvolve a render focused at D1 with its map, re-blur to focus at D2, vs the real D2 render",
    compute=compute,
    plot="experiments.plotting.fig8:plot",
    configs={"quick": QUICK, "full": FULL},
    version=2,  # 2: every preset of ``presets`` and every scene set
)
