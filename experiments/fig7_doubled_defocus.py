"""Fig. 7: doubled defocus — an f/8 render magnified ×2 against the real f/4 render of the same scene.

The paper photographs one scene at f/8 and f/4 and shows that (a) twice the f/8 defocus map
resembles the f/4 map and (b) magnifying the f/8 photo's defocus by 2 resembles the f/4 photo.
Here both apertures are rendered with the same camera, seed and scene, so both claims are measured.

Ground truth and the "upper bound"
----------------------------------
σ_gt = √(σ_d² + σ_f²) with σ_d = c/4 the defocus (line-spread) σ and σ_f = 1/√12 px the box pixel
filter. Halving the f-number doubles c, hence σ_d, but not σ_f:
σ_gt(f/4) = √(4·σ_d(f/8)² + σ_f²) ≠ 2·σ_gt(f/8). The magnification adds a Gaussian of
σ_e = √(k² − 1)·B (k = 2) to every pixel; with B = σ_d(f/8) this is exactly the blur the f/4 lens
adds on top of the f/8 one (√(4σ_d² − σ_d²) = √3·σ_d, both renders share σ_f). Passing σ_gt instead
would also "double" the filter blur and over-blur in-focus pixels by √3·σ_f ≈ 0.5 px. So the upper
bound magnifies with the oracle map B = σ_d(f/8) = √(σ_gt² − σ_f²), without the Sec. 5 map
preprocessing (the oracle needs no clipping or smoothing), in two versions: ``oracle_srgb`` —
the same operation as the estimated-map result (blur applied to the sRGB-encoded 8-bit image), so it
isolates the map error; ``oracle_linear`` — blur applied to linear radiance, then encoded and
quantised like the renders (physically right: a lens blurs radiance, not sRGB values).

Notes
-----
1. Render each scene at f/``f_number_small_aperture`` and f/``f_number_large_aperture`` (same
   camera otherwise); inputs are ``render.image(encoding, quantize_bits)``.
2. Estimate both defocus maps (:func:`method.estimate_defocus_map`, paper defaults).
3. Map metrics against σ_gt(f/4), over pixels with finite σ_gt outside the occlusion bands of
   *both* renders: the f/8 map, 2 × the f/8 map, the f/4 map, 2 × σ_gt(f/8) (naive doubling) and
   √(4·σ_d(f/8)² + σ_f²) (filter-aware doubling of the truth; ≈ 0 error, a consistency check).
4. Image metrics against the real f/4 render (PSNR dB, SSIM; :func:`experiments.metrics.image_quality`):
   the unchanged f/8 render (lower bound), the f/8 render magnified ×k with the estimated map (the
   paper's result, Sec. 5 preprocessing on), and the oracle upper bounds above. PSNR and SSIM also
   per region: in focus (σ_d(f/4) ≤ ``in_focus_sigma_px``) and defocused, outside occlusion bands —
   the estimated map's in-focus floor (edge blur of sharp texture is estimated ≈ 0.5–1 px, not
   σ_f) makes the magnification over-blur in-focus pixels, which a whole-image PSNR mixes with
   the gain in the defocused regions — and in the occlusion band (the f/4 render's
   ``occlusion_boundary``: within a CoC radius + 1 px of a depth jump), where renderers differ: a
   gather blur spreads a sharp subject over the blurry background behind it and the background over
   the subject's edge, a lens does not. Regional SSIM is the mean of scikit-image's SSIM map
   (averaged over channels) over the region.
5. The preset's own magnification (``magnified_estimated_default``: its ``magnify_renderer`` and
   ``map_floor``, what a user of the preset gets; the gather + ``"clamp"`` row for the paper preset,
   named by the flags ``default_magnification/renderer_<name>`` and ``floor_<mode>``), and the same magnification with the other reading of Sec. 5's "clamp its minimum value to 0"
   (``magnified_estimated_subtract``, ``floor="subtract"`` of :func:`method.magnify_defocus`): the
   map's lower-percentile value p_lo (its in-focus floor, reported as ``map_floor_px``) is removed
   in quadrature before smoothing, so pixels at the floor get no extra blur.
6. Renderers (``config.renderers``; :data:`method.magnify.magnification.MAGNIFICATION_RENDERERS`): the
   first (``"gather"``, the paper preset's path, ``config.kernel``) gives the rows above; every
   further renderer R (``"scatter"``: per-pixel disks of ``config.aperture`` in linear light with
   occlusion layers) the same estimated-map (``floor="clamp"``) and oracle rows as
   ``magnified_estimated_R``, ``magnified_oracle_srgb_R`` (the 8-bit sRGB input, blended in R's
   default light: linear light for the scatter) and ``magnified_oracle_linear_R`` (linear radiance
   in, blended in linear light by every renderer, encoded and quantised like the renders). The oracle
   rows of a renderer that models occlusion are also told what is in front of the focus plane
   (``in_front``: the f/8 render's depth < its focus distance, :attr:`scenes.render_files.Render.in_front`),
   so that with the true map and the true depth order their error is the renderer's alone; the
   estimated rows are not (the method knows no depth).
7. Cases (:func:`cases`): per scene set × scene a ``stage`` case — both renders and the rows that do not
   depend on the method preset (the naive and filter-aware doubled truth, the unchanged f/8 render, the
   oracle magnifications) — and, needing it, one case per preset of ``config.presets`` (steps 2–3, 5 and
   6 with its maps; Sec. 5 preprocessing with its ``map_clip_percent`` / ``map_smoothing``). A value is
   measured once: the preset cases do not repeat the stage's rows.
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "FULL", "QUICK", "Fig7Config", "cases", "compute_case"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fig7Config:
    """Every parameter of Fig. 7."""

    scene_sets: tuple = (("paper_cameras", ("portrait_garden", "heron_at_the_lake")),
                         ("tabletop_stress", ("portrait", "planes")),
                         ("procedural_test", ("procedural_100000", "procedural_100001", "procedural_100002",
                                              "procedural_100003")))
    # (scene set, scenes) pairs (experiments.scene_sets), the first the default; scenes rendered at both
    # apertures, the first of each set plotted. Scenes with large depth differences make the doubling visible.
    preset: str = "full"
    # render preset: "small" (160x120 px) or "full" (640x480 px).
    f_number_small_aperture: float = 8.0
    # N of the input render (the paper's f/8 photo).
    f_number_large_aperture: float = 4.0
    # N of the reference render (the paper's f/4 photo); k = N_small / N_large = 2.
    encoding: str = "srgb"
    # encoding of the images the method sees and that are compared ("srgb" as a camera delivers).
    quantize_bits: int = 8
    # bits per channel of the images (8 = JPEG-like).
    kernel: str = "gaussian"
    # magnification kernel of the gather renderer (method.MAGNIFICATION_KERNELS).
    renderers: tuple[str, ...] = ("gather", "scatter")
    # magnification renderers (method.magnify.magnification.MAGNIFICATION_RENDERERS); the first gives the
    # unsuffixed image rows (the paper's path), each further one R the rows "<row>_R".
    aperture: str = "disk"
    # aperture of the renderers that take one (method.magnify.scatter.APERTURES).
    in_focus_sigma_px: float = 0.5
    # pixels whose defocus-only σ at the large aperture is ≤ this are "in focus" for the per-region
    # PSNR, px (the rest outside occlusion bands is "defocused").
    render_seed: int = 0
    # Mitsuba sampler seed (same for both apertures).
    presets: tuple[str, ...] = ("paper", "robust")
    # method parameter presets (method.PRESETS), one case each per scene (not to be confused with the
    # render `preset`).

    @property
    def factor(self) -> float:
        """Magnification k = N_small / N_large (2 for f/8 → f/4), dimensionless."""
        return self.f_number_small_aperture / self.f_number_large_aperture


FULL = Fig7Config()
#: Quick: small renders, one scene per hand-built set (each set's first) and two of the test split.
QUICK = Fig7Config(preset="small", scene_sets=(("paper_cameras", ("portrait_garden",)), ("tabletop_stress", ("portrait",)),
                                               ("procedural_test", ("procedural_100000", "procedural_100001"))))


def _estimate(image, params=None, *, encoding="srgb"):
    from method import estimate_defocus_map

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return estimate_defocus_map(image, params, encoding=encoding)


def _encode(linear, config):
    from scenes.display import camera_image

    return camera_image(linear, quantize_bits=config.quantize_bits, encoding=config.encoding)


def _masked_psnr(test, reference, mask):
    """PSNR (dB, peak 1) over the pixels of ``mask`` (HxW bool; all channels); NaN if empty, inf if equal."""
    if not mask.any():
        return float("nan")
    mse = float(np.mean((np.asarray(test, np.float64)[mask] - np.asarray(reference, np.float64)[mask]) ** 2))
    return float("inf") if mse == 0 else float(10.0 * np.log10(1.0 / mse))


@dataclasses.dataclass(frozen=True)
class _RenderedPair:
    """The small- and large-aperture renders of one scene, as the experiment uses them.

    Attributes
    ----------
    image_small, image_large : ndarray, shape (H, W, 3)
        The f/8 and f/4 inputs (``config.encoding``, quantised).
    linear_small : ndarray, shape (H, W, 3)
        The f/8 render's linear RGB clipped to [0, 1].
    gt_small, gt_large : ndarray, shape (H, W)
        σ_gt of the two renders, px (NaN where no surface).
    defocus_small : ndarray, shape (H, W)
        Defocus-only σ of the f/8 render, √(σ_gt² − σ_filter²) = c/4, px.
    mask, in_focus, defocused : ndarray of bool, shape (H, W)
        Evaluated pixels (finite σ_gt in both, off occlusion boundaries); of those, the pixels whose
        f/4 defocus-only σ is ≤ / > ``config.in_focus_sigma_px``.
    occlusion : ndarray of bool, shape (H, W)
        The f/4 render's occlusion band (within a CoC radius + 1 px of a depth discontinuity).
    in_front : ndarray of bool, shape (H, W)
        Pixels nearer than the focus plane (depth < focus distance; both renders share the camera's focus).
    """

    image_small: np.ndarray
    image_large: np.ndarray
    linear_small: np.ndarray
    gt_small: np.ndarray
    gt_large: np.ndarray
    defocus_small: np.ndarray
    mask: np.ndarray
    in_focus: np.ndarray
    defocused: np.ndarray
    occlusion: np.ndarray
    in_front: np.ndarray

    @property
    def regions(self) -> dict:
        """``{"all": mask}`` for :func:`experiments.metrics.dense_metrics`."""
        return {"all": self.mask}


def _render_pair(name, config) -> _RenderedPair:
    """Render scene ``name`` at ``config``'s two apertures (:class:`_RenderedPair`)."""
    from scenes import render_scene
    from scenes.render import FILTER_SIGMA_PX

    r_s = render_scene(name, preset=config.preset, f_number=config.f_number_small_aperture,
                       seed=config.render_seed, progress=False)
    r_l = render_scene(name, preset=config.preset, f_number=config.f_number_large_aperture,
                       seed=config.render_seed, progress=False)
    gt_s = np.asarray(r_s.sigma_px, dtype=np.float64)
    gt_l = np.asarray(r_l.sigma_px, dtype=np.float64)
    sf = FILTER_SIGMA_PX
    mask = np.isfinite(gt_s) & np.isfinite(gt_l) & ~r_s.occlusion_boundary & ~r_l.occlusion_boundary
    sigma_d_l = np.sqrt(np.maximum(gt_l**2 - sf**2, 0.0))
    return _RenderedPair(
        image_small=r_s.image(encoding=config.encoding, quantize_bits=config.quantize_bits),
        image_large=r_l.image(encoding=config.encoding, quantize_bits=config.quantize_bits),
        linear_small=np.clip(np.asarray(r_s.rgb, dtype=np.float64), 0.0, 1.0),
        gt_small=gt_s, gt_large=gt_l,
        defocus_small=np.sqrt(np.maximum(gt_s**2 - sf**2, 0.0)),  # defocus-only σ of the f/8 render (c/4)
        mask=mask,
        in_focus=mask & (sigma_d_l <= config.in_focus_sigma_px),
        defocused=mask & (sigma_d_l > config.in_focus_sigma_px),
        occlusion=np.asarray(r_l.occlusion_boundary, dtype=bool),
        in_front=r_s.in_front,
    )


def _masked_ssim(ssim_map, mask):
    """Mean of an SSIM map (HxW) over ``mask``; NaN if empty."""
    return float(np.mean(ssim_map[mask])) if mask.any() else float("nan")


def _score_image(im, pair: _RenderedPair) -> dict:
    """:func:`experiments.metrics.image_quality` against the f/4 input, plus PSNR and SSIM in focus,
    defocused and in the occlusion band."""
    from skimage.metrics import structural_similarity

    from .metrics import image_quality

    q = image_quality(im, pair.image_large)
    _, smap = structural_similarity(np.asarray(pair.image_large, np.float64), np.asarray(im, np.float64),
                                    data_range=1.0, channel_axis=-1, full=True)
    smap = smap.mean(axis=-1)
    for name, mask in (("in_focus", pair.in_focus), ("defocused", pair.defocused), ("occlusion", pair.occlusion)):
        q[f"psnr_{name}_db"] = _masked_psnr(im, pair.image_large, mask)
        q[f"ssim_{name}"] = _masked_ssim(smap, mask)
    return q


def _magnify(image, defocus_map, config, renderer, *, in_front=None, **kwargs):
    """:func:`method.magnify_defocus` ×k with ``renderer`` and the config's kernel / aperture where it takes one,
    and ``in_front`` (HxW bool, pixels before the focus plane) where the renderer models occlusion."""
    from method import magnify_defocus
    from method.magnify.magnification import MAGNIFICATION_RENDERERS

    caps = MAGNIFICATION_RENDERERS.entry(renderer).capabilities
    kwargs.setdefault("encoding", config.encoding)
    return magnify_defocus(image, defocus_map, factor=config.factor, renderer=renderer,
                           kernel=config.kernel if "kernel" in caps else None,
                           aperture=config.aperture if "aperture" in caps else None,
                           in_front=in_front if "occlusion" in caps else None, **kwargs)


def _suffix(renderer, config) -> str:
    """"" for the first renderer of ``config`` (the paper's rows), else ``"_<renderer>"``."""
    return "" if renderer == config.renderers[0] else f"_{renderer}"


def _preset_independent(pair: _RenderedPair, config) -> tuple[dict, dict, dict]:
    """Rows that do not depend on the method preset: the doubled truth, the unchanged input, the oracles.

    Returns
    -------
    (dict, dict, dict)
        ``truth_rows`` (dense metrics of k·σ_gt(f/8) and the filter-aware doubled truth against
        σ_gt(f/4)), ``images`` (``unchanged_small``, and per renderer ``magnified_oracle_srgb<sx>``,
        ``magnified_oracle_linear<sx>``, sx = :func:`_suffix`; HxWx3; a renderer that models occlusion
        is given ``pair.in_front``) and their ``quality`` (:func:`_score_image`).
    """
    from scenes.render import FILTER_SIGMA_PX

    from .metrics import dense_metrics

    k, sf = config.factor, FILTER_SIGMA_PX
    truth_maps = {"k_x_gt_small_naive": k * pair.gt_small,
                  "gt_small_doubled_filter_aware": np.sqrt(k * k * pair.defocus_small**2 + sf**2)}
    truth_rows = {n: dense_metrics(m, pair.gt_large, regions=pair.regions)["all"] for n, m in truth_maps.items()}
    oracle_map = np.where(np.isfinite(pair.defocus_small), pair.defocus_small, 0.0)
    images = {"unchanged_small": pair.image_small}
    for renderer in config.renderers:
        sx = _suffix(renderer, config)
        linear = {"encoding": "linear", "light": "linear"}  # radiance blended as given, by every renderer
        images[f"magnified_oracle_srgb{sx}"] = _magnify(pair.image_small, oracle_map, config, renderer,
                                                        preprocess=False, in_front=pair.in_front)
        images[f"magnified_oracle_linear{sx}"] = _encode(_magnify(pair.linear_small, oracle_map, config, renderer,
                                                                  preprocess=False, in_front=pair.in_front,
                                                                  **linear), config)
    return truth_rows, images, {n: _score_image(im, pair) for n, im in images.items()}


def _estimated_case(pair: _RenderedPair, params, config) -> tuple[dict, dict, dict]:
    """Estimate both maps with ``params``, magnify the f/8 input and score everything (one preset).

    Returns
    -------
    (dict, dict, dict)
        Arrays ``map_small``, ``map_large``, ``magnified<sx>`` (per renderer, :func:`_suffix`),
        ``magnified_subtract``, ``magnified_default``, ``map_small_subtract``; the preset's metrics (see :func:`compute_case`);
        the seconds of the estimate and of each magnification.
    """
    from method.magnify.magnification import preprocess_defocus_map

    from .metrics import dense_metrics

    k, regions, gt_s, gt_l, img_s = config.factor, pair.regions, pair.gt_small, pair.gt_large, pair.image_small
    t0 = time.perf_counter()
    res_s = _estimate(img_s, params, encoding=config.encoding)
    res_l = _estimate(pair.image_large, params, encoding=config.encoding)
    seconds = {"estimate_seconds": time.perf_counter() - t0}
    candidates = {"map_small": res_s.defocus_map, "k_x_map_small": k * res_s.defocus_map,
                  "map_large": res_l.defocus_map}
    maps = {n: dense_metrics(m, gt_l, regions=regions)["all"] for n, m in candidates.items()}
    maps_vs_gt_small = {"map_small": dense_metrics(res_s.defocus_map, gt_s, regions=regions)["all"]}
    # the doubling claim compared directly: k × map(f/8) with map(f/4) as the reference, px
    doubled_vs_map_large = dense_metrics(k * res_s.defocus_map, res_l.defocus_map, regions=regions)["all"]
    clip, smooth = params.map_clip_percent, params.map_smoothing  # paper: 5 %, 0.5 %
    quality = {}
    arrays = {"map_small": res_s.defocus_map, "map_large": res_l.defocus_map}
    for renderer in config.renderers:
        sx = _suffix(renderer, config)
        t0 = time.perf_counter()
        mag = _magnify(img_s, res_s.defocus_map, config, renderer, clip_percent=clip, smoothing=smooth)
        seconds[f"magnify_seconds{sx}"] = time.perf_counter() - t0
        quality[f"magnified_estimated{sx}"] = _score_image(mag, pair)
        arrays[f"magnified{sx}"] = mag
        if not sx:  # the other reading of Sec. 5's map floor, on the paper's path
            mag_subtract = _magnify(img_s, res_s.defocus_map, config, renderer, clip_percent=clip,
                                    smoothing=smooth, floor="subtract")
            quality["magnified_estimated_subtract"] = _score_image(mag_subtract, pair)
            arrays["magnified_subtract"] = mag_subtract
    quality["magnified_estimated_default"], arrays["magnified_default"] = _default_row(
        img_s, res_s.defocus_map, params, config, quality, arrays, pair)
    arrays["map_small_subtract"] = preprocess_defocus_map(res_s.defocus_map, clip_percent=clip, smoothing=smooth,
                                                          floor="subtract")
    map_floor_px = max(float(np.percentile(res_s.defocus_map, clip)), 0.0)  # p_lo, px
    metrics = {
        "maps_vs_gt_large": maps,
        "maps_vs_gt_small": maps_vs_gt_small,
        "k_x_map_small_vs_map_large": doubled_vs_map_large,
        "image_vs_large": quality,
        "map_floor_px": map_floor_px,
        # flags (the results table holds numbers): renderer_<name> and floor_<mode> of the default row
        "default_magnification": {f"renderer_{params.magnify_renderer}": True, f"floor_{params.map_floor}": True},
    }
    return arrays, metrics, seconds


def _default_row(image, defocus_map, params, config, quality, arrays, pair):
    """(scores, HxWx3 image) of the preset's own magnification (``params.magnify_renderer`` and
    ``params.map_floor``): a row above when it is one of them (the gather + ``"clamp"`` row for the
    paper preset), else magnified with them (no ``in_front``: the method knows no depth)."""
    renderer, floor = params.magnify_renderer, params.map_floor
    if floor == "clamp" and renderer in config.renderers:
        sx = _suffix(renderer, config)
        return quality[f"magnified_estimated{sx}"], arrays[f"magnified{sx}"]
    mag = _magnify(image, defocus_map, config, renderer, clip_percent=params.map_clip_percent,
                   smoothing=params.map_smoothing, floor=floor)
    return _score_image(mag, pair), mag


def cases(config: Fig7Config) -> tuple:
    """Per scene set × scene: a ``stage`` case (both renders and the preset-independent rows: the doubled
    truth, the unchanged input, the oracle magnifications) and, needing it, one case per preset."""
    from method.magnify.magnification import MAGNIFICATION_RENDERERS

    from .cases import Case, method_presets
    from .scene_sets import set_scene_pairs

    if config.factor < 1:
        raise ValueError(f"f_number_small_aperture/f_number_large_aperture = {config.factor:g} is invalid; allowed: >= 1")
    MAGNIFICATION_RENDERERS.check_all(config.renderers, what="Fig7Config.renderers")
    presets = method_presets(config.presets)
    out = []
    for set_name, scene in set_scene_pairs(config):
        stage = Case("fig7", scene_set=set_name, scene=scene, aperture=float(config.f_number_small_aperture),
                     encoding=config.encoding, variant="stage", scene_size=config.preset)
        out.append(stage)
        out += [Case("fig7", scene_set=set_name, scene=scene, preset=p, aperture=stage.aperture,
                     encoding=config.encoding, scene_size=config.preset, needs=(stage,)) for p in presets]
    return tuple(out)


#: Arrays of the stage case the preset cases read (as a :class:`_RenderedPair`).
_PAIR_FIELDS = ("image_small", "image_large", "gt_small", "gt_large", "mask", "in_focus", "defocused", "occlusion",
                "in_front")


def compute_case(config: Fig7Config, case, inputs) -> dict:
    """One case of :func:`cases`.

    Returns
    -------
    dict
        ``stage``: arrays ``image_small`` / ``image_large`` (the f/8 and f/4 inputs, HxWx3),
        ``gt_small`` / ``gt_large`` (σ_gt, px), ``mask``, ``in_focus``, ``defocused``, ``occlusion``
        ``in_front`` (HxW bool) and the oracle results ``magnified_oracle_srgb<sx>`` / ``magnified_oracle_linear<sx>``
        per renderer (HxWx3); metrics ``maps_vs_gt_large`` (the naive and the filter-aware doubled truth
        against σ_gt(f/4)), ``image_vs_large`` (``unchanged_small`` and the oracle rows), ``gt_range_px``
        and pixel counts (``in_front_pixels`` among them). A preset: arrays ``map_small``, ``map_large``, ``magnified<sx>``,
        ``magnified_subtract``, ``magnified_default``, ``map_small_subtract``; metrics ``maps_vs_gt_large`` (its maps),
        ``maps_vs_gt_small``, ``k_x_map_small_vs_map_large``, ``image_vs_large`` (its magnified rows),
        ``map_floor_px``, ``default_magnification`` (module Notes).
    """
    from method import DefocusParams

    if case.variant == "stage":
        pair = _render_pair(case.scene, config)
        truth_rows, images, quality = _preset_independent(pair, config)
        gt_s, gt_l = pair.gt_small, pair.gt_large
        metrics = {"maps_vs_gt_large": truth_rows, "image_vs_large": quality,
                   "gt_range_px": {"small": [float(np.nanmin(gt_s)), float(np.nanmax(gt_s))],
                                   "large": [float(np.nanmin(gt_l)), float(np.nanmax(gt_l))]},
                   "evaluated_pixels": int(pair.mask.sum()), "in_focus_pixels": int(pair.in_focus.sum()),
                   "defocused_pixels": int(pair.defocused.sum()), "occlusion_pixels": int(pair.occlusion.sum()),
                   "in_front_pixels": int(pair.in_front.sum())}
        arrays = {k: getattr(pair, k) for k in _PAIR_FIELDS}
        arrays.update({k: v.astype(np.float32) for k, v in images.items() if k != "unchanged_small"})
        return {"arrays": arrays, "metrics": metrics, "info": {"upper_bound_note": _UPPER_BOUND_NOTE}}
    (stage,) = case.needs
    a = inputs[stage].arrays()
    pair = _RenderedPair(linear_small=None, defocus_small=None, **{k: a[k] for k in _PAIR_FIELDS})
    arrays, metrics, seconds = _estimated_case(pair, DefocusParams.preset(case.preset), config)
    return {"arrays": {k: np.asarray(v).astype(np.float32) for k, v in arrays.items()}, "metrics": metrics,
            "info": {"seconds": seconds}}


_UPPER_BOUND_NOTE = ("oracle map = defocus-only sigma c/4 = sqrt(sigma_gt^2 - sigma_filter^2) of the small-aperture "
                     "render, no Sec. 5 preprocessing; the box-filter sigma does not double with the aperture")


FIGURE = Figure(
    name="fig7", plot="experiments.plotting.fig7:plot", configs={"quick": QUICK, "full": FULL},
    cases_fn=cases, case_fn=compute_case, version=8,
    title="Doubled defocus: f/8 render magnified x2 vs the real f/4 render (maps and images)",
)
