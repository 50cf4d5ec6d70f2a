"""Render a scene with its ground truth, cached on disk.

:func:`render_scene` renders a :data:`scenes.library.SCENES` entry with Mitsuba 3 (thin-lens camera,
``box`` pixel filter), computes per-pixel ground truth (:mod:`scenes.ground_truth`: camera-space
depth from lens-centre rays, CoC by Eq. (5), σ_gt, occlusion-boundary mask), writes everything to one
float32 EXR (:mod:`scenes.exr`) plus a JSON sidecar, and returns a :class:`Render` (the file and its
reader: :mod:`scenes.render_files`).

Renders are cached under ``scenes.backend.cache_root() / "renders"`` (:class:`defocus_cache.Cache`)
keyed by everything that changes the output: the scene's *content* (:func:`scene_content_hash`, a hash
of its Mitsuba shapes and integrator, textures and transforms included, so editing a scene re-renders
it and only it), camera (incl. resolution), spp, seed, Mitsuba variant, the library versions of
:data:`defocus_cache.KEY_LIBRARIES`, the source of the ground-truth code, σ convention and filter σ, and
:data:`RENDER_FORMAT`. Entries are checksummed; a truncated entry is rebuilt; concurrent processes build
an entry once.
"""

from __future__ import annotations

import datetime
import json
import math
import time
from pathlib import Path

import numpy as np

from .backend import cache_root, import_mitsuba
from .camera import ThinLensCamera
from .ground_truth import camera_space_depth, ground_truth_from_depth
from .library import SceneDefinition, get_scene
from .library.base import SAMPLER
from defocus_cache import Cache, atomic_write_text, hash_key, library_versions, source_fingerprint
from .render_files import CHANNEL_UNITS, EXR_NAME, Render, load_render, sidecar_path
from .thin_lens import BOX_FILTER_SIGMA_PX, SIGMA_CONVENTIONS

__all__ = [
    "CHUNK_SAMPLES",
    "EXR_NAME",
    "RENDER_FORMAT",
    "Render",
    "load_render",
    "render_cache",
    "render_key",
    "render_scene",
    "scene_content_hash",
    "sidecar_path",
    "validate_render_options",
]

#: Version of the render file layout (channels and sidecar fields); part of the cache key. The
#: ground-truth algorithm enters the key by its source (:func:`_ground_truth_code`).
RENDER_FORMAT = 2
#: Samples (pixels x spp) per ``mitsuba.render`` call; renders are split into chunks with
#: different seeds, averaged, so progress can be shown.
CHUNK_SAMPLES = 1 << 23
#: σ of the ``box`` pixel filter every scene uses, px (1/√12).
FILTER_SIGMA_PX = float(BOX_FILTER_SIGMA_PX)

def validate_render_options(scene, camera=None, *, preset="small", f_number=None, spp=None, seed=0,
                            sigma_convention="line_spread"):
    """Check and complete the options of :func:`render_scene` without rendering anything.

    Returns
    -------
    (SceneDefinition, ThinLensCamera, int, int)
        Scene, camera, spp, seed.

    Raises
    ------
    ValueError
        Naming the bad value and the allowed range.
    """
    sdef = get_scene(scene)
    if camera is None:
        camera = sdef.camera(preset, f_number=f_number)
    else:
        if not isinstance(camera, ThinLensCamera):
            raise ValueError(f"camera={camera!r} is invalid; allowed: a scenes.camera.ThinLensCamera or None")
        sdef.spp(preset)  # validates the preset
        if f_number is not None:
            camera = camera.replace(f_number=f_number)
    if spp is None:
        spp = sdef.spp(preset)
    if isinstance(spp, bool) or not isinstance(spp, (int, np.integer)) or spp <= 0:
        raise ValueError(f"spp={spp!r} is invalid; allowed: integer > 0")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**32:
        raise ValueError(f"seed={seed!r} is invalid; allowed: integer in [0, 2**32)")
    if sigma_convention not in SIGMA_CONVENTIONS:
        raise ValueError(f"sigma_convention={sigma_convention!r} is invalid; allowed: {sorted(SIGMA_CONVENTIONS)}")
    return sdef, camera, int(spp), int(seed)


