"""Estimate the defocus map of a photo (Bae & Durand 2007) and write it.

``python -m repro.estimate PHOTO [-o MAP.exr|MAP.png|MAP.npy] [--preset NAME] [--estimator NAME] [--alpha A]``

``--preset`` names a parameter set of ``method.PRESETS``: ``robust`` (the default here: beyond the
paper, measured better dense maps), ``paper`` (the literal reproduction, ``DefocusParams()``),
``zhuo_sim`` (the Zhuo & Sim 2011 baseline); ``--estimator``/``--alpha`` override the preset's value.
The preset in use is said in one line on stderr (not with ``-q``).

Output (``-o``; default ``<photo folder>/<photo stem>.defocus.exr``):

* ``.exr`` — float32 channel ``sigma``: blur σ in px of the photo (opens in Krita, GIMP, Photoshop,
  Nuke; lossless);
* ``.png`` — a colour-mapped preview with a colour bar labelled "blur σ (px)";
* ``.npy`` — the raw float64 array for NumPy.

Large photos are estimated at a reduced working resolution (``--max-working-pixels``, default
1.5 MP) and the map is brought back to full resolution with a guided filter guided by the photo;
σ is converted to full-resolution px. Maps are cached (``$DEFOCUS_CACHE_DIR/maps``), keyed by the
photo's bytes, the parameters, the working size and the code version, so ``repro.magnify`` reuses
them. Bad input: one line on stderr, exit status 2. A photo without edges: a warning, an all-zero
map, exit status 0.

This module also holds the pieces ``repro.magnify`` shares (argument parsing, cached estimation).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

from repro._cli import (ArgumentParser, CLIError, add_force_option, add_preset_option, add_quiet_option,
                        check_output_path, run_cli, user_input)

PROG = "python -m repro.estimate"

#: Map output extensions.
MAP_OUTPUT_SUFFIXES = (".exr", ".png", ".npy")

#: Largest map plotted as is in a PNG preview, px (bigger maps are downscaled for display first).
PREVIEW_MAX_PIXELS = 2_000_000

#: Version of the map-cache layout (bump when the entry's files or their meaning change).
MAP_CACHE_VERSION = 1

#: Parameter set (key of ``method.PRESETS``) of the photo tools when ``--preset`` is not given:
#: photographers want the map that works, so the tools go beyond the literal reproduction.
DEFAULT_PRESET = "robust"

#: What each preset is, for the help text and the "preset: NAME (...)" line. A preset of the
#: registry missing here is described by the fields it changes from the paper.
PRESET_BLURBS = {
    "paper": "the literal reproduction of Bae & Durand 2007, DefocusParams()",
    "robust": "beyond the paper, measured better dense maps",
    "zhuo_sim": "Zhuo & Sim 2011 baseline: gradient-ratio blur, matting-Laplacian propagation",
}


# ------------------------------------------------------------------------------------------------
# CLI plumbing shared with repro.magnify
# ------------------------------------------------------------------------------------------------


def pixel_count(text: str) -> int:
    """argparse ``type=`` for a pixel count (``1500000`` or ``1.5e6``), ≥ 1."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a pixel count (e.g. 1500000 or 1.5e6)") from None
    if not math.isfinite(value) or value < 1:
        raise argparse.ArgumentTypeError(f"{text!r} is not a positive pixel count")
    return int(value)


def _presets() -> dict:
    """The registry ``method.PRESETS`` (name -> DefocusParams), read at run time."""
    from method.presets import PRESETS

    return PRESETS


def _preset_blurb(name: str) -> str:
    from method.params import DefocusParams

    if name in PRESET_BLURBS:
        return PRESET_BLURBS[name]
    changed = sorted(_presets()[name].changes_from(DefocusParams()))
    return f"changes {', '.join(changed)} from the paper" if changed else "the paper's parameters"


