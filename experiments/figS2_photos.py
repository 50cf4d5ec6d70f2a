"""Real photos scored against hand-drawn regions: photo with its regions, map per preset, magnified result.

The photos ship inside scikit-image (``skimage.data``) with region files in ``experiments/photos``
(:mod:`experiments.photo_regions`): "in focus" and "defocused" polygons drawn by hand before any map
was computed on them. A photo has no ground-truth σ; the score is whether the map ranks the
defocused region blurrier than the in-focus one (ranking AUC, and the share of in-focus pixels above
the defocused region's median; targets AUC ≥ 0.95, share ≤ 2 %).

Notes
-----
1. Load each photo's region file (validated against the photo's shape) and the photo, 8-bit sRGB →
   float in [0, 1], at its shipped size (the regions are in its pixels).
2. Per method preset of ``config.presets``: :func:`method.estimate_defocus_map` with
   ``DefocusParams.preset(name)``.
3. :func:`experiments.photo_regions.score_defocus_map` of each map.
4. :func:`method.magnify_defocus` of the ``magnify_preset`` map with ``factor`` (Sec. 5 preprocessing
   of the preset: ``map_clip_percent``, ``map_smoothing``, ``map_floor``), once per renderer of ``renderers``.
5. A crop of a sharp subject's border (:func:`border_crop`): a square of side
   max(:data:`MIN_CROP_PX`, min(H, W) / 4) px centred on the pixel of the in-focus region's outline
   where the magnified map changes most (largest gradient magnitude of the map, Gaussian-smoothed
   by 2 px), moved inside the photo — where the renderers differ (halo, background bleed).
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np

from .registry import Figure

__all__ = ["FIGURE", "FULL", "MIN_CROP_PX", "QUICK", "PhotosConfig", "border_crop", "case_key_config", "cases", "compute_case",
           "photo_view"]

#: Smallest side of the border crop, px.
MIN_CROP_PX = 48


@dataclasses.dataclass(frozen=True, kw_only=True)
class PhotosConfig:
    """Every parameter of the photos figure."""

    photos: tuple[str, ...] = ("coffee", "chelsea", "astronaut")
    # photos with a region file (experiments.photo_regions.available_photos), in drawing order.
    presets: tuple[str, ...] = ("paper", "robust", "zhuo_sim")
    # method parameter presets (method.PRESETS), one map column each.
    factor: float = 2.0
    # defocus magnification k (total blur k·B; 2 = doubling the aperture diameter).
    kernel: str = "gaussian"
    # magnification kernel of the gather renderer (method.MAGNIFICATION_KERNELS).
    renderers: tuple[str, ...] = ("gather", "scatter")
    # magnification renderers (method.magnify.magnification.MAGNIFICATION_RENDERERS), one magnified result
    # and border crop each; the first is stored as <photo>__magnified, the others as <photo>__magnified_<R>.
    magnify_preset: str = "robust"
    # the preset whose map is magnified in the last column (must be in presets; else the first).
    regions_digest: str = dataclasses.field(default_factory=lambda: _regions_digest())
    # SHA-256 (16 hex digits) of the shipped region files, read when the config is made: part of the
    # cache key, so an edited region file recomputes the figure (the code fingerprint covers .py only).


def _regions_digest() -> str:
    import hashlib

    from .photo_regions import PHOTO_DIR

    h = hashlib.sha256()
    for path in sorted(PHOTO_DIR.glob("*.json")):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


FULL = PhotosConfig()
QUICK = PhotosConfig(photos=("coffee",))


def border_crop(in_focus, defocus_map) -> tuple[int, int, int, int]:
    """(y0, y1, x0, x1) of a square crop of a sharp subject's border (module Notes, step 5).

    Parameters
    ----------
    in_focus : ndarray of bool, HxW
        The hand-drawn in-focus region.
    defocus_map : ndarray, HxW, float
        The magnified map, σ px.

    Returns
    -------
    tuple of int
        Rows y0:y1 and columns x0:x1 of the crop (inside the photo).
    """
    from scipy import ndimage

    h, w = in_focus.shape
    side = min(max(MIN_CROP_PX, min(h, w) // 4), h, w)
    outline = in_focus & ~ndimage.binary_erosion(in_focus)
    smooth = ndimage.gaussian_filter(np.asarray(defocus_map, dtype=np.float64), 2.0)
    grad = np.hypot(*np.gradient(smooth))
    if outline.any():
        cy, cx = np.unravel_index(int(np.argmax(np.where(outline, grad, -1.0))), grad.shape)
    else:
        cy, cx = h // 2, w // 2
    y0 = int(min(max(cy - side // 2, 0), h - side))
    x0 = int(min(max(cx - side // 2, 0), w - side))
    return y0, y0 + side, x0, x0 + side


def cases(config: PhotosConfig) -> tuple:
    """One case per photo × preset (its map and scores) and per photo × renderer (``variant="magnify:<R>"``,
    needing the ``magnify_preset`` case: the magnified photo and its border crop)."""
    from method import PRESETS
    from method.magnify.magnification import MAGNIFICATION_RENDERERS

    from .cases import Case
    from .photo_regions import SCORE_PRESETS, validate_photo_names

    names = validate_photo_names(config.photos)
    renderers = MAGNIFICATION_RENDERERS.check_all(config.renderers, what="PhotosConfig.renderers")
    presets = tuple(PRESETS.check_all(dict.fromkeys(config.presets or SCORE_PRESETS), what="preset"))
    mag = config.magnify_preset if config.magnify_preset in presets else presets[0]
    out = []
    for name in names:
        maps = {p: Case("photos", scene=name, preset=p, variant="map") for p in presets}
        out += maps.values()
        out += [Case("photos", scene=name, preset=mag, variant=f"magnify:{r}", needs=(maps[mag],)) for r in renderers]
    return tuple(out)


def case_key_config(config: PhotosConfig, case) -> dict:
    """The fields of ``config`` one case of :func:`cases` reads (its cache key's config): the region files'
    digest; a magnified case also ``factor`` and ``kernel`` (photo, preset and renderer are the case's own
    fields, the map it magnifies is in its ``needs``). A photo's cases are then shared by every config that
    lists it (the quick config's coffee is the full config's)."""
    key = {"regions_digest": config.regions_digest}
    if case.variant != "map":
        key.update(factor=config.factor, kernel=config.kernel)
    return key


def compute_case(config: PhotosConfig, case, inputs) -> dict:
    """One case of :func:`cases`.

    Returns
    -------
    dict
        ``map``: arrays ``input`` (H, W, 3) float in [0, 1], ``in_focus`` / ``defocused`` (H, W) bool region
        masks, ``map`` (H, W) σ px; metrics :func:`experiments.photo_regions.score_defocus_map`'s.
        ``magnify:<R>``: array ``magnified`` (H, W, 3), the map magnified ×factor with renderer R (Sec. 5
        preprocessing of the preset); info ``border_crop`` ([y0, y1, x0, x1], :func:`border_crop`).
    """
    from method import DefocusParams, magnify_defocus
    from method.magnify.magnification import MAGNIFICATION_RENDERERS

    from .photo_regions import compute_photo_maps, score_defocus_map

    if case.variant == "map":
        run = compute_photo_maps(case.scene, (case.preset,))
        image, regions, res = run["image"], run["regions"], run["results"][case.preset]
        masks = regions.masks()
        return {"arrays": {"input": image, "in_focus": masks["in_focus"], "defocused": masks["defocused"],
                           "map": res.defocus_map},
                "metrics": score_defocus_map(res.defocus_map, regions),
                "info": {"seconds": run["seconds"][case.preset], "shape": list(image.shape[:2]),
                         "source": regions.source}}
    a = inputs[case.needs[0]].arrays()
    renderer = case.variant.split(":", 1)[1]
    params = DefocusParams.preset(case.preset)
    caps = MAGNIFICATION_RENDERERS.entry(renderer).capabilities
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        out = magnify_defocus(a["input"], a["map"], factor=config.factor, renderer=renderer,
                              kernel=config.kernel if "kernel" in caps else None,
                              clip_percent=params.map_clip_percent, smoothing=params.map_smoothing,
                              floor=params.map_floor)
    return {"arrays": {"magnified": out.astype(np.float32)},
            "info": {"seconds": time.perf_counter() - t0, "border_crop": list(border_crop(a["in_focus"], a["map"]))}}


def photo_view(fd) -> dict:
    """The cases as one dict: ``items`` (photo names), per photo ``<photo>__input``, ``<photo>__in_focus``,
    ``<photo>__defocused``, ``<photo>__<preset>__map``, ``<photo>__magnified[_<R>]``; ``metrics``:
    ``photos.<photo>.<preset>`` (scores, ``seconds``), ``photos.<photo>.border_crop`` / ``.shape`` /
    ``.magnify_seconds.<R>``, ``summary.<preset>``, ``presets_scored``, ``targets``, ``magnify_preset``,
    ``factor``, ``renderers``."""
    from .photo_regions import TARGET_AUC, TARGET_SHARE

    config = fd.config
    names = fd.values("scene", variant="map")
    presets = fd.values("preset", variant="map")
    renderers = [v.split(":", 1)[1] for v in fd.values("variant") if v.startswith("magnify:")]
    view, per_photo = {"items": np.asarray(names)}, {}
    for name in names:
        scores = per_photo[name] = {"magnify_seconds": {}}
        for p in presets:
            o = fd.one(scene=name, preset=p, variant="map")
            a = o.arrays()
            if f"{name}__input" not in view:
                view.update({f"{name}__input": a["input"].astype(np.float32), f"{name}__in_focus": a["in_focus"],
                             f"{name}__defocused": a["defocused"]})
            view[f"{name}__{p}__map"] = a["map"].astype(np.float32)
            scores[p] = {**o.metrics, "seconds": o.info.get("seconds")}
            scores["shape"] = o.info.get("shape")
        for i, r in enumerate(renderers):
            o = fd.one(scene=name, variant=f"magnify:{r}")
            view[f"{name}__magnified" + (f"_{r}" if i else "")] = o.arrays()["magnified"]
            scores["magnify_seconds"][r] = o.info.get("seconds")
            scores["border_crop"] = o.info["border_crop"]
    summary = {}
    for p in presets:
        aucs = [per_photo[n][p]["auc"] for n in names]
        shares = [per_photo[n][p]["in_focus_above_defocused_median"] for n in names]
        summary[p] = {"min_auc": float(min(aucs)), "max_in_focus_above_defocused_median": float(max(shares)),
                      "photos_meeting_targets": int(sum(bool(per_photo[n][p]["meets_targets"]) for n in names)),
                      "n_photos": len(names)}
    mag = next((o.case.preset for o in fd.outputs.values() if o.case.variant.startswith("magnify:")), presets[0])
    view["metrics"] = {"photos": per_photo, "summary": summary, "presets_scored": list(presets),
                       "targets": {"auc_min": TARGET_AUC, "in_focus_above_defocused_median_max": TARGET_SHARE},
                       "magnify_preset": mag, "factor": config.factor, "renderers": renderers}
    return view


FIGURE = Figure(
    name="photos",
    title="Real photos (skimage.data) with hand-drawn in-focus/defocused regions: map per preset, ranking AUC, "
          "magnified result",
    plot="experiments.plotting.photos:plot",
    configs={"quick": QUICK, "full": FULL},
    cases_fn=cases, case_fn=compute_case, version=4, key_config=case_key_config,
    sigma_convention="Gaussian sigma of the estimated blur, px of the photo (no ground truth)",
    renders=False,
)
