"""Real photos with hand-drawn "in focus" and "defocused" regions, and the scores of a defocus map on them.

The photos are the ones shipped inside installed packages (``skimage.data``: no download). Each has a
region file ``experiments/photos/<name>.json`` (installed as package data) with polygons drawn by hand
by looking at the photo, before any defocus map was computed on it, and conservative: only pixels
whose label is certain (see ``docs/real-photos.md``). A real photo has no ground-truth σ, but its
labels say which pixels must come out sharper than which:

- **ranking AUC** = P(σ_defocused > σ_in-focus) over all (defocused pixel, in-focus pixel) pairs, ties
  counting half: the Mann–Whitney U statistic of the two samples divided by n_d·n_f (1 = every
  defocused pixel is blurrier than every in-focus one, 0.5 = no ranking, 0 = inverted);
- **in-focus share above the defocused median** = the fraction of in-focus pixels whose σ exceeds the
  median σ of the defocused region (0 is right; the targets allow at most :data:`TARGET_SHARE`).

Region file format (JSON): ``photo`` (its name, = the file's stem), ``source`` (``"skimage.data.<fn>"``),
``shape`` ([H, W, 3] of the photo as loaded), ``regions``: a list of {``label``: ``"in_focus"`` or
``"defocused"``, ``polygon``: [[x, y], ...] ≥ 3 vertices in pixels (x = column, y = row, pixel
centres at integers, inside the photo), ``why``: one line}; free-text ``description`` etc. may follow.
"""

from __future__ import annotations

import dataclasses
import json
import time
import warnings
from pathlib import Path

import numpy as np

__all__ = [
    "LABELS",
    "PHOTO_DIR",
    "SCORE_PRESETS",
    "TARGET_AUC",
    "TARGET_SHARE",
    "PhotoRegions",
    "Region",
    "available_photos",
    "compute_photo_maps",
    "in_focus_share_above_median",
    "load_photo_image",
    "load_regions",
    "ranking_auc",
    "rasterise_polygon",
    "score_defocus_map",
    "score_photo",
    "score_presets",
    "validate_photo_names",
]

#: Folder of the shipped region files (package data of ``experiments``).
PHOTO_DIR = Path(__file__).resolve().parent / "photos"
#: Region labels a region file may use (each must appear at least once).
LABELS = ("in_focus", "defocused")
#: Method presets scored by default (:data:`method.PRESETS`).
SCORE_PRESETS = ("paper", "robust", "zhuo_sim")
#: Target ranking AUC on every photo (the defocused region ranked blurrier).
TARGET_AUC = 0.95
#: Target maximum share of in-focus pixels blurrier than the defocused region's median.
TARGET_SHARE = 0.02
#: Allowed prefix of a region file's ``source``: a function of ``skimage.data`` returning an RGB photo.
_SOURCE_PREFIX = "skimage.data."


@dataclasses.dataclass(frozen=True)
class Region:
    """One hand-drawn region: its label, polygon (V, 2) [x, y] px, and why it has that label."""

    label: str
    polygon: tuple[tuple[float, float], ...]
    why: str


@dataclasses.dataclass(frozen=True)
class PhotoRegions:
    """A validated region file.

    Attributes
    ----------
    photo : str
        Photo name (the file's stem).
    source : str
        ``"skimage.data.<fn>"``.
    shape : tuple of int
        (H, W, 3) of the photo as loaded, px.
    regions : tuple of Region
    path : Path
        The region file.
    """

    photo: str
    source: str
    shape: tuple[int, ...]
    regions: tuple[Region, ...]
    path: Path

    def masks(self) -> dict[str, np.ndarray]:
        """``{label: (H, W) bool}``: the union of the label's polygons (:func:`rasterise_polygon`)."""
        hw = self.shape[:2]
        out = {label: np.zeros(hw, dtype=bool) for label in LABELS}
        for r in self.regions:
            out[r.label] |= rasterise_polygon(r.polygon, hw)
        return out


