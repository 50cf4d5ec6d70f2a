"""The defocus map of a photo for the photo tools: estimated at a working resolution and cached, written.

:func:`estimate_photo_map` is the cached estimation ``repro.estimate`` and ``repro.magnify`` share
(:class:`defocus_cache.Cache` under ``$DEFOCUS_CACHE_DIR/maps``, keyed by :func:`map_cache_key`);
:func:`write_map` writes a map by extension (EXR, PNG preview with a colour bar, NPY). Imported from
:mod:`repro.estimate`.
"""

from __future__ import annotations

import json
import tempfile
import warnings
from pathlib import Path

import numpy as np

__all__ = ["MAP_CACHE_VERSION", "PREVIEW_MAX_PIXELS", "estimate_photo_map", "map_cache_key", "write_map",
           "write_map_preview"]

#: Largest map plotted as is in a PNG preview, px (bigger maps are downscaled for display first).
PREVIEW_MAX_PIXELS = 2_000_000

#: Version of the map-cache layout (bump when the entry's files or their meaning change).
MAP_CACHE_VERSION = 1


def _code_version(params) -> str:
    """:func:`defocus_cache.source_fingerprint` of what determines a map: the ``method`` package,
    the photo decoder and display encoding, and the chosen estimator (which may be registered at
    run time from outside ``method``)."""
    import method
    import scenes.display
    import repro.photo_io
    from method import BLUR_ESTIMATORS
    from defocus_cache import source_fingerprint

    extra = [BLUR_ESTIMATORS[params.estimator]] if params.estimator in BLUR_ESTIMATORS else []
    return source_fingerprint(method, repro.photo_io, scenes.display, *extra)


def map_cache_key(photo, params, working_shape_) -> dict:
    """Everything that determines a working-resolution map (JSON-able).

    ``params`` enters field by field (every field of ``DefocusParams``), so two presets, or a preset
    and its ``--estimator``/``--alpha`` variant, never share an entry; the preset's *name* is not in
    the key (equal parameters give the same map whatever they are called).
    """
    import dataclasses

    from defocus_cache import library_versions, sha256_file

    return {
        "kind": "defocus_map",
        "layout": MAP_CACHE_VERSION,
        "photo_sha256": sha256_file(photo.path),
        "decoded": {"shape": list(photo.image.shape), "repaired": any("repaired" in n for n in photo.notes),
                    "encoding": photo.encoding},
        "params": dataclasses.asdict(params),
        "working_shape": list(working_shape_),
        "code": _code_version(params),
        "versions": library_versions(),
    }


