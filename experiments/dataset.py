"""A versioned on-disk dataset of the rendered scenes and their ground truth (maps are scored by
:mod:`experiments.external_maps`).

Layout (:data:`LAYOUT_VERSION`), per image ``NAME = <scene>_f<N>_<scene_preset>`` (N with ``p`` for
the decimal point, e.g. ``bars_f8_small``, ``bars_f5p6_small``):

``images/NAME.png`` (sRGB 8 bit), ``images/NAME_16bit.png`` (sRGB 16 bit), ``images/NAME.exr``
(linear radiance), ``gt/NAME_{sigma,depth,coc,occlusion,textured}.{exr,npy}``, ``done/NAME.json``
(the per-image completion record, written last), ``manifest.json`` and ``README.md``.
"""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import numpy as np

from .metrics import region_masks

__all__ = ["GT_FIELDS", "LAYOUT_VERSION", "export_image", "ground_truth_arrays", "git_commit", "image_name",
           "is_complete", "load_ground_truth", "load_image", "parse_image_name", "read_dataset", "write_manifest"]

#: "major.minor"; a reader refuses another major version.
LAYOUT_VERSION = "1.0"
#: Ground-truth fields written per image.
GT_FIELDS = ("sigma", "depth", "coc", "occlusion", "textured")
#: ``<scene>_f<N>_<scene_preset>`` (:func:`image_name`), as a pattern.
_NAME = re.compile(r"^(?P<scene>.+)_f(?P<n>[0-9]+(?:p[0-9]+)?)_(?P<preset>[a-z]+)$")


def image_name(scene: str, f_number: float, scene_preset: str) -> str:
    """``<scene>_f<N>_<scene_preset>`` with the f-number's decimal point as ``p`` (``bars_f5p6_small``)."""
    return f"{scene}_f{float(f_number):g}_{scene_preset}".replace(".", "p")


def parse_image_name(name: str) -> tuple[str, float, str] | None:
    """``(scene, f_number, scene_preset)`` of an :func:`image_name`, or None if ``name`` is not one."""
    m = _NAME.match(str(name))
    if m is None:
        return None
    return m.group("scene"), float(m.group("n").replace("p", ".")), m.group("preset")


def git_commit(root=None) -> str | None:
    """The checkout's ``git rev-parse HEAD`` (with ``+dirty`` if files are modified), None outside git."""
    root = Path(__file__).resolve().parents[1] if root is None else Path(root)
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=30)
        if head.returncode != 0:
            return None
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return None
    return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def is_complete(root, name: str) -> bool:
    """True when ``done/NAME.json`` (written after every other file of the image) exists."""
    return (Path(root) / "done" / f"{name}.json").is_file()


def _png_bytes(image_u, bits) -> bytes:
    """An HxWx3 (or HxW) integer array as 8- or 16-bit PNG bytes (imagecodecs; Pillow cannot write 16-bit RGB)."""
    import imagecodecs

    return imagecodecs.png_encode(np.ascontiguousarray(np.asarray(image_u).astype(np.uint8 if bits == 8 else np.uint16)))


def _write_png(path, image_u, bits):
    from defocus_cache import atomic_write_bytes

    atomic_write_bytes(path, _png_bytes(image_u, bits))


def _write_npy(path, array):
    from defocus_cache import atomic_write

    with atomic_write(path, suffix=".npy") as tmp:
        np.save(tmp, array)


def _write_exr(path, channels):
    from defocus_cache import atomic_write
    from scenes.exr import write_exr

    with atomic_write(path, suffix=".exr") as tmp:
        write_exr(tmp, channels)


def ground_truth_arrays(render) -> dict:
    """σ_gt (px), depth (m), CoC (px), occlusion-band and textured-pixel masks (HxW) of a render."""
    from .evaluation import ground_truth_sigma, input_image

    sigma = ground_truth_sigma(render)
    occ = np.asarray(render.occlusion_boundary, dtype=bool)
    masks = region_masks(input_image(render, encoding="srgb", quantize_bits=8), sigma, exclude=occ)
    return {"sigma": sigma.astype(np.float64), "depth": np.asarray(render.depth, dtype=np.float64),
            "coc": np.asarray(render.coc_px, dtype=np.float64), "occlusion": occ,
            "textured": masks["textured"]}


def noise_seed(name: str) -> int:
    """The seed of an exported image's sensor noise: CRC-32 of its name (the same on any machine)."""
    import zlib

    return zlib.crc32(name.encode("utf-8"))