def _hash_value(h, obj) -> None:
    """Feed a Mitsuba scene-dictionary value into ``h`` by content (arrays by their bytes)."""
    if isinstance(obj, dict):
        h.update(b"{")
        for k in sorted(obj, key=str):
            h.update(repr(str(k)).encode())
            _hash_value(h, obj[k])
        h.update(b"}")
    elif isinstance(obj, (list, tuple)):
        h.update(b"[")
        for v in obj:
            _hash_value(h, v)
        h.update(b"]")
    elif isinstance(obj, (str, int, float, bool)) or obj is None:
        h.update(f"{type(obj).__name__}:{obj!r};".encode())
    elif isinstance(obj, np.ndarray):
        a = np.ascontiguousarray(obj)
        h.update(f"ndarray:{a.dtype.str}:{a.shape};".encode())
        h.update(a.tobytes())
    elif hasattr(obj, "matrix"):  # mitsuba (Scalar)Transform3f/4f, AffineTransform
        h.update(f"{type(obj).__name__}:".encode())
        _hash_value(h, np.asarray(obj.matrix, dtype=np.float64))
    elif type(obj).__name__ == "Bitmap":
        h.update(f"Bitmap:{obj.pixel_format()}:{obj.component_format()}:{obj.srgb_gamma()};".encode())
        _hash_value(h, np.asarray(obj))
    else:
        h.update(f"{type(obj).__module__}.{type(obj).__qualname__}:{obj!r};".encode())


#: In-process memo of :func:`scene_content_hash`: (scene, source fingerprint, variant) -> hash.
_CONTENT_HASHES: dict[tuple, str] = {}


def scene_content_hash(sdef: SceneDefinition, *, variant: str) -> str:
    """Hash (16 hex digits) of what a scene *is*: its Mitsuba shapes and integrator, by content.

    The render cache key uses this instead of a hand-bumped version: an edit of a scene's geometry,
    textures, materials or lighting re-renders that scene, and an edit that leaves the scene
    dictionary unchanged (a refactoring, a new scene beside it) re-renders nothing.

    Parameters
    ----------
    sdef : SceneDefinition
    variant : str, keyword-only
        The selected Mitsuba variant (the builders create Mitsuba objects).

    Returns
    -------
    str

    Notes
    -----
    Building the dictionary of the larger scenes takes seconds (procedural textures), so the hash is
    memoised in memory and on disk (``cache_root() / "scene_hashes"``) under the source fingerprint of
    the ``scenes`` package and of the builder function, the variant and the library versions: while
    none of those change, the dictionary is not rebuilt.
    """
    import hashlib

    package = Path(__file__).resolve().parent  # the scenes package (every .py below it)
    memo = {"scene": sdef.name, "source": source_fingerprint(package, sdef.shapes), "variant": variant,
            "libraries": library_versions()}
    mkey = hash_key(memo)
    # Only library scenes are memoised: their builders are determined by the scenes package's source.
    # A definition made elsewhere may capture values (a closure) that no source fingerprint sees.
    try:
        registered = get_scene(sdef.name) is sdef
    except ValueError:
        registered = False
    mem_key = (sdef.name, mkey)
    if registered and mem_key in _CONTENT_HASHES:
        return _CONTENT_HASHES[mem_key]
    path = cache_root() / "scene_hashes" / f"{mkey}.json"
    try:
        if not registered:
            raise OSError("not memoised")
        value = json.loads(path.read_text())["content"]
    except (OSError, ValueError, KeyError, TypeError):
        import_mitsuba(variant)
        h = hashlib.sha256()
        _hash_value(h, {"integrator": dict(sdef.integrator), "shapes": sdef.shapes()})
        value = h.hexdigest()[:16]
        if registered:
            path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(path, json.dumps({**memo, "content": value}, sort_keys=True))
    if registered:
        _CONTENT_HASHES[mem_key] = value
    return value


def _ground_truth_code() -> str:
    from . import exr, ground_truth, mitsuba_camera, thin_lens

    return source_fingerprint(ground_truth, thin_lens, mitsuba_camera, exr)


