"""Score defocus maps made by any tool against the harness's ground truth, in the field's protocols.

A map is ``MAPDIR/NAME`` + one of :data:`MAP_SUFFIXES`, ``NAME`` an image of the dataset
(:func:`experiments.dataset.image_name`, e.g. ``planes_f8_small``): an HxW array of Gaussian σ in px
of the image's pixels (NaN = no estimate). ``.npy``; ``.npz`` (its first array); float EXR (its first
channel, read by :func:`scenes.exr.read_exr`); 16-bit PNG holding σ × ``png_scale`` (default
:data:`PNG_SCALE`: 0.001 px steps up to 65.5 px).

The ground truth comes from an exported dataset folder (:class:`DatasetTruth`; needs neither the
renderer nor the sweep engine) or from the harness's own renders of the same names
(:class:`RenderTruth`; cached renders, the renderer for missing ones).

Protocols (:data:`PROTOCOLS`), every one with the occlusion bands excluded:

``harness``
    MAE, RMSE and bias (mean signed error) of σ over all pixels and over textured pixels, the dense-map
    metrics the harness scores its own renders with (:func:`experiments.metrics.dense_metrics`, as
    :func:`experiments.scoring.score_render` does), and MAE and bias per σ_gt bin (:data:`SIGMA_BINS_PX`), px.
``rtf``
    D'Andrès et al. (TIP 2016), as used by DMENet (Lee et al., CVPR 2019): σ and σ_gt clipped at
    3.275 px and divided by it; MSE and MAE (:func:`experiments.metrics.rtf_normalized_errors`).
``syndof``
    Lee et al. (CVPR 2019): the reference is σ = (CoC − 1)/4 px from the exported CoC, 0 where
    CoC < 1 px; MSE (px²) and MAE (px).
``detection``
    Blur detection (CUHK, Shi et al., CVPR 2014): a pixel is blurred where σ > ``threshold_px``
    (default :data:`DETECTION_THRESHOLD_PX`), in the truth and in the map; accuracy and F-measure
    with blurred as the positive class.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from method.registry import Entry, Registry

from .dataset import ground_truth_arrays, image_name, load_ground_truth, load_image, parse_image_name, read_dataset
from .metrics import RTF_SIGMA_CLIP_PX, dense_metrics, rtf_normalized_errors, sparse_metrics

__all__ = ["DETECTION_THRESHOLD_PX", "HEADLINE", "MAP_SUFFIXES", "PNG_SCALE", "PROTOCOLS", "SIGMA_BINS_PX",
           "DatasetTruth", "MapScores", "RenderTruth", "detection_scores", "find_map", "flatten", "folder_maps",
           "load_map",
           "read_map", "score_folder", "score_map", "score_maps", "summarize", "syndof_sigma"]

#: Map file suffixes, in lookup order (the first present is read).
MAP_SUFFIXES = (".npy", ".npz", ".exr", ".png")
#: σ_gt bins [lo, hi) of the harness protocol, px.
SIGMA_BINS_PX = (0.0, 1.0, 2.0, 4.0, np.inf)
#: Default blurred/sharp threshold of the detection protocol, px.
DETECTION_THRESHOLD_PX = 1.0
#: Default scale of a 16-bit PNG map: σ (px) = value / PNG_SCALE.
PNG_SCALE = 1000.0


# ------------------------------------------------------------------------------------------------
# reading maps
# ------------------------------------------------------------------------------------------------


def find_map(mapdir, name: str) -> Path:
    """``MAPDIR/NAME`` with the first of :data:`MAP_SUFFIXES` that exists; ValueError naming it if none."""
    mapdir = Path(mapdir)
    for suffix in MAP_SUFFIXES:
        path = mapdir / f"{name}{suffix}"
        if path.is_file():
            return path
    raise ValueError(f"{mapdir / name}: no map (allowed: {name}{'|'.join(MAP_SUFFIXES)})")


def read_map(path, *, png_scale: float = PNG_SCALE) -> np.ndarray:
    """One map file as an HxW float64 σ map, px.

    Parameters
    ----------
    path : path
        ``.npy``, ``.npz`` (first array), ``.exr`` (first channel) or 16-bit ``.png`` (÷ ``png_scale``).
    png_scale : float, keyword-only
        PNG value per px of σ.

    Raises
    ------
    ValueError
        One line naming the file: unreadable, an 8-bit PNG (such as the colour preview the photo
        tools write for a ``.png`` map, which holds no σ), or not HxW.
    """
    path = Path(path)
    eight_bit = False
    try:
        if path.suffix == ".npy":
            arr = np.load(path, allow_pickle=False)
        elif path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                arr = z[z.files[0]]
        elif path.suffix == ".exr":
            from scenes.exr import read_exr

            arr = next(iter(read_exr(path).values()))
        elif path.suffix == ".png":
            import imageio.v3 as iio

            raw = iio.imread(path)
            eight_bit = raw.dtype == np.uint8
            if raw.dtype != np.uint16:
                raise ValueError(f"dtype {raw.dtype}; allowed: 16-bit PNG (σ × {png_scale:g})")
            arr = raw / float(png_scale)
        else:
            raise ValueError(f"suffix {path.suffix!r}; allowed: {', '.join(MAP_SUFFIXES)}")
    except Exception as exc:  # any decoder failure is the file's fault: one line naming it
        if eight_bit:
            raise ValueError(f"{path}: an 8-bit PNG holds no σ values (e.g. the colour preview that repro.estimate "
                             f"-o MAP.png / repro.magnify --save-map MAP.png write); allowed: a 16-bit PNG of "
                             f"σ × {png_scale:g}, .npy, .npz or float .exr") from None
        raise ValueError(f"{path}: unreadable ({' '.join(str(exc).split())})") from None
    arr = np.asarray(arr, dtype=np.float64)
    if arr.ndim == 3 and arr.shape[-1] == 1:
        arr = arr[..., 0]
    if arr.ndim != 2:
        raise ValueError(f"{path}: shape {arr.shape}; allowed: HxW")
    return arr


def load_map(mapdir, name: str, *, png_scale: float = PNG_SCALE) -> np.ndarray:
    """:func:`read_map` of :func:`find_map` (ValueError naming the file when missing or unreadable)."""
    return read_map(find_map(mapdir, name), png_scale=png_scale)


# ------------------------------------------------------------------------------------------------
# the protocols
# ------------------------------------------------------------------------------------------------


def syndof_sigma(coc_px) -> np.ndarray:
    """SYNDOF σ = (CoC − 1)/4 px, 0 where CoC < 1 px (Lee et al. 2019); NaN stays NaN."""
    c = np.asarray(coc_px, dtype=np.float64)
    return np.where(c < 1.0, 0.0, (c - 1.0) / 4.0)


def detection_scores(estimate, truth, *, threshold_px=DETECTION_THRESHOLD_PX, mask=None) -> dict:
    """Binary blur detection: blurred where σ > ``threshold_px``, blurred the positive class.

    Parameters
    ----------
    estimate, truth : ndarray, HxW, σ in px (NaN = none)
    threshold_px : float, keyword-only
    mask : ndarray of bool, HxW, optional, keyword-only

    Returns
    -------
    dict
        ``n`` (pixels), ``accuracy``, ``precision``, ``recall``, ``f_measure`` (harmonic mean of the
        two; 0 when both are 0); NaN when ``n == 0``.
    """
    est, gt = np.asarray(estimate, float), np.asarray(truth, float)
    ok = np.isfinite(est) & np.isfinite(gt)
    if mask is not None:
        ok &= np.asarray(mask, bool)
    p, t = est[ok] > threshold_px, gt[ok] > threshold_px
    n = int(ok.sum())
    if n == 0:
        nan = float("nan")
        return {"n": 0, "accuracy": nan, "precision": nan, "recall": nan, "f_measure": nan}
    tp = int(np.sum(p & t))
    prec = tp / max(int(p.sum()), 1)
    rec = tp / max(int(t.sum()), 1)
    f = 2 * prec * rec / (prec + rec) if prec + rec > 0 else 0.0
    return {"n": n, "accuracy": float(np.mean(p == t)), "precision": float(prec), "recall": float(rec),
            "f_measure": float(f)}


def _harness(est, gt, keep, threshold_px):
    """The dense-map metrics of a render's scorer (:func:`experiments.evaluation.evaluate_result`'s ``dense``,
    :func:`experiments.metrics.dense_metrics`) over all and textured pixels, plus MAE and bias per σ_gt bin."""
    sigma = np.asarray(gt["sigma"], dtype=np.float64)
    out = dense_metrics(est, sigma, regions={"all": keep, "textured": keep & np.asarray(gt["textured"], bool)})
    for lo, hi in zip(SIGMA_BINS_PX[:-1], SIGMA_BINS_PX[1:]):
        m = sparse_metrics(est, sigma, mask=keep & (sigma >= lo) & (sigma < hi))
        out[f"bin_{lo:g}_{hi:g}"] = {"n": m["n"], "mae": m["mae"], "bias": m["bias"]}
    return out


def _rtf(est, gt, keep, threshold_px):
    return rtf_normalized_errors(est, gt["sigma"], mask=keep, clip_px=RTF_SIGMA_CLIP_PX)


def _syndof(est, gt, keep, threshold_px):
    m = sparse_metrics(est, syndof_sigma(gt["coc"]), mask=keep)
    return {"n": m["n"], "mse": m["rmse"] ** 2, "mae": m["mae"], "bias": m["bias"]}


def _detection(est, gt, keep, threshold_px):
    return detection_scores(est, gt["sigma"], threshold_px=threshold_px, mask=keep)


#: Protocol name -> scoring function ``(estimate, ground truth fields, kept pixels, threshold_px) -> dict``.
PROTOCOLS = Registry("protocol", {
    "harness": Entry(_harness, "MAE, RMSE, bias of σ over all / textured pixels and per σ_gt bin, px"),
    "rtf": Entry(_rtf, "D'Andrès et al. 2016: σ clipped at 3.275 px and ÷ 3.275; MSE, MAE"),
    "syndof": Entry(_syndof, "Lee et al. 2019: reference σ = (CoC − 1)/4, 0 where CoC < 1; MSE (px²), MAE (px)"),
    "detection": Entry(_detection, "Shi et al. 2014: blurred where σ > threshold; accuracy, F-measure"),
})

#: Per protocol, the flat metric keys (:func:`flatten`) a leaderboard shows, with their labels.
HEADLINE = {
    "harness": (("all_mae", "MAE (px)"), ("all_bias", "bias (px)"), ("textured_mae", "MAE textured (px)")),
    "rtf": (("nmse", "nMSE"), ("nmae", "nMAE")),
    "syndof": (("mse", "MSE (px²)"), ("mae", "MAE (px)")),
    "detection": (("accuracy", "accuracy"), ("f_measure", "F-measure")),
}


def score_map(estimate, gt: dict, *, protocol: str = "harness", threshold_px=DETECTION_THRESHOLD_PX) -> dict:
    """Score one HxW σ map (px) against one image's ground truth.

    Parameters
    ----------
    estimate : ndarray, HxW, σ in px (NaN = no estimate)
    gt : dict
        The fields of :func:`experiments.dataset.load_ground_truth`: ``sigma`` (px), ``coc`` (px),
        ``occlusion`` and ``textured`` (bool), HxW.
    protocol : str, keyword-only
        Key of :data:`PROTOCOLS`.
    threshold_px : float, keyword-only
        The detection protocol's blurred/sharp threshold.

    Returns
    -------
    dict
        The protocol's metrics (nested for ``harness``).

    Raises
    ------
    ValueError
        An unknown protocol, a shape that is not the ground truth's, or a map without a finite value.
    """
    score = PROTOCOLS[PROTOCOLS.check(protocol, what="protocol")]
    est = np.asarray(estimate, dtype=np.float64)
    sigma = np.asarray(gt["sigma"], dtype=np.float64)
    if est.shape != sigma.shape:
        raise ValueError(f"shape {est.shape[::-1] if est.ndim == 2 else est.shape} (WxH) != the image's "
                         f"{sigma.shape[::-1]}")
    if not np.isfinite(est).any():
        raise ValueError("no finite value (NaN-only map)")
    keep = np.isfinite(sigma) & ~np.asarray(gt["occlusion"], bool)
    return score(est, gt, keep, float(threshold_px))


def flatten(d: dict, prefix: str = "") -> dict:
    """Nested metrics -> ``{"all_mae": ...}``."""
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(flatten(v, f"{prefix}{k}_"))
        else:
            out[f"{prefix}{k}"] = v
    return out


# ------------------------------------------------------------------------------------------------
# ground truth: an exported dataset, or the harness's renders
# ------------------------------------------------------------------------------------------------


class DatasetTruth:
    """The images and ground truth of a folder written by ``repro.dataset export``.

    Reads only ``manifest.json``, ``gt/*.npy`` and ``images/*.png`` (no renderer). ValueError for a
    folder without a manifest or with a layout of an unknown major version.
    """

    def __init__(self, root):
        self.root = Path(root)
        self.manifest = read_dataset(self.root)
        self.names = sorted(self.manifest.get("images", {}))
        self.source = str(self.root)

    def scene(self, name: str) -> str:
        entry = self.manifest["images"].get(name, {})
        parsed = parse_image_name(name)
        return str(entry.get("scene") or (parsed[0] if parsed else name))

    def ground_truth(self, name: str) -> dict:
        return load_ground_truth(self.root, name)

    def image(self, name: str) -> np.ndarray:
        """HxWx3 float64 in [0, 1]: the 8-bit sRGB PNG."""
        return load_image(self.root, name)


class RenderTruth:
    """The harness's own renders (scene's own camera) of the images ``<scene>_f<N>_<scene_preset>``.

    Parameters
    ----------
    names : iterable of str
        :func:`experiments.dataset.image_name` values.
    variant : str, optional, keyword-only
        Mitsuba variant.

    Renders are read from the render cache (rendered through it when missing); one is kept in memory.
    """

    def __init__(self, names: Iterable[str], *, variant: str | None = None):
        self.names = sorted(dict.fromkeys(names))
        bad = [n for n in self.names if parse_image_name(n) is None]
        if bad:
            raise ValueError(f"image name(s) {', '.join(map(repr, bad))} are invalid; allowed: "
                             "<scene>_f<N>_<scene_preset>, e.g. 'planes_f8_small'")
        self.variant = variant
        self.source = "harness renders (render cache)"
        self._last = (None, None)

    def scene(self, name: str) -> str:
        return parse_image_name(name)[0]

    def render(self, name: str):
        if self._last[0] != name:
            from scenes import render_scene

            scene, n, preset = parse_image_name(name)
            self._last = (name, render_scene(scene, preset=preset, f_number=n, variant=self.variant, progress=False))
        return self._last[1]

    def ground_truth(self, name: str) -> dict:
        return ground_truth_arrays(self.render(name))

    def image(self, name: str) -> np.ndarray:
        return self.render(name).image(encoding="srgb", quantize_bits=8)

    @classmethod
    def named_by(cls, folders, *, variant: str | None = None) -> "RenderTruth":
        """The renders named by the map files of ``folders``: every file stem that is an image name
        of a known scene with a valid f-number and resolution preset (other files are left to
        :func:`score_folder`'s "unknown name" lines)."""
        from scenes import SCENES
        from scenes.render import validate_render_options

        names = []
        for stem in sorted({p.stem for f in folders if Path(f).is_dir() for p in Path(f).iterdir() if p.is_file()}):
            parsed = parse_image_name(stem)
            if parsed is None or parsed[0] not in SCENES:
                continue
            try:
                validate_render_options(parsed[0], preset=parsed[2], f_number=parsed[1])
            except ValueError:
                continue
            names.append(stem)
        return cls(names, variant=variant)

    @staticmethod
    def grid(scenes, f_numbers, scene_preset: str) -> list[str]:
        """The image names of a scene × f-number grid at one resolution preset."""
        return [image_name(s, n, scene_preset) for s in scenes for n in f_numbers]


# ------------------------------------------------------------------------------------------------
# scoring many maps
# ------------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class MapScores:
    """The scores of one set of maps.

    Attributes
    ----------
    rows : list of dict
        One per scored image × protocol, sorted: ``image``, ``scene``, ``protocol``, ``map`` (file or
        source), and the protocol's :func:`flatten`-ed metrics.
    problems : list of str
        One line per map that could not be scored, naming it (missing, misnamed, wrongly sized,
        NaN-only, unreadable), sorted.
    scored : list of str
        The images scored.
    """

    rows: list
    problems: list
    scored: list


def score_maps(get_map: Callable[[str], tuple[np.ndarray, str]], truth, *, protocols=("harness",),
               threshold_px: float = DETECTION_THRESHOLD_PX, names=None) -> MapScores:
    """Score one map per image of ``truth`` in each protocol; a map that cannot be scored is a problem line.

    Parameters
    ----------
    get_map : callable
        ``name -> (HxW σ map in px, what to call it in messages)``; raises ValueError (one line) when
        the map is missing or unreadable.
    truth : DatasetTruth or RenderTruth
    protocols : sequence of str, keyword-only
        Keys of :data:`PROTOCOLS`.
    threshold_px : float, keyword-only
        Detection threshold.
    names : sequence of str, optional, keyword-only
        Images to score (default: all of ``truth``).
    """
    protocols = PROTOCOLS.check_all(dict.fromkeys(protocols), what="protocol")
    rows, problems, scored = [], [], []
    for name in sorted(truth.names if names is None else names):
        try:
            est, label = get_map(name)
        except ValueError as exc:
            problems.append(" ".join(str(exc).split()))
            continue
        gt = truth.ground_truth(name)
        try:
            out = [(p, score_map(est, gt, protocol=p, threshold_px=threshold_px)) for p in protocols]
        except ValueError as exc:
            problems.append(f"{label}: {' '.join(str(exc).split())}")
            continue
        scored.append(name)
        rows += [{"image": name, "scene": truth.scene(name), "protocol": p, "map": label, **flatten(m)}
                 for p, m in out]
    return MapScores(rows=rows, problems=sorted(problems), scored=scored)


def folder_maps(mapdir, *, png_scale: float = PNG_SCALE) -> Callable[[str], tuple[np.ndarray, str]]:
    """``name -> (the map MAPDIR/NAME.<suffix> as HxW σ px, its path)``, the ``get_map`` of :func:`score_maps`."""
    mapdir = Path(mapdir)

    def get(name):
        path = find_map(mapdir, name)
        return read_map(path, png_scale=png_scale), str(path)

    return get


def score_folder(mapdir, truth, *, protocols=("harness",), threshold_px: float = DETECTION_THRESHOLD_PX,
                 png_scale: float = PNG_SCALE) -> MapScores:
    """:func:`score_maps` of the files ``MAPDIR/NAME.<suffix>``, plus one problem per file of MAPDIR
    that names no image of ``truth`` (misnamed) and per map shadowed by another suffix.

    Raises
    ------
    ValueError
        When ``mapdir`` is not a folder.
    """
    mapdir = Path(mapdir)
    if not mapdir.is_dir():
        raise ValueError(f"--maps {str(mapdir)!r} is not a folder; allowed: a folder of NAME.npy|npz|exr|png maps")

    result = score_maps(folder_maps(mapdir, png_scale=png_scale), truth, protocols=protocols,
                        threshold_px=threshold_px)
    known = set(truth.names)
    extra = []
    for path in sorted(p for p in mapdir.iterdir() if p.is_file() and not p.name.startswith(".")):
        if path.suffix not in MAP_SUFFIXES:
            extra.append(f"{path}: not a map (allowed suffixes: {', '.join(MAP_SUFFIXES)})")
        elif path.stem not in known:
            example = f"; e.g. {truth.names[0]!r}" if truth.names else ""
            extra.append(f"{path}: unknown name (no image {path.stem!r} in {truth.source}{example})")
        elif find_map(mapdir, path.stem) != path:
            extra.append(f"{path}: ignored ({find_map(mapdir, path.stem).name} is read for {path.stem})")
    return MapScores(rows=result.rows, problems=sorted(result.problems + extra), scored=result.scored)


def summarize(rows, *, by=("protocol",)) -> list[dict]:
    """Mean over images of every numeric metric, per group of ``by`` columns (sorted).

    Returns
    -------
    list of dict
        ``{**group, "n_images": k, metric: mean}``; a metric NaN in an image is left out of its mean.
    """
    groups: dict[tuple, list] = {}
    for r in rows:
        groups.setdefault(tuple(r[k] for k in by), []).append(r)
    out = []
    for key in sorted(groups):
        rs = groups[key]
        metrics = {}
        for k in rs[0]:
            if k in ("image", "scene", "protocol", "map", *by):
                continue
            vals = np.array([r.get(k) for r in rs if isinstance(r.get(k), (int, float))], dtype=float)
            vals = vals[np.isfinite(vals)]
            metrics[k] = float(vals.mean()) if vals.size else float("nan")
        out.append({**dict(zip(by, key)), "n_images": len(rs), **metrics})
    return out