def export_image(root, name: str, render, *, camera_preset: str | None = None, noise="none",
                 jpeg_quality: int | None = None) -> dict:
    """Write one image's files atomically, the completion record ``done/NAME.json`` last.

    Parameters
    ----------
    root : path
        Dataset folder.
    name : str
        :func:`image_name`.
    render : scenes.Render
    camera_preset : str, optional, keyword-only
        The :data:`scenes.CAMERA_PRESETS` name the render used (None: the scene's own camera).
    noise : str or (float, float), keyword-only
        Sensor noise of the camera pipeline (:data:`scenes.display.NOISE_LEVELS`), drawn from
        :func:`noise_seed` of the name, in the 8- and 16-bit images (the linear EXR stays the render).
    jpeg_quality : int or None, keyword-only
        JPEG quality of the 8-bit image (decoded and stored as PNG), None for none.

    Returns
    -------
    dict
        The manifest entry (camera, shape, the render's spp, seed, variant and sampler, the camera
        pipeline, files).
    """
    from scenes.display import noise_parameters

    root = Path(root)
    for sub in ("images", "gt", "done"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    seed = noise_seed(name)
    s8 = render.image(encoding="srgb", quantize_bits=8, noise=noise, jpeg_quality=jpeg_quality, rng=seed)
    s16 = render.image(encoding="srgb", quantize_bits=16, noise=noise, rng=seed)
    _write_png(root / "images" / f"{name}.png", np.rint(s8 * 255), 8)
    _write_png(root / "images" / f"{name}_16bit.png", np.rint(s16 * 65535), 16)
    lin = np.asarray(render.rgb, dtype=np.float32)
    _write_exr(root / "images" / f"{name}.exr", {"R": lin[..., 0], "G": lin[..., 1], "B": lin[..., 2]})
    files = [f"images/{name}.png", f"images/{name}_16bit.png", f"images/{name}.exr"]
    for field, arr in ground_truth_arrays(render).items():
        _write_npy(root / "gt" / f"{name}_{field}.npy", arr)
        _write_exr(root / "gt" / f"{name}_{field}.exr", {"Y": np.asarray(arr, dtype=np.float32)})
        files += [f"gt/{name}_{field}.npy", f"gt/{name}_{field}.exr"]
    meta = render.metadata
    entry = {"name": name, "shape": list(lin.shape[:2]), "camera": meta.get("camera"), "scene": meta.get("scene"),
             "camera_preset": camera_preset,
             "render": {k: meta.get(k) for k in ("spp", "seed", "variant", "sampler", "integrator", "pixel_filter")},
             "camera_pipeline": {"noise": noise if isinstance(noise, str) else None, **noise_parameters(noise),
                                 "noise_seed": seed, "tone_curve": "srgb", "jpeg_quality": jpeg_quality},
             "files": files}
    from defocus_cache import atomic_write_text

    atomic_write_text(root / "done" / f"{name}.json", json.dumps(entry, indent=1, sort_keys=True, default=str))
    return entry


def write_manifest(root, entries, *, render_settings: dict, harness: dict) -> Path:
    """Write ``manifest.json`` and ``README.md`` (atomically) from the completed images' entries."""
    from defocus_cache import atomic_write_text

    root = Path(root)
    manifest = {"layout_version": LAYOUT_VERSION, "naming": "<scene>_f<N>_<scene_preset>, '.' in N as 'p'",
                "sigma_convention": "line_spread: sigma_gt = sqrt((c/4)^2 + 1/12) px (box pixel filter)",
                "render_settings": render_settings, "harness": harness,
                "images": {e["name"]: e for e in entries}}
    atomic_write_text(root / "manifest.json", json.dumps(manifest, indent=1, sort_keys=True, default=str) + "\n")
    atomic_write_text(root / "README.md", "# Defocus dataset\n\nLayout version " + LAYOUT_VERSION +
                      ". See manifest.json; per image NAME: images/NAME.png (sRGB 8 bit), images/NAME_16bit.png, "
                      "images/NAME.exr (linear), gt/NAME_{sigma,depth,coc,occlusion,textured}.{npy,exr} "
                      "(sigma, coc in px; depth in m; masks 0/1). A map to score is MAPDIR/NAME.npy|npz|exr|png "
                      "(sigma in px; a 16-bit PNG holds sigma * 1000 unless scored with --png-scale): "
                      "python -m repro.evaluate --maps MAPDIR --dataset DIR.\n")
    return root / "manifest.json"


def read_dataset(root) -> dict:
    """The manifest of a dataset folder; ``ValueError`` for an unknown major layout version."""
    path = Path(root) / "manifest.json"
    if not path.is_file():
        raise ValueError(f"{Path(root)}: no manifest.json; allowed: a folder written by repro.dataset export")
    manifest = json.loads(path.read_text())
    version = str(manifest.get("layout_version", "?"))
    if version.split(".")[0] != LAYOUT_VERSION.split(".")[0]:
        raise ValueError(f"{path}: layout version {version!r} is unknown; allowed: major version "
                         f"{LAYOUT_VERSION.split('.')[0]} (this harness writes {LAYOUT_VERSION})")
    return manifest


def load_ground_truth(root, name: str) -> dict:
    """The ``.npy`` ground-truth fields of one image (:data:`GT_FIELDS`)."""
    return {f: np.load(Path(root) / "gt" / f"{name}_{f}.npy", allow_pickle=False) for f in GT_FIELDS}


def load_image(root, name: str) -> np.ndarray:
    """``images/NAME.png`` (sRGB, 8 bit) as an HxWx3 float64 image in [0, 1] (exactly the render's
    8-bit quantised sRGB input)."""
    import imageio.v3 as iio

    return np.asarray(iio.imread(Path(root) / "images" / f"{name}.png"), dtype=np.float64) / 255.0