def available_photos(photo_dir=None) -> tuple[str, ...]:
    """Names of the photos with a region file in ``photo_dir`` (default :data:`PHOTO_DIR`), sorted."""
    folder = Path(photo_dir) if photo_dir is not None else PHOTO_DIR
    return tuple(sorted(p.stem for p in folder.glob("*.json") if not p.name.startswith(".")))


def validate_photo_names(names, photo_dir=None) -> tuple[str, ...]:
    """``names`` (default: every available photo) checked against :func:`available_photos`, duplicates dropped.

    Raises
    ------
    ValueError
        An unknown name (one line naming the allowed values).
    """
    allowed = available_photos(photo_dir)
    names = tuple(dict.fromkeys(names)) if names else allowed
    bad = [n for n in names if n not in allowed]
    if bad:
        raise ValueError(f"unknown photo(s) {', '.join(map(repr, bad))}; allowed: {list(allowed)}")
    return names


def load_photo_image(source: str) -> np.ndarray:
    """The photo of a region file's ``source``, as (H, W, 3) float64 in [0, 1] (sRGB-encoded, 8-bit).

    Parameters
    ----------
    source : str
        ``"skimage.data.<fn>"`` with ``fn`` a loader of an 8-bit RGB(A) photo (alpha dropped).

    Raises
    ------
    ValueError
        Any other source, or a loader that does not return an 8-bit RGB image.
    """
    import skimage.data

    fn = source[len(_SOURCE_PREFIX):] if isinstance(source, str) and source.startswith(_SOURCE_PREFIX) else ""
    loader = getattr(skimage.data, fn, None) if fn and not fn.startswith("_") else None
    if not callable(loader):
        raise ValueError(f"photo source {source!r} is unknown; allowed: 'skimage.data.<function>' of an RGB photo")
    img = np.asarray(loader())
    if img.ndim != 3 or img.shape[2] not in (3, 4) or img.dtype != np.uint8:
        raise ValueError(f"photo source {source!r} is not an 8-bit RGB photo (shape {img.shape}, {img.dtype}); "
                         "allowed: 'skimage.data.<function>' of an RGB photo")
    return img[..., :3].astype(np.float64) / 255.0


def rasterise_polygon(polygon, shape) -> np.ndarray:
    """The pixels inside a polygon, as an (H, W) bool mask (:func:`skimage.draw.polygon`).

    Parameters
    ----------
    polygon : array_like, (V, 2), px
        Vertices [x, y] (x = column, y = row; pixel centres at integers), V ≥ 3.
    shape : tuple of int
        (H, W) of the mask (further entries ignored).

    Returns
    -------
    ndarray, (H, W), bool
        True at the pixel centres inside the polygon (clipped to the image).
    """
    from skimage.draw import polygon as draw_polygon

    xy = np.asarray(polygon, dtype=np.float64)
    if xy.ndim != 2 or xy.shape[1] != 2 or xy.shape[0] < 3 or not np.isfinite(xy).all():
        raise ValueError(f"polygon of shape {xy.shape} is invalid; allowed: (V, 2) finite [x, y] vertices, V >= 3")
    h, w = int(shape[0]), int(shape[1])
    mask = np.zeros((h, w), dtype=bool)
    rr, cc = draw_polygon(xy[:, 1], xy[:, 0], shape=(h, w))
    mask[rr, cc] = True
    return mask


def _fail(path, what: str):
    raise ValueError(f"region file {path}: {what}")