def render_key(sdef: SceneDefinition, camera: ThinLensCamera, *, spp, seed, variant, sigma_convention,
               scene_content: str | None = None, libraries: dict | None = None) -> dict:
    """The cache key: everything that changes a render's pixels or ground truth.

    ``scene_content`` (default :func:`scene_content_hash`) and ``libraries`` (default
    :func:`defocus_cache.library_versions`) can be given to build keys without Mitsuba.
    """
    return {
        "kind": "render",
        "format": RENDER_FORMAT,
        "scene": sdef.name,
        "scene_content": scene_content if scene_content is not None else scene_content_hash(sdef, variant=variant),
        "camera": camera.to_dict(),
        "spp": int(spp),
        "seed": int(seed),
        "variant": variant,
        "libraries": dict(libraries) if libraries is not None else library_versions(),
        "ground_truth_code": _ground_truth_code(),
        "sigma_convention": sigma_convention,
        "filter_sigma_px": FILTER_SIGMA_PX,
    }


def render_cache() -> Cache:
    """The render cache, ``cache_root() / "renders"``."""
    return Cache(cache_root() / "renders")


def _sampler_accepts(n: int) -> bool:
    # Mitsuba's multijitter sampler lays n samples on an ny x nx grid with ny = floor(sqrt(n)),
    # nx = ceil(n / ny), and rounds n up otherwise (measured: 32 → 35, 128 → 132, 512 → 528).
    return n % math.isqrt(n) == 0


def _chunks(spp: int, pixels: int) -> list[int]:
    """Split ``spp`` into chunks of ≤ CHUNK_SAMPLES samples, each a count the sampler takes as is."""
    n = max(1, min(spp, math.ceil(spp * pixels / CHUNK_SAMPLES)))
    target = math.ceil(spp / n)
    out, left = [], spp
    while left > 0:
        k = min(left, target)
        while not _sampler_accepts(k):
            k -= 1
        out.append(k)
        left -= k
    return out


def _compute(sdef, camera, *, spp, seed, mi, variant, sigma_convention, progress):
    from tqdm.auto import tqdm

    width, height = camera.resolution
    t0 = time.perf_counter()
    scene = mi.load_dict(sdef.build(camera, spp=spp, seed=seed))
    t_load = time.perf_counter() - t0
    chunks = _chunks(spp, width * height)
    acc = np.zeros((height, width, 3), np.float64)
    t0 = time.perf_counter()
    desc = f"{sdef.name} {width}x{height} f/{camera.f_number:g}"
    with tqdm(total=spp, unit="spp", desc=desc, disable=not progress, leave=False) as bar:
        for i, k in enumerate(chunks):
            chunk_seed = (seed * 1_000_003 + i) % (2**32)
            img = np.asarray(mi.render(scene, spp=k, seed=chunk_seed), dtype=np.float64)
            used = int(scene.sensors()[0].sampler().sample_count())
            if used != k:  # pragma: no cover - guarded by _sampler_accepts
                raise RuntimeError(f"sampler used {used} spp for a chunk of {k}")
            acc += img[:, :, :3] * k
            bar.update(k)
    rgb = (acc / spp).astype(np.float32)
    t_render = time.perf_counter() - t0
    t0 = time.perf_counter()
    depth = camera_space_depth(scene, mi=mi)
    gt = ground_truth_from_depth(depth, camera, sigma_convention=sigma_convention, filter_sigma_px=FILTER_SIGMA_PX)
    t_gt = time.perf_counter() - t0
    finite = np.isfinite(depth)
    sig = gt["sigma_px"].astype(np.float64)
    metadata = {
        "format": RENDER_FORMAT,
        "scene": sdef.name,
        "scene_version": int(sdef.version),
        "description": sdef.description,
        "camera": camera.to_dict(),
        "resolution": [width, height],
        "spp": spp,
        "seed": seed,
        "chunks_spp": chunks,
        "variant": variant,
        "integrator": dict(sdef.integrator),
        "sampler": SAMPLER,
        "pixel_filter": "box",
        "versions": library_versions(),
        "sigma_convention": sigma_convention,
        "filter_sigma_px": FILTER_SIGMA_PX,
        "depth_method": "lens-centre ray through each pixel centre; z = (p - camera position) . forward; inf on miss",
        "channels": CHANNEL_UNITS,
        "load_time_s": t_load,
        "render_time_s": t_render,
        "ground_truth_time_s": t_gt,
        "created_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "stats": {
            "sigma_px_min": float(sig.min()),
            "sigma_px_p05": float(np.percentile(sig, 5)),
            "sigma_px_median": float(np.median(sig)),
            "sigma_px_p95": float(np.percentile(sig, 95)),
            "sigma_px_max": float(sig.max()),
            "depth_min_m": float(depth[finite].min()) if finite.any() else None,
            "depth_max_m": float(depth[finite].max()) if finite.any() else None,
            "miss_fraction": float(1.0 - finite.mean()),
            "occlusion_boundary_fraction": float(gt["occlusion_boundary"].mean()),
        },
    }
    return Render(rgb=rgb, depth=depth, metadata=metadata, path=None, **gt)


