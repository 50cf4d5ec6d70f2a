"""A versioned on-disk dataset of the rendered scenes, external defocus maps, and the field's protocols.

Layout (:data:`LAYOUT_VERSION`), per image ``NAME = <scene>_f<N>_<scene_preset>`` (N with ``p`` for
the decimal point, e.g. ``bars_f8_small``, ``bars_f5p6_small``):

``images/NAME.png`` (sRGB 8 bit), ``images/NAME_16bit.png`` (sRGB 16 bit), ``images/NAME.exr``
(linear radiance), ``gt/NAME_{sigma,depth,coc,occlusion,textured}.{exr,npy}``, ``done/NAME.json``
(the per-image completion record, written last), ``manifest.json`` and ``README.md``.

Protocols (:data:`PROTOCOLS`): ``harness`` (MAE, bias, per-σ bins over all and textured pixels,
occlusion bands excluded), ``rtf`` (σ clipped at 3.275 px and divided by it, MSE and MAE),
``syndof`` (σ = (CoC − 1)/4, 0 where CoC < 1), ``detection`` (blurred where σ > a threshold:
accuracy and F-measure).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .metrics import RTF_SIGMA_CLIP_PX, region_masks, rtf_normalized_errors, sparse_metrics

__all__ = ["GT_FIELDS", "LAYOUT_VERSION", "MAP_SUFFIXES", "PROTOCOLS", "SIGMA_BINS_PX", "export_image",
           "image_name", "is_complete", "load_map", "read_dataset", "score_map", "write_manifest"]

#: "major.minor"; a reader refuses another major version.
LAYOUT_VERSION = "1.0"
#: Ground-truth fields written per image.
GT_FIELDS = ("sigma", "depth", "coc", "occlusion", "textured")
#: Map file suffixes accepted by :func:`load_map`, in lookup order.
MAP_SUFFIXES = (".npy", ".npz", ".exr", ".png")
PROTOCOLS = ("harness", "rtf", "syndof", "detection")
#: σ_gt bins [lo, hi) of the harness protocol, px.
SIGMA_BINS_PX = (0.0, 1.0, 2.0, 4.0, np.inf)
#: Default blurred/sharp threshold of the detection protocol, px.
DETECTION_THRESHOLD_PX = 1.0
#: Default scale of a 16-bit PNG map: σ (px) = value / PNG_SCALE.
PNG_SCALE = 1000.0


def image_name(scene: str, f_number: float, scene_preset: str) -> str:
    """``<scene>_f<N>_<scene_preset>`` with the f-number's decimal point as ``p`` (``bars_f5p6_small``)."""
    return f"{scene}_f{float(f_number):g}_{scene_preset}".replace(".", "p")


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


def export_image(root, name: str, render) -> dict:
    """Write one image's files atomically, the completion record ``done/NAME.json`` last.

    Parameters
    ----------
    root : path
        Dataset folder.
    name : str
        :func:`image_name`.
    render : scenes.Render

    Returns
    -------
    dict
        The manifest entry (camera, shape, files).
    """
    root = Path(root)
    for sub in ("images", "gt", "done"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    s8 = render.image(encoding="srgb", quantize_bits=8)
    s16 = render.image(encoding="srgb", quantize_bits=16)
    _write_png(root / "images" / f"{name}.png", np.rint(s8 * 255), 8)
    _write_png(root / "images" / f"{name}_16bit.png", np.rint(s16 * 65535), 16)
    lin = np.asarray(render.rgb, dtype=np.float32)
    _write_exr(root / "images" / f"{name}.exr", {"R": lin[..., 0], "G": lin[..., 1], "B": lin[..., 2]})
    files = [f"images/{name}.png", f"images/{name}_16bit.png", f"images/{name}.exr"]
    for field, arr in ground_truth_arrays(render).items():
        _write_npy(root / "gt" / f"{name}_{field}.npy", arr)
        _write_exr(root / "gt" / f"{name}_{field}.exr", {"Y": np.asarray(arr, dtype=np.float32)})
        files += [f"gt/{name}_{field}.npy", f"gt/{name}_{field}.exr"]
    entry = {"name": name, "shape": list(lin.shape[:2]), "camera": render.metadata.get("camera"),
             "scene": render.metadata.get("scene"), "files": files}
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
                      "(sigma, coc in px; depth in m; masks 0/1). A map to score is MAPDIR/NAME.npy|npz|exr|png.\n")
    return root / "manifest.json"


def read_dataset(root) -> dict:
    """The manifest of a dataset folder; ``ValueError`` for an unknown major layout version."""
    path = Path(root) / "manifest.json"
    manifest = json.loads(path.read_text())
    version = str(manifest.get("layout_version", "?"))
    if version.split(".")[0] != LAYOUT_VERSION.split(".")[0]:
        raise ValueError(f"{path}: layout version {version!r} is unknown; allowed: major version "
                         f"{LAYOUT_VERSION.split('.')[0]} (this harness writes {LAYOUT_VERSION})")
    return manifest


def load_ground_truth(root, name: str) -> dict:
    """The ``.npy`` ground-truth fields of one image (:data:`GT_FIELDS`)."""
    return {f: np.load(Path(root) / "gt" / f"{name}_{f}.npy", allow_pickle=False) for f in GT_FIELDS}