def load_regions(name_or_path, *, photo_dir=None, check_photo: bool = True) -> PhotoRegions:
    """Load and validate a region file.

    Parameters
    ----------
    name_or_path : str or Path
        A photo name of :func:`available_photos` or the path of a ``.json`` region file.
    photo_dir : path, optional, keyword-only
        Folder of the region files for a name (default :data:`PHOTO_DIR`).
    check_photo : bool, keyword-only
        Load the photo and require its shape to equal the file's ``shape`` (default True).

    Returns
    -------
    PhotoRegions

    Raises
    ------
    ValueError
        Unknown photo name; a file that is not JSON or lacks a field; a ``photo`` that is not the
        file's stem; an unknown source; a ``shape`` that does not match the photo; an unknown label;
        a polygon with < 3 vertices or a vertex outside the photo; a label with no region or no
        pixel; pixels labelled both ways. One line naming the file and the allowed values.

    Notes
    -----
    1. Parse the JSON; check the fields and their types.
    2. Load the photo from ``source`` and compare its shape with ``shape``.
    3. Check every polygon lies inside [0, W−1] × [0, H−1] and has ≥ 3 vertices.
    4. Rasterise (:meth:`PhotoRegions.masks`): each label non-empty, the labels disjoint.
    """
    p = Path(name_or_path)
    if p.suffix == ".json" or p.exists():
        path = p
    else:
        (name,) = validate_photo_names([str(name_or_path)], photo_dir)
        path = (Path(photo_dir) if photo_dir is not None else PHOTO_DIR) / f"{name}.json"
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        _fail(path, "not found; allowed: an existing region file or a photo of " + str(list(available_photos(photo_dir))))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        _fail(path, f"is not JSON ({exc}); allowed: a JSON object with photo, source, shape, regions")
    if not isinstance(doc, dict):
        _fail(path, "is not a JSON object; allowed: an object with photo, source, shape, regions")
    missing = [k for k in ("photo", "source", "shape", "regions") if k not in doc]
    if missing:
        _fail(path, f"lacks {', '.join(missing)}; allowed: an object with photo, source, shape, regions")
    if doc["photo"] != path.stem:
        _fail(path, f"photo {doc['photo']!r} is not the file's name; allowed: {path.stem!r}")
    shape = doc["shape"]
    if (not isinstance(shape, list) or len(shape) != 3 or shape[2] != 3
            or not all(isinstance(s, int) and s > 0 for s in shape)):
        _fail(path, f"shape {shape!r} is invalid; allowed: [H, W, 3] positive integers")
    if check_photo:
        try:
            image = load_photo_image(doc["source"])
        except ValueError as exc:
            _fail(path, str(exc))
        if list(image.shape) != shape:
            _fail(path, f"shape {shape} does not fit its photo {doc['source']}; allowed: {list(image.shape)}")
    elif not (isinstance(doc["source"], str) and doc["source"].startswith(_SOURCE_PREFIX)):
        _fail(path, f"photo source {doc['source']!r} is unknown; allowed: 'skimage.data.<function>' of an RGB photo")
    h, w = shape[0], shape[1]
    if not isinstance(doc["regions"], list) or not doc["regions"]:
        _fail(path, f"has no regions; allowed: a non-empty list of regions labelled {list(LABELS)}")
    regions = []
    for i, r in enumerate(doc["regions"]):
        if not isinstance(r, dict) or r.get("label") not in LABELS:
            label = r.get("label") if isinstance(r, dict) else r
            _fail(path, f"region {i} has label {label!r}; allowed: {list(LABELS)}")
        poly = r.get("polygon")
        try:
            xy = np.asarray(poly, dtype=np.float64)
        except (TypeError, ValueError):
            xy = np.empty((0,))
        if xy.ndim != 2 or xy.shape[1] != 2 or xy.shape[0] < 3 or not np.isfinite(xy).all():
            _fail(path, f"region {i} polygon is invalid; allowed: a list of >= 3 [x, y] vertices")
        if xy[:, 0].min() < 0 or xy[:, 0].max() > w - 1 or xy[:, 1].min() < 0 or xy[:, 1].max() > h - 1:
            _fail(path, f"region {i} polygon leaves the photo; allowed: 0 <= x <= {w - 1}, 0 <= y <= {h - 1}")
        regions.append(Region(label=r["label"], polygon=tuple(map(tuple, xy.tolist())), why=str(r.get("why", ""))))
    out = PhotoRegions(photo=doc["photo"], source=doc["source"], shape=tuple(shape), regions=tuple(regions),
                       path=path)
    masks = out.masks()
    for label in LABELS:
        if not masks[label].any():
            _fail(path, f"the {label!r} regions are empty; allowed: at least one polygon with pixels per label {list(LABELS)}")
    if (masks["in_focus"] & masks["defocused"]).any():
        _fail(path, "pixels are labelled both in_focus and defocused; allowed: disjoint regions")
    return out