def _build_map(folder: Path, image, params, progress, preset, *, max_working_pixels, encoding):
    """Estimate (:func:`method.magnify.upsampling.estimate_defocus_map_at_scale`) and store the
    working-resolution map and its notes in a cache entry ``folder``; return the full-resolution map."""
    from method.magnify.upsampling import estimate_defocus_map_at_scale
    from method.pipeline import NoEdgesWarning

    # no RNG seeding needed: the pipeline is deterministic (tests/test_determinism_method.py)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", NoEdgesWarning)
        scaled = estimate_defocus_map_at_scale(image, params, encoding=encoding, max_working_pixels=max_working_pixels,
                                               progress=progress)
    result = scaled.working_result
    no_edges = any(issubclass(w.category, NoEdgesWarning) for w in caught)
    for w in caught:  # anything else is re-raised as a normal warning
        if not issubclass(w.category, NoEdgesWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    with open(folder / "map.npy", "wb") as fh:
        np.save(fh, np.ascontiguousarray(result.defocus_map, dtype=np.float64), allow_pickle=False)
    n_measures = int(np.count_nonzero(np.isfinite(result.sparse_sigma)))
    meta = {"no_edges": no_edges, "edge_pixels": int(result.edges.sum()), "measures": n_measures,
            "psf_model": result.psf_model,  # "gaussian" / "disk" / "mixed" / None (DefocusResult.psf_model)
            "psf_disk_measures": None if result.psf_disk is None else int(np.count_nonzero(result.psf_disk)),
            "encoding": result.encoding,  # the tone curve read (encoding="auto": the one fitted)
            "timings_s": {k: float(v) for k, v in result.timings.items()},
            "preset": preset}  # informational: the name it was built under (the key holds the params)
    (folder / "meta.json").write_text(json.dumps(meta, indent=1, sort_keys=True))
    return scaled.defocus_map


def _load_entry(folder: Path, shape):
    m = np.load(folder / "map.npy", allow_pickle=False)
    meta = json.loads((folder / "meta.json").read_text())
    if m.shape != tuple(shape) or not np.all(np.isfinite(m)) or (m.size and m.min() < 0):
        raise ValueError("bad cached map")
    return m, meta


def estimate_photo_map(photo, params, *, max_working_pixels, use_cache=True, force=False, progress=None,
                       log=lambda msg: None, preset=None):
    """Defocus map of a photo at full resolution, estimated at the working resolution, cached.

    Parameters
    ----------
    photo : repro.photo_io.Photo
        Its ``encoding`` is passed to the method (and is part of the cache key); linear values above 1
        are estimated as 1.
    params : DefocusParams
    max_working_pixels : int, keyword-only
    use_cache : bool, keyword-only
        Read/write ``cache_root()/"maps"`` (:class:`defocus_cache.Cache`, checksummed, locked).
    force : bool, keyword-only
        Re-estimate even when the map is cached (the new map replaces the entry).
    progress : callable, optional, keyword-only
        ``progress(stage_name)``.
    log : callable, keyword-only
        Receives one-line notes (working resolution, cache reuse).
    preset : str, optional, keyword-only
        Name of the preset ``params`` came from, recorded in the cache entry's ``meta.json``
        (informational; the entry is keyed by ``params`` itself).

    Returns
    -------
    sigma : ndarray, HxW, float64
        σ in px of the full-resolution photo.
    info : dict
        ``scale``, ``working_shape``, ``no_edges``, ``cached`` (reused an existing entry),
        ``preset`` (as given), ``measures`` (edge pixels with a blur measure), ``psf_model`` and
        ``psf_disk_measures`` (:attr:`method.pipeline.DefocusResult.psf_model`; None when the
        estimator fits no PSF model).

    Notes
    -----
    A new map is estimated by :func:`method.magnify.upsampling.estimate_defocus_map_at_scale`
    (downscale, pipeline, σ to full-resolution px, guided upsampling); the cache keeps its
    working-resolution map, and a cached map is upsampled the same way
    (:func:`method.magnify.upsampling.upsample_defocus_map`), so both give the same bytes.
    """
    from method.magnify.upsampling import downscale_image, upsample_defocus_map, working_shape
    from scenes.backend import cache_root
    from defocus_cache import Cache

    # linear highlights above 1 (an EXR's) are seen as white by the estimation, whose edges and fits
    # read values in [0, 1]; the magnifier gets them unclipped
    image = np.minimum(photo.image, 1.0)
    H, W = image.shape[:2]
    (h, w), scale = working_shape(image.shape, max_working_pixels=max_working_pixels)
    if scale < 1:
        log(f"{W}x{H} px ({H * W / 1e6:.1f} MP) is over --max-working-pixels {max_working_pixels:,}: "
            f"estimating at {w}x{h} (scale {scale:.3g}), map upsampled edge-aware (guided filter) "
            "to full resolution")
    built = []  # full-resolution maps estimated by this call

    def build(folder):
        built.append(_build_map(Path(folder), image, params, progress, preset, max_working_pixels=max_working_pixels,
                                encoding=photo.encoding))

    if use_cache:
        cache = Cache(cache_root() / "maps")
        key = map_cache_key(photo, params, (h, w))
        if force:
            cache.invalidate(key)
        folder = cache.get_or_build(key, build)
        try:
            m, meta = _load_entry(folder, (h, w))
        except (OSError, ValueError):  # checksummed yet unreadable: rebuild once
            cache.invalidate(key)
            folder = cache.get_or_build(key, build)
            m, meta = _load_entry(folder, (h, w))
        if not built:
            log(f"defocus map reused from the cache ({folder})")
    else:
        with tempfile.TemporaryDirectory() as tmp:
            build(tmp)
            m, meta = _load_entry(Path(tmp), (h, w))
    if built:
        sigma = built[-1]
    elif scale < 1:  # a cached working-resolution map: upsampled as estimate_defocus_map_at_scale does
        if progress:
            progress("downscale")
        working = downscale_image(image, (h, w))
        if progress:
            progress("upsample")
        sigma = upsample_defocus_map(m, working, image, scale=scale, encoding=meta.get("encoding", photo.encoding))
    else:
        sigma = m
    return sigma, {"scale": scale, "working_shape": (h, w), "no_edges": bool(meta["no_edges"]),
                   "cached": not built, "preset": preset, "psf_model": meta.get("psf_model"),
                   "measures": meta.get("measures"), "psf_disk_measures": meta.get("psf_disk_measures"),
                   "encoding": meta.get("encoding", photo.encoding)}


def write_map_preview(path, sigma) -> Path:
    """Colour-mapped PNG of a defocus map with a colour bar labelled "blur σ (px)", atomically.

    Parameters
    ----------
    path : str or Path
        ``.png`` destination.
    sigma : ndarray, HxW, float
        σ in px, ≥ 0.
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from defocus_cache import atomic_write

    sigma = np.asarray(sigma, dtype=np.float64)
    h, w = sigma.shape
    if h * w > PREVIEW_MAX_PIXELS:  # the figure is ~1200 px wide: plot a downscaled copy
        from method.magnify.upsampling import downscale_image

        s = (PREVIEW_MAX_PIXELS / (h * w)) ** 0.5
        sigma = downscale_image(sigma, (max(1, int(h * s)), max(1, int(w * s))))
        h, w = sigma.shape
    vmax = float(sigma.max()) if sigma.size and sigma.max() > 0 else 1.0
    width_in = 8.0
    fig = Figure(figsize=(width_in, max(2.0, width_in * h / w * 0.85)), dpi=150)
    ax = fig.add_subplot()
    im = ax.imshow(sigma, cmap="magma", vmin=0.0, vmax=vmax, interpolation="antialiased")
    ax.set_axis_off()
    fig.colorbar(im, ax=ax, label="blur σ (px)", fraction=0.046, pad=0.02)
    path = Path(path)
    with atomic_write(path) as tmp:
        fig.savefig(tmp, format="png", bbox_inches="tight", metadata={"Software": None})
    return path


def write_map(path, sigma) -> Path:
    """Write a defocus map by extension: .exr (float32 σ), .png (preview), .npy (raw)."""
    from repro.photo_io import write_defocus_map

    path = Path(path)
    if path.suffix.lower() == ".png":
        return write_map_preview(path, sigma)
    return write_defocus_map(path, sigma)