def load_map(mapdir, name: str, *, png_scale: float = PNG_SCALE) -> np.ndarray:
    """Read ``MAPDIR/NAME`` + one of :data:`MAP_SUFFIXES` as an HxW float64 σ map (px).

    ``.npz`` takes its first array; EXR its first channel; a 16-bit PNG is divided by ``png_scale``.
    Raises ``ValueError`` (one line naming the file) when missing, unreadable or not 2-D.
    """
    mapdir = Path(mapdir)
    path = next((mapdir / f"{name}{s}" for s in MAP_SUFFIXES if (mapdir / f"{name}{s}").is_file()), None)
    if path is None:
        raise ValueError(f"{mapdir / name}: no map (allowed: {', '.join(MAP_SUFFIXES)})")
    try:
        if path.suffix == ".npy":
            arr = np.load(path, allow_pickle=False)
        elif path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                arr = z[z.files[0]]
        elif path.suffix == ".exr":
            from scenes.exr import read_exr

            arr = next(iter(read_exr(path).values()))
        else:
            import imageio.v3 as iio

            raw = iio.imread(path)
            if raw.dtype != np.uint16:
                raise ValueError(f"dtype {raw.dtype}; allowed: 16-bit PNG")
            arr = raw / float(png_scale)
    except Exception as exc:  # any decoder failure is the file's fault: one line naming it
        raise ValueError(f"{path}: unreadable ({' '.join(str(exc).split())})") from None
    arr = np.asarray(arr, dtype=np.float64)
    if arr.ndim == 3 and arr.shape[-1] == 1:
        arr = arr[..., 0]
    if arr.ndim != 2:
        raise ValueError(f"{path}: shape {arr.shape}; allowed: HxW")
    return arr


def syndof_sigma(coc_px) -> np.ndarray:
    """SYNDOF σ = (CoC − 1)/4 px, 0 where CoC < 1 (Lee et al. 2019)."""
    c = np.asarray(coc_px, dtype=np.float64)
    return np.where(c < 1.0, 0.0, (c - 1.0) / 4.0)


def detection_scores(estimate, truth, *, threshold_px=DETECTION_THRESHOLD_PX, mask=None) -> dict:
    """Binary blur detection: blurred where σ > ``threshold_px``; accuracy and F-measure (blurred = positive)."""
    est, gt = np.asarray(estimate, float), np.asarray(truth, float)
    ok = np.isfinite(est) & np.isfinite(gt)
    if mask is not None:
        ok &= np.asarray(mask, bool)
    p, t = est[ok] > threshold_px, gt[ok] > threshold_px
    n = int(ok.sum())
    if n == 0:
        return {"n": 0, "accuracy": float("nan"), "f_measure": float("nan")}
    tp = int(np.sum(p & t))
    prec = tp / max(int(p.sum()), 1)
    rec = tp / max(int(t.sum()), 1)
    f = 2 * prec * rec / (prec + rec) if prec + rec > 0 else 0.0
    return {"n": n, "accuracy": float(np.mean(p == t)), "f_measure": float(f), "precision": prec, "recall": rec}


def score_map(estimate, gt: dict, *, protocol: str = "harness", threshold_px=DETECTION_THRESHOLD_PX) -> dict:
    """Score one HxW σ map (px) against an image's ground truth (:func:`load_ground_truth` fields).

    Occlusion bands are excluded in every protocol. Raises ``ValueError`` on a shape mismatch, an
    all-NaN map or an unknown protocol.
    """
    if protocol not in PROTOCOLS:
        raise ValueError(f"protocol={protocol!r} is invalid; allowed: {list(PROTOCOLS)}")
    est = np.asarray(estimate, dtype=np.float64)
    sigma = np.asarray(gt["sigma"], dtype=np.float64)
    if est.shape != sigma.shape:
        raise ValueError(f"shape {est.shape} != ground truth {sigma.shape}")
    if not np.isfinite(est).any():
        raise ValueError("no finite value (NaN-only map)")
    keep = np.isfinite(sigma) & ~np.asarray(gt["occlusion"], bool)
    if protocol == "rtf":
        return rtf_normalized_errors(est, sigma, mask=keep, clip_px=RTF_SIGMA_CLIP_PX)
    if protocol == "syndof":
        m = sparse_metrics(est, syndof_sigma(gt["coc"]), mask=keep)
        return {"n": m["n"], "mse": m["rmse"] ** 2, "mae": m["mae"], "bias": m["bias"]}
    if protocol == "detection":
        return detection_scores(est, sigma, threshold_px=threshold_px, mask=keep)
    out = {"all": sparse_metrics(est, sigma, mask=keep),
           "textured": sparse_metrics(est, sigma, mask=keep & np.asarray(gt["textured"], bool))}
    for lo, hi in zip(SIGMA_BINS_PX[:-1], SIGMA_BINS_PX[1:]):
        m = sparse_metrics(est, sigma, mask=keep & (sigma >= lo) & (sigma < hi))
        out[f"bin_{lo:g}_{hi:g}"] = {"n": m["n"], "mae": m["mae"], "bias": m["bias"]}
    return out
