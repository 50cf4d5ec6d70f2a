"""Magnify the defocus of a photo (Bae & Durand 2007, Sec. 5): blur each pixel so its blur becomes
``factor`` × its estimated blur, as if shot with a ``factor``× wider aperture.

``python -m repro.magnify PHOTO --factor 2 [-o OUT.jpg] [--renderer gather|scatter] [--aperture disk|hexagon]
[--kernel gaussian|disk] [--map MAP [--png-scale S]] [--save-map MAP.exr] [--floor clamp|subtract|shift|auto]
[--preset NAME] [--encoding srgb|linear]``

``--preset`` (a key of ``method.PRESETS``; default ``robust``, beyond the paper; ``paper`` is the
literal reproduction) chooses the parameters of the defocus map and of its Sec. 5 preprocessing, as
in ``repro.estimate``; the preset in use is said in one line on stderr (not with ``-q``).

Renderer (``--renderer``, :data:`method.magnify.magnification.MAGNIFICATION_RENDERERS`): ``scatter``
(the default, except with ``--preset paper``) spreads every pixel's linear light over its own disk
(``--aperture disk``, default) or hexagon, in occlusion layers (a sharper pixel is nearer), so a sharp
subject gets no halo of background and highlights become aperture-shaped; ``gather`` (the paper
preset's path, default with ``--preset paper``) blends a blur stack per pixel in display (sRGB)
values, with ``--kernel gaussian`` (default) or ``disk``. The default was chosen on Fig. 7's
oracle-map rows (``docs/figures.md``). ``--kernel`` with the scatter and ``--aperture`` with the
gather are refused.

``--map MAP`` uses a defocus map made elsewhere (σ in px of the photo's pixels: ``.npy``, ``.npz``,
float ``.exr``, or a 16-bit ``.png`` holding σ × ``--png-scale``, default 1000, read by the same
reader as ``repro.evaluate --maps``) instead of estimating one; the 8-bit colour preview that
``--save-map MAP.png`` writes holds no σ and is refused. The map must have the upright photo's size,
or its aspect ratio (each side within one pixel of the photo's scaled by one factor s): then it is
resized to the photo's size (bilinear) and its σ multiplied by s = photo width / map width. NaN,
Inf or negative σ, or another size, is one line and exit status 2. The map is preprocessed as in
Sec. 5 like an estimated one.

Output (``-o``; default ``<photo folder>/<stem>.magnified-x<factor><photo's extension>``): same size,
upright (EXIF orientation applied, orientation tag reset), format from the extension (JPEG, PNG,
TIFF, EXR); 16-bit PNG/TIFF input gives 16-bit PNG/TIFF output, 8-bit input 8-bit output; EXIF and
ICC profile are passed through to JPEG, 8-bit PNG and TIFF. ``--encoding`` (default from the file type:
OpenEXR linear light, the others sRGB) says what the photo's values are; the estimation, the renderer
and the writer all read it (a linear photo written to JPEG/PNG/TIFF is sRGB-encoded).

Without ``--map`` the defocus map is estimated (or reused from the cache, whatever the factor) as in
``repro.estimate``: at most ``--max-working-pixels`` (default 1.5 MP), upsampled edge-aware to full
resolution (the cache does not depend on ``--factor``, the renderer or ``--floor``). Before
magnifying, the map is preprocessed as in Sec. 5 (crop the lower and upper 5 %, remove the floor as
``--floor`` says, blur by 0.5 % of the image size). The magnification itself runs at full
resolution, in overlapping tiles of ``--tile-pixels`` (default 4 MP) so its memory stays bounded per
tile whatever the photo's size (gather ≈ 290 B per tile pixel; scatter less).

Memory (gather): ≈ 75 B per photo pixel (photo, result, map, all float64) + one tile (≈ 290 B/px × 4 MP).
Measured on a 24 MP JPEG: peak RSS 2.9 GiB, 42 s wall (estimation included) on 2 busy cores. The
scatter's 12 MP timing (map given) is recorded by ``repro.bench`` (``docs/performance.md``).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from repro._cli import ArgumentParser, CLIError, check_output_path, run_cli, user_input
from repro.estimate import (
    MAP_OUTPUT_SUFFIXES,
    add_estimation_arguments,
    announce,
    by_preset,
    defocus_params,
    estimate_from_args,
    load_photo,
    map_summary,
    note,
    pixel_count,
    report_map,
    write_map,
)

PROG = "python -m repro.magnify"

#: Renderer when --renderer is not given: the one that measured better on Fig. 7's oracle-map rows
#: (PSNR against the real f/4 render, overall and in the occlusion band; docs/figures.md) ...
DEFAULT_RENDERER = "scatter"
#: ... except with --preset paper, whose path (the literal reproduction) stays the gather.
PAPER_RENDERER = "gather"
#: Default --png-scale: a 16-bit PNG map holds σ × 1000 (0.001 px steps), as repro.evaluate --maps reads it.
DEFAULT_PNG_SCALE = 1000.0


def _parser() -> ArgumentParser:
    from method.magnify.magnification import MAGNIFICATION_KERNELS, MAGNIFICATION_RENDERERS, MAP_FLOOR_MODES
    from method.magnify.scatter import APERTURES
    from method.magnify.upsampling import DEFAULT_TILE_PIXELS
    from repro._cli import float_type

    p = ArgumentParser(
        prog=PROG,
        description="Magnify the defocus of a photo: out-of-focus regions get blurrier, the in-focus "
                    "subject stays sharp (Bae & Durand 2007).",
        epilog="Without -o the result goes next to the photo as <stem>.magnified-x<factor> with the "
               "photo's extension. The defocus map is cached, so trying several --factor values "
               "estimates it once. Exit status 2 on bad input, with one line on stderr.",
    )
    p.add_argument("photo", help="the photo (JPEG, PNG, TIFF or EXR)")
    p.add_argument("--factor", default="2", metavar="K",
                   help="blur magnification k >= 1: each pixel's blur σ becomes k·σ (k = 2 is like "
                        "doubling the aperture diameter; 1 leaves the photo unchanged). Default 2")
    p.add_argument("-o", "--output", default=None, metavar="OUT",
                   help="output photo: .jpg/.jpeg (8-bit), .png/.tif/.tiff (8 or 16-bit, as the "
                        "input), .exr (float, linear)")
    p.add_argument("--renderer", default=None, metavar="NAME",
                   help=f"how the blur is added (method.magnify.magnification.MAGNIFICATION_RENDERERS): "
                        f"{MAGNIFICATION_RENDERERS.describe()}. Default {DEFAULT_RENDERER} ({PAPER_RENDERER} with "
                        "--preset paper, the literal reproduction)")
    p.add_argument("--aperture", default=None, metavar="SHAPE",
                   help=f"scatter only: shape of the out-of-focus highlights: {', '.join(APERTURES)} "
                        "(default disk)")
    p.add_argument("--kernel", default=None, metavar="NAME",
                   help=f"gather only: shape of the added blur (method.MAGNIFICATION_KERNELS): "
                        f"{', '.join(MAGNIFICATION_KERNELS)} (default gaussian)")
    p.add_argument("--floor", default=None, metavar="MODE",
                   help="how the paper's 'clamp the map's minimum to 0' is read: clamp (the "
                        "literal reading: only negative values are raised to 0, so the estimated map's "
                        "in-focus floor, about 0.3-0.7 px of pixel/sensor blur, is magnified too and "
                        "sharp regions soften) or subtract (the map's lower-5%% value is removed in "
                        "quadrature, sqrt(max(σ² − floor², 0)): pixels at that floor get no extra "
                        "blur, in-focus pixels estimated above it still get some); shift subtracts "
                        "it linearly; auto estimates the in-focus floor from the map's sharpest mode and adds no "
                        "blur up to it plus its uncertainty, growing smoothly above "
                        f"(method.magnify.magnification.MAP_FLOOR_MODES: {', '.join(MAP_FLOOR_MODES)}). "
                        f"Default: the preset's map_floor, {by_preset('map_floor')}")
    p.add_argument("--map", default=None, metavar="MAP",
                   help="use this defocus map instead of estimating one: σ in px of the photo, .npy, .npz, "
                        "float .exr or 16-bit .png (σ × --png-scale); the photo's size, or its aspect ratio "
                        "(resized bilinearly, σ scaled by photo width / map width). Not the 8-bit preview "
                        "that --save-map MAP.png writes")
    p.add_argument("--png-scale", type=float_type("--png-scale"), default=None, metavar="S",
                   help=f"with a .png --map: the PNG holds σ × S (default {DEFAULT_PNG_SCALE:g}, as repro.evaluate "
                        "--maps reads it)")
    p.add_argument("--save-map", default=None, metavar="MAP",
                   help="also write the defocus map: .exr (float σ px), .png (preview) or .npy")
    p.add_argument("--bit-depth", type=int, choices=(8, 16), default=None,
                   help="bits per sample of a PNG/TIFF output (default: 16 for 16-bit or float input, else 8)")
    p.add_argument("--tile-pixels", type=pixel_count, default=DEFAULT_TILE_PIXELS, metavar="N",
                   help=f"magnify in tiles of N pixels to bound memory (default {DEFAULT_TILE_PIXELS:,}, "
                        "about 1.1 GiB with the gather)")
    add_estimation_arguments(p)
    return p


@user_input()
def renderer_options(args) -> tuple[str, str | None, str | None]:
    """(renderer, kernel, aperture) of the command line, checked against the registries.

    Raises :class:`repro._cli.CLIError` (one line) for an unknown name, ``--kernel`` with the scatter or
    ``--aperture`` with the gather.
    """
    from method.magnify.magnification import MAGNIFICATION_KERNELS, MAGNIFICATION_RENDERERS
    from method.magnify.scatter import APERTURES

    renderer = args.renderer or (PAPER_RENDERER if args.preset == "paper" else DEFAULT_RENDERER)
    MAGNIFICATION_RENDERERS.check(renderer, what="--renderer")
    if args.kernel is not None:
        MAGNIFICATION_KERNELS.check(args.kernel, what="--kernel")
    if args.aperture is not None:
        APERTURES.check(args.aperture, what="--aperture")
    caps = MAGNIFICATION_RENDERERS.entry(renderer).capabilities
    if args.kernel is not None and "kernel" not in caps:
        raise CLIError(f"--kernel applies to the gather renderer, not to --renderer {renderer}; "
                         "allowed: --renderer gather --kernel NAME, or --aperture SHAPE with the scatter")
    if args.aperture is not None and "aperture" not in caps:
        raise CLIError(f"--aperture applies to the scatter renderer, not to --renderer {renderer}; "
                         "allowed: --renderer scatter --aperture SHAPE, or --kernel NAME with the gather")
    return renderer, args.kernel, args.aperture


@user_input()
def read_given_map(path, shape, *, png_scale: float = DEFAULT_PNG_SCALE):
    """The ``--map`` file as an HxW float64 σ map (px of the photo) and a note when it was resized.

    Parameters
    ----------
    path : str or Path
        ``.npy``, ``.npz``, float ``.exr`` or 16-bit ``.png`` (:func:`experiments.external_maps.read_map`,
        the reader of ``repro.evaluate --maps``).
    shape : tuple
        The upright photo's shape (H, W, ...).
    png_scale : float, keyword-only
        PNG value per px of σ.

    Returns
    -------
    (ndarray, HxW, float64, ≥ 0; str or None)

    Raises
    ------
    CLIError
        One line: missing or unreadable file, an 8-bit PNG, NaN/Inf or negative σ, a size that is
        neither the photo's nor its aspect ratio.

    Notes
    -----
    Resize rule: an h×w map fits an H×W photo when h = round(w·H/W) or w = round(h·W/H) (the photo
    scaled by one factor, each side rounded to whole pixels). It is resized to H×W by bilinear
    interpolation of pixel centres (``skimage.transform.resize``, order 1, edge mode, anti-aliased
    when shrinking) and its σ multiplied by s = W / w (px of the map → px of the photo).
    """
    from experiments.external_maps import read_map

    path = Path(path)
    if not path.is_file():
        raise CLIError(f"--map {path}: no such file")
    try:
        sigma = read_map(path, png_scale=png_scale)
    except ValueError as exc:
        raise CLIError(f"--map {exc}") from exc
    bad = int(np.count_nonzero(~np.isfinite(sigma)))
    if bad:
        raise CLIError(f"--map {path}: {bad} non-finite σ values (NaN or Inf); allowed: a finite σ >= 0 px "
                         "at every pixel")
    if sigma.size and float(sigma.min()) < 0:
        raise CLIError(f"--map {path}: negative σ (min {float(sigma.min()):.4g} px); allowed: σ >= 0 px")
    (H, W), (h, w) = shape[:2], sigma.shape
    if (h, w) == (H, W):
        return sigma, None
    if h < 1 or w < 1 or not (h == round(w * H / W) or w == round(h * W / H)):
        hint = (" (the photo is read upright, EXIF orientation applied: transpose the map?)"
                if (h, w) == (W, H) else "")
        raise CLIError(f"--map {path}: {w}x{h} px does not fit the photo's {W}x{H} px{hint}; allowed: the "
                         "photo's size or its aspect ratio (resized, σ scaled)")
    from skimage.transform import resize

    s = W / w
    resized = resize(sigma, (H, W), order=1, mode="edge", anti_aliasing=s < 1, preserve_range=True) * s
    return np.maximum(resized, 0.0), f"--map {w}x{h} px resized to the photo's {W}x{H} px, σ × {s:.4g}"


def parse_factor(text) -> float:
    """--factor as a float ≥ 1 (CLIError naming the value and the allowed range otherwise)."""
    try:
        k = float(text)
    except (TypeError, ValueError):
        raise CLIError(f"--factor {text!r} is not a number; allowed: a number >= 1") from None
    if not math.isfinite(k):
        raise CLIError(f"--factor {text} is invalid; allowed: a finite number >= 1")
    if k <= 0:
        raise CLIError(f"--factor {text} is invalid; allowed: a number >= 1 (a blur cannot be scaled by {text})")
    if k < 1:
        raise CLIError(f"--factor {text} is invalid; allowed: a number >= 1 (factors below 1 would "
                         "need deblurring, which the magnifier does not do)")
    return k


def default_output_path(photo: Path, factor: float) -> Path:
    """``<folder>/<stem>.magnified-x<factor><ext>`` (PNG when the photo's extension is not writable)."""
    from repro.photo_io import OUTPUT_SUFFIXES

    photo = Path(photo)
    suffix = photo.suffix if photo.suffix.lower() in OUTPUT_SUFFIXES else ".png"
    return photo.with_name(f"{photo.stem}.magnified-x{factor:g}{suffix}")


def _check_map_flags(args) -> None:
    """With --map: no estimation option; --png-scale only with a .png map (CLIError otherwise)."""
    if args.map is None:
        if args.png_scale is not None:
            raise CLIError("--png-scale applies to a .png --map only")
        return
    used = [f"--{name.replace('_', '-')}" for name in ("estimator", "alpha", "force") if getattr(args, name)]
    if used:
        raise CLIError(f"--map replaces the estimation; {', '.join(used)} {'does' if len(used) == 1 else 'do'} "
                         "not apply with it")
    if args.png_scale is not None and Path(args.map).suffix.lower() != ".png":
        raise CLIError(f"--png-scale applies to a .png --map only, not to {args.map}")


def main(argv=None) -> int:
    """Entry point; returns the exit status (errors raise; see :func:`repro._cli.run_cli`)."""
    from method.magnify.magnification import MAP_FLOOR_MODES, check_extra_blur, preprocess_defocus_map
    from method.magnify.upsampling import magnify_defocus_tiled
    from repro.photo_io import OUTPUT_SUFFIXES, output_bit_depth, probe_photo, write_photo

    args = _parser().parse_args(argv)
    factor = parse_factor(args.factor)
    renderer, kernel, aperture = renderer_options(args)
    with user_input():
        MAP_FLOOR_MODES.check(args.floor, what="--floor", optional=True)
    params = defocus_params(args)
    _check_map_flags(args)
    floor = args.floor or params.map_floor
    photo_path = Path(args.photo)
    with user_input():
        probe_photo(photo_path)  # a missing/bad photo is reported before anything about the output
    out = Path(args.output) if args.output else default_output_path(photo_path, factor)
    check_output_path(out, photo=photo_path, overwrite=args.overwrite, suffixes=OUTPUT_SUFFIXES, flag="output")
    if args.save_map:
        map_path = check_output_path(args.save_map, photo=photo_path, overwrite=args.overwrite,
                                     suffixes=MAP_OUTPUT_SUFFIXES, flag="--save-map")
        if map_path.resolve() == out.resolve():
            raise CLIError(f"--save-map {map_path} is the output photo's path; choose another name")
    photo = load_photo(args, prog=PROG)
    given = None
    if args.map is not None:  # read and checked before any output is written
        given, resized = read_given_map(args.map, photo.image.shape,
                                        png_scale=args.png_scale or DEFAULT_PNG_SCALE)
    with user_input():
        bits = args.bit_depth or output_bit_depth(out.suffix, photo.bit_depth)
    progress = announce(args, photo, prog=PROG)
    try:
        if given is None:
            sigma, info = estimate_from_args(photo, params, args, prog=PROG, progress=progress)
        else:
            sigma, info = given, None
            if resized:
                note(PROG, resized, quiet=args.quiet)
        if args.save_map:
            progress("save map")
            write_map(args.save_map, sigma)
        # Sec. 5 preprocessing on the whole map (a global operation), then tiled magnification
        processed = preprocess_defocus_map(sigma, clip_percent=params.map_clip_percent,
                                           smoothing=params.map_smoothing, floor=floor)
        with user_input():  # --factor too large for this photo: before any big allocation
            check_extra_blur(factor, processed, photo.image.shape, name="--factor")
        result = magnify_defocus_tiled(
            photo.image, processed, factor=factor, kernel=kernel, preprocess=False, renderer=renderer,
            aperture=aperture, tile_pixels=args.tile_pixels, progress=progress, encoding=photo.encoding,
        )
        progress("write")
        write_photo(out, result, bit_depth=bits, exif=photo.exif, icc_profile=photo.icc_profile,
                    encoding=photo.encoding)
    finally:
        progress.close()
    shape = f"{aperture or 'disk'} aperture" if renderer == "scatter" else f"{kernel or 'gaussian'} kernel"
    summary = (f"defocus map {map_summary(sigma)}{' (--map)' if given is not None else ''}; factor {factor:g}, "
               f"{renderer} renderer, {shape}, {floor} floor")
    if info is None:
        note(PROG, summary, quiet=args.quiet)
    else:
        report_map(args, info, params, prog=PROG, no_edges_consequence=", so the photo is unchanged", summary=summary)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, prog=PROG))