def _ranking_auc(a: np.ndarray, b: np.ndarray) -> float:
    from scipy.stats import rankdata

    ranks = rankdata(np.concatenate([a, b]))  # average ranks: a tie counts half
    u = ranks[a.size:].sum() - b.size * (b.size + 1) / 2.0
    return float(u / (a.size * b.size))


def _samples(sigma_in_focus, sigma_defocused):
    a = np.asarray(sigma_in_focus, dtype=np.float64).ravel()
    b = np.asarray(sigma_defocused, dtype=np.float64).ravel()
    if a.size == 0 or b.size == 0:
        raise ValueError(f"empty sample (in focus {a.size}, defocused {b.size} values); allowed: >= 1 value each")
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise ValueError("σ values contain NaN or Inf; allowed: finite values")
    return a, b


def ranking_auc(sigma_in_focus, sigma_defocused) -> float:
    """P(σ_defocused > σ_in-focus) over all pixel pairs, ties counting half (Mann–Whitney U / n_f·n_d).

    Parameters
    ----------
    sigma_in_focus : array_like, (n_f,), px
        Map values at the in-focus pixels.
    sigma_defocused : array_like, (n_d,), px
        Map values at the defocused pixels.

    Returns
    -------
    float in [0, 1]
        1: every defocused pixel is blurrier than every in-focus pixel; 0.5: no ranking; 0: inverted.

    Notes
    -----
    1. Rank the pooled sample, ties getting their average rank.
    2. U = (sum of the defocused ranks) − n_d (n_d + 1) / 2 = #{pairs d > f} + ½ #{pairs d = f}.
    3. AUC = U / (n_f n_d).
    """
    a, b = _samples(sigma_in_focus, sigma_defocused)
    return _ranking_auc(a, b)


def in_focus_share_above_median(sigma_in_focus, sigma_defocused) -> float:
    """The fraction of in-focus pixels whose σ is above the median σ of the defocused pixels.

    Parameters
    ----------
    sigma_in_focus : array_like, (n_f,), px
    sigma_defocused : array_like, (n_d,), px

    Returns
    -------
    float in [0, 1]
        #{σ_f > median(σ_d)} / n_f (strictly above; 0 is right).
    """
    a, b = _samples(sigma_in_focus, sigma_defocused)
    return float(np.mean(a > np.median(b)))