def by_preset(field: str) -> str:
    """'model_fit (paper, robust), gradient_ratio (zhuo_sim)': a field's value in each preset."""
    groups: dict = {}
    for name, params in _presets().items():
        value = getattr(params, field)
        groups.setdefault(f"{value:g}" if isinstance(value, float) else str(value), []).append(name)
    if len(groups) == 1:
        return f"{next(iter(groups))} in every preset"
    return ", ".join(f"{value} ({', '.join(names)})" for value, names in groups.items())


def add_estimation_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by repro.estimate and repro.magnify."""
    from method.blur.estimators import BLUR_ESTIMATORS
    from method.magnify.upsampling import DEFAULT_MAX_WORKING_PIXELS
    from repro.photo_io import DEFAULT_MAX_PIXELS

    add_preset_option(p, default=DEFAULT_PRESET, blurbs={name: _preset_blurb(name) for name in _presets()},
                      extra="--estimator and --alpha override the preset's value")
    p.add_argument("--estimator", default=None, metavar="NAME",
                   help=f"blur estimator at edges: {BLUR_ESTIMATORS.describe()}. Default: the preset's, "
                        f"{by_preset('estimator')}")
    p.add_argument("--alpha", default=None, metavar="A",
                   help=f"propagation data weight α > 0 (Eq. 4; Fig. 6 sweeps 0.1–1). Default: the "
                        f"preset's, {by_preset('alpha')}")
    p.add_argument("--max-working-pixels", type=pixel_count, default=DEFAULT_MAX_WORKING_PIXELS,
                   metavar="N",
                   help=f"estimate at most N pixels (default {DEFAULT_MAX_WORKING_PIXELS:,}); a bigger "
                        "photo is estimated downscaled and its map upsampled edge-aware (guided filter) "
                        "to full resolution. Estimation time and memory grow about linearly with N "
                        "(measured at 1.5 MP: ~1.3 GiB peak, 10-20 s on 2 cores)")
    p.add_argument("--max-pixels", type=pixel_count, default=DEFAULT_MAX_PIXELS, metavar="N",
                   help=f"refuse photos over N pixels, checked from the header before decoding "
                        f"(default {DEFAULT_MAX_PIXELS:,})")
    p.add_argument("--repair-nonfinite", action="store_true",
                   help="EXR input: set NaN/-Inf to 0 and +Inf to 1 instead of refusing the file")
    add_force_option(p, what="re-estimate the defocus map even when it is cached (the new map replaces it)")
    p.add_argument("--overwrite", action="store_true", help="allow an output path equal to the input photo")
    add_quiet_option(p)


@user_input()
def defocus_params(args):
    """DefocusParams of --preset changed by --estimator / --alpha, validated.

    Raises :class:`repro._cli.CLIError` (a ``ValueError``) naming the bad value and the allowed ones
    (an unknown preset lists the registry ``method.PRESETS``).
    """
    from method.blur.estimators import BLUR_ESTIMATORS
    from method.params import DefocusParams

    _presets().check(args.preset, what="--preset")
    changes = {}
    if args.estimator is not None:
        changes["estimator"] = BLUR_ESTIMATORS.check(args.estimator, what="--estimator")
    if args.alpha is not None:
        try:
            alpha = float(args.alpha)
        except ValueError:
            raise CLIError(f"--alpha {args.alpha!r} is not a number; allowed: a number > 0") from None
        if not (math.isfinite(alpha) and alpha > 0):
            raise CLIError(f"--alpha {args.alpha} is invalid; allowed: a finite number > 0")
        changes["alpha"] = alpha
    return DefocusParams.preset(args.preset, **changes)


def preset_line(args) -> str:
    """'preset: robust (beyond the paper; --preset paper for the literal reproduction)', plus overrides."""
    name = args.preset
    if name == "paper":
        text = f"preset: paper ({PRESET_BLURBS['paper'].split(',')[0]})"
    else:
        text = f"preset: {name} ({'beyond the paper' if name == 'robust' else _preset_blurb(name)}; "
        text += "--preset paper for the literal reproduction)"
    overrides = [f"--{flag} {getattr(args, flag)}" for flag in ("estimator", "alpha")
                 if getattr(args, flag) is not None]
    return text + (f", with {' '.join(overrides)}" if overrides else "")


class StageProgress:
    """Per-stage progress on stderr (tqdm), shown only for runs longer than a second on a terminal."""

    def __init__(self, prog, *, quiet=False):
        from tqdm import tqdm

        self.prog = prog
        self.bar = tqdm(total=None, file=sys.stderr, delay=1.0, leave=False, disable=True if quiet else None,
                        bar_format="{desc} [{elapsed}]", dynamic_ncols=True)

    def __call__(self, stage: str) -> None:
        self.bar.set_description_str(f"{self.prog}: {stage}")
        self.bar.update(1)

    def close(self) -> None:
        self.bar.close()


def note(prog, message, *, quiet=False) -> None:
    """One informational line on stderr."""
    if not quiet:
        print(f"{prog}: {message}", file=sys.stderr)


@user_input()
def load_photo(args, *, prog):
    """Probe (size limits before decoding) and read the photo named by ``args.photo``.

    Raises :class:`repro._cli.CLIError` for a file the decoders refuse (missing, not an image,
    corrupt, too large or too small, NaN/Inf).
    """
    from method.validation import MIN_IMAGE_SIDE
    from repro.photo_io import probe_photo, read_photo

    header = probe_photo(args.photo)
    if min(header.width, header.height) < MIN_IMAGE_SIDE:
        raise CLIError(f"{header.path}: {header.width}x{header.height} px is too small; "
                         f"the smallest supported side is {MIN_IMAGE_SIDE} px")
    return read_photo(header.path, max_pixels=args.max_pixels, repair_nonfinite=args.repair_nonfinite)


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
        "decoded": {"shape": list(photo.image.shape), "repaired": any("repaired" in n for n in photo.notes)},
        "params": dataclasses.asdict(params),
        "working_shape": list(working_shape_),
        "code": _code_version(params),
        "versions": library_versions(),
    }


def _build_map(folder: Path, image, params, progress, preset, *, max_working_pixels):
    """Estimate (:func:`method.magnify.upsampling.estimate_defocus_map_at_scale`) and store the
    working-resolution map and its notes in a cache entry ``folder``; return the full-resolution map."""
    from method.magnify.upsampling import estimate_defocus_map_at_scale
    from method.pipeline import NoEdgesWarning

    # no RNG seeding needed: the pipeline is deterministic (tests/test_determinism_method.py)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", NoEdgesWarning)
        scaled = estimate_defocus_map_at_scale(image, params, max_working_pixels=max_working_pixels,
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

    image = photo.image
    H, W = image.shape[:2]
    (h, w), scale = working_shape(image.shape, max_working_pixels=max_working_pixels)
    if scale < 1:
        log(f"{W}x{H} px ({H * W / 1e6:.1f} MP) is over --max-working-pixels {max_working_pixels:,}: "
            f"estimating at {w}x{h} (scale {scale:.3g}), map upsampled edge-aware (guided filter) "
            "to full resolution")
    built = []  # full-resolution maps estimated by this call

    def build(folder):
        built.append(_build_map(Path(folder), image, params, progress, preset, max_working_pixels=max_working_pixels))

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
        sigma = upsample_defocus_map(m, working, image, scale=scale)
    else:
        sigma = m
    return sigma, {"scale": scale, "working_shape": (h, w), "no_edges": bool(meta["no_edges"]),
                   "cached": not built, "preset": preset, "psf_model": meta.get("psf_model"),
                   "measures": meta.get("measures"), "psf_disk_measures": meta.get("psf_disk_measures")}


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


def psf_line(info, params) -> str | None:
    """'blur model at the edges: …' for the terminal: which PSF model the fit used (None: no model fit).

    ``params.fit_psf="auto"`` (the robust preset) chooses one model per image: the thin lens's
    uniform disk, or the paper's Gaussian of Eq. (2c).
    """
    model = info.get("psf_model")
    if model is None:
        return None
    how = {"auto": "chosen for this photo by fit_psf='auto'", "gaussian": "fit_psf='gaussian'",
           "disk": "fit_psf='disk'", "best": "per edge, fit_psf='best'"}.get(params.fit_psf, f"fit_psf={params.fit_psf!r}")
    if model == "mixed":
        share = info["psf_disk_measures"] / max(info["measures"], 1)
        return f"blur model at the edges: disk at {share:.0%} of the measures, Gaussian at the rest ({how})"
    text = "uniform disk (a thin lens's defocus)" if model == "disk" else "Gaussian, Eq. (2c) of the paper"
    return f"blur model at the edges: {text} ({how})"


def map_summary(sigma) -> str:
    """'σ 0.42–7.9 px (median 1.3)'."""
    return (f"σ {float(np.min(sigma)):.3g}–{float(np.max(sigma)):.3g} px "
            f"(median {float(np.median(sigma)):.3g})")


def announce(args, photo, *, prog) -> StageProgress:
    """The preset line and the photo's notes on stderr; the progress display of the run."""
    note(prog, preset_line(args), quiet=args.quiet)
    for n in photo.notes:
        note(prog, n, quiet=args.quiet)
    return StageProgress(prog, quiet=args.quiet)