def render_scene(
    scene,
    camera: ThinLensCamera | None = None,
    *,
    preset: str = "small",
    f_number: float | None = None,
    spp: int | None = None,
    seed: int = 0,
    variant: str | None = None,
    sigma_convention: str = "line_spread",
    use_cache: bool = True,
    force: bool = False,
    progress: bool = True,
) -> Render:
    """Render a scene and its ground truth (cached).

    Parameters
    ----------
    scene : str or SceneDefinition
        A key of :data:`scenes.library.SCENES` or a definition.
    camera : ThinLensCamera, optional
        Default: ``scene.camera(preset, f_number=f_number)`` (full frame, 50 mm, the scene's focus).
    preset : {"small", "full"}, keyword-only
        Resolution preset (160x120 / 640x480) of the default camera, and the default spp.
    f_number : float, optional, keyword-only
        N; overrides the camera's (default f/8).
    spp : int, optional, keyword-only
        Samples per pixel (default: the scene's for ``preset``).
    seed : int, keyword-only
        Base sampler seed, in [0, 2**32).
    variant : str, optional, keyword-only
        Mitsuba variant (default: ``$DEFOCUS_MITSUBA_VARIANT`` or the fastest that works).
    sigma_convention : {"line_spread", "erf_fit"}, keyword-only
        CoC → σ convention of ``sigma_px`` (c/4 or 0.273·c, in quadrature with the box filter's σ).
    use_cache : bool, keyword-only
        Read/write the render cache. ``False`` renders in memory (``Render.path`` is None).
    force : bool, keyword-only
        Re-render even when the render is cached (the new render replaces the entry).
    progress : bool, keyword-only
        Show a tqdm progress bar (spp chunks).

    Returns
    -------
    Render

    Raises
    ------
    ValueError
        On a bad scene, preset, camera, spp, seed or convention (before anything is rendered).
    scenes.backend.BackendError
        If the requested Mitsuba variant does not work here.

    Notes
    -----
    1. Validate every option; select and set the Mitsuba variant.
    2. Look the key up in the cache; if absent or invalid, under a file lock:
    3. build the scene dictionary, render in chunks of ≤ :data:`CHUNK_SAMPLES` samples with seeds
       ``seed·1000003 + i`` and average them (weighted by spp),
    4. cast lens-centre rays through the pixel centres for depth; CoC (Eq. 5), σ_gt, mask,
    5. write ``render.exr`` + ``render.json`` into the entry; checksum; rename into place.
    """
    sdef, camera, spp, seed = validate_render_options(
        scene, camera, preset=preset, f_number=f_number, spp=spp, seed=seed, sigma_convention=sigma_convention
    )
    mi, chosen = import_mitsuba(variant)
    kwargs = dict(spp=spp, seed=seed, mi=mi, variant=chosen, sigma_convention=sigma_convention, progress=progress)
    if not use_cache:
        return _compute(sdef, camera, **kwargs)
    key = render_key(sdef, camera, spp=spp, seed=seed, variant=chosen, sigma_convention=sigma_convention)
    cache = render_cache()
    if force:
        cache.invalidate(key)

    def build(folder: Path) -> None:
        _compute(sdef, camera, **kwargs).save(folder / EXR_NAME)

    folder = cache.get_or_build(key, build)
    return load_render(folder / EXR_NAME)