def score_defocus_map(defocus_map, regions: PhotoRegions) -> dict:
    """Score a dense defocus map against a photo's regions.

    Parameters
    ----------
    defocus_map : ndarray, (H, W), px
        σ per pixel of the photo (finite inside the regions).
    regions : PhotoRegions

    Returns
    -------
    dict
        ``auc`` (:func:`ranking_auc`), ``in_focus_above_defocused_median``
        (:func:`in_focus_share_above_median`), ``in_focus_median_px``, ``in_focus_p95_px``,
        ``defocused_median_px``, ``defocused_p5_px``, ``n_in_focus``, ``n_defocused`` and
        ``meets_targets`` (AUC ≥ :data:`TARGET_AUC` and share ≤ :data:`TARGET_SHARE`).

    Raises
    ------
    ValueError
        A map whose shape is not the regions' (H, W), or NaN/Inf inside the regions.
    """
    m = np.asarray(defocus_map, dtype=np.float64)
    if m.shape != tuple(regions.shape[:2]):
        raise ValueError(f"defocus map of shape {m.shape} does not fit photo {regions.photo!r}; "
                         f"allowed: {tuple(regions.shape[:2])}")
    masks = regions.masks()
    a, b = _samples(m[masks["in_focus"]], m[masks["defocused"]])
    auc = _ranking_auc(a, b)
    share = float(np.mean(a > np.median(b)))
    return {"auc": auc, "in_focus_above_defocused_median": share,
            "in_focus_median_px": float(np.median(a)), "in_focus_p95_px": float(np.percentile(a, 95)),
            "defocused_median_px": float(np.median(b)), "defocused_p5_px": float(np.percentile(b, 5)),
            "n_in_focus": int(a.size), "n_defocused": int(b.size),
            "meets_targets": bool(auc >= TARGET_AUC and share <= TARGET_SHARE)}


def score_photo(name: str, defocus_map, *, photo_dir=None) -> dict:
    """:func:`score_defocus_map` of ``defocus_map`` on the shipped regions of photo ``name``.

    Parameters
    ----------
    name : str
        A photo of :func:`available_photos` (e.g. ``"coffee"``).
    defocus_map : ndarray, (H, W), px
        σ per pixel of that photo at its shipped size.
    photo_dir : path, optional, keyword-only
        Folder of the region files (default :data:`PHOTO_DIR`).
    """
    return score_defocus_map(defocus_map, load_regions(name, photo_dir=photo_dir, check_photo=False))


def compute_photo_maps(name: str, presets=SCORE_PRESETS, *, photo_dir=None) -> dict:
    """The photo, its regions and the defocus map of each preset (:func:`method.estimate_defocus_map`).

    Parameters
    ----------
    name : str
        A photo of :func:`available_photos`.
    presets : sequence of str
        Keys of :data:`method.PRESETS`.

    Returns
    -------
    dict
        ``image`` (H, W, 3) float in [0, 1], ``regions`` (PhotoRegions), ``results`` {preset:
        :class:`method.DefocusResult`} and ``seconds`` {preset: wall time of the estimate, s}.
    """
    from method import DefocusParams, estimate_defocus_map

    params = {p: DefocusParams.preset(p) for p in dict.fromkeys(presets)}  # ValueError on an unknown preset
    regions = load_regions(name, photo_dir=photo_dir)
    image = load_photo_image(regions.source)
    results, seconds = {}, {}
    for p, prm in params.items():
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            results[p] = estimate_defocus_map(image, prm)
        seconds[p] = time.perf_counter() - t0
    return {"image": image, "regions": regions, "results": results, "seconds": seconds}


def score_presets(names=None, presets=SCORE_PRESETS, *, photo_dir=None) -> dict:
    """Compute each preset's map on each photo and score it.

    Parameters
    ----------
    names : sequence of str, optional
        Photos (default: every one of :func:`available_photos`).
    presets : sequence of str
        Keys of :data:`method.PRESETS` (default :data:`SCORE_PRESETS`).
    photo_dir : path, optional, keyword-only

    Returns
    -------
    dict
        ``{photo: {preset: score dict of score_defocus_map + "seconds"}}``.

    Notes
    -----
    1. Validate the names and presets (ValueError naming the allowed values).
    2. Per photo: :func:`compute_photo_maps`, then :func:`score_defocus_map` of each map.
    """
    from method import PRESETS

    names = validate_photo_names(names, photo_dir)
    presets = tuple(dict.fromkeys(PRESETS.check_all(presets, what="preset")))
    out = {}
    for name in names:
        run = compute_photo_maps(name, presets, photo_dir=photo_dir)
        out[name] = {p: {**score_defocus_map(res.defocus_map, run["regions"]), "seconds": run["seconds"][p]}
                     for p, res in run["results"].items()}
    return out