def estimate_from_args(photo, params, args, *, prog, progress):
    """:func:`estimate_photo_map` with the command line's working size, ``--force`` and notes."""
    return estimate_photo_map(photo, params, max_working_pixels=args.max_working_pixels, force=args.force,
                              progress=progress, log=lambda m: note(prog, m, quiet=args.quiet), preset=args.preset)


def report_map(args, info, params, *, prog, summary, no_edges_consequence="") -> None:
    """The lines after a run: the no-edges warning, the PSF model used, the map's summary."""
    if info["no_edges"]:
        print(f"{prog}: warning: no edges found above the noise thresholds; the defocus map is all zeros"
              f"{no_edges_consequence}", file=sys.stderr)
    if (line := psf_line(info, params)) is not None:
        note(prog, line, quiet=args.quiet)
    note(prog, summary, quiet=args.quiet)


# ------------------------------------------------------------------------------------------------
# repro.estimate
# ------------------------------------------------------------------------------------------------


def _parser() -> argparse.ArgumentParser:
    p = ArgumentParser(
        prog=PROG,
        description="Estimate the defocus map (blur σ in px at every pixel) of a photo, "
                    "Bae & Durand 2007.",
        epilog="Without -o the map goes next to the photo as <stem>.defocus.exr (float σ in px; "
               "-o map.png gives a colour-mapped preview instead). Reads JPEG, PNG, TIFF (8/16-bit) "
               "and OpenEXR (linear). Exit status 2 on bad input, with one line on stderr.",
    )
    p.add_argument("photo", help="the photo (JPEG, PNG, TIFF or EXR)")
    p.add_argument("-o", "--output", default=None, metavar="MAP",
                   help="output map: .exr (float32 σ, default), .png (preview with colour bar) or .npy")
    add_estimation_arguments(p)
    return p


def default_map_path(photo: Path) -> Path:
    """``<folder>/<stem>.defocus.exr`` next to the photo."""
    photo = Path(photo)
    return photo.with_name(f"{photo.stem}.defocus.exr")


def main(argv=None) -> int:
    """Entry point; returns the exit status (errors raise; see :func:`repro._cli.run_cli`)."""
    args = _parser().parse_args(argv)
    params = defocus_params(args)
    photo_path = Path(args.photo)
    out = Path(args.output) if args.output else default_map_path(photo_path)
    from repro.photo_io import probe_photo

    with user_input():
        probe_photo(photo_path)  # a missing/bad photo is reported before anything about the output
    check_output_path(out, photo=photo_path, overwrite=args.overwrite, suffixes=MAP_OUTPUT_SUFFIXES,
                      flag="output map")
    photo = load_photo(args, prog=PROG)
    progress = announce(args, photo, prog=PROG)
    try:
        sigma, info = estimate_from_args(photo, params, args, prog=PROG, progress=progress)
        progress("write")
        write_map(out, sigma)
    finally:
        progress.close()
    report_map(args, info, params, prog=PROG, summary=map_summary(sigma))
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, prog=PROG))
