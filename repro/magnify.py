"""Magnify the defocus of a photo (Bae & Durand 2007, Sec. 5): blur each pixel so its blur becomes
``factor`` × its estimated blur, as if shot with a ``factor``× wider aperture.

``python -m repro.magnify PHOTO --factor 2 [-o OUT.jpg] [--renderer gather|scatter] [--aperture disk|hexagon]
[--kernel gaussian|disk] [--map MAP [--png-scale S]] [--save-map MAP.exr] [--floor clamp|subtract|shift|auto]
[--preset NAME] [--encoding NAME] [--focus-point X,Y] [--keep-sharp MASK] [--depth DEPTH]
[--highlights [GAIN]] [--html PAGE.html]``

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

The subject: ``--focus-point X,Y`` (column, row of the upright photo) and ``--keep-sharp MASK`` (an image,
white = the subject; the photo's size or aspect ratio) go to ``magnify_defocus`` (and to the map's Sec. 5
preprocessing) as ``focus_point`` and ``keep_sharp`` when they take them; without ``keep_sharp`` support
no blur is added under the mask (the map is multiplied by 1 − mask). Front and back (scatter): by default a
blurrier pixel lies behind the subject (said on stderr); ``--depth DEPTH`` (a depth map or a signed
defocus map, ``.npy``/``.npz``/``.exr``) marks as ``in_front`` the pixels nearer than the focus depth (read
at ``--focus-point``, else where the defocus map is lowest; :func:`repro._magnify_inputs.front_back`).
Highlights: an EXR's linear light is magnified and written unclipped; ``--highlights [GAIN]`` (scatter,
display-encoded photos) decodes the photo with its tone curve (``--encoding``; ``auto``: the curve the
estimate chose) and expands clipped highlights to GAIN × white in linear light before the blur, and
inverts that curve after it (:mod:`repro.photo_io.highlights`). ``--html PAGE.html`` also writes a
self-contained before/after page (:mod:`repro._magnify_page`; its path is printed after the photo's).
Every input is checked before anything is written; every output is written atomically after the
magnification.

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

import dataclasses
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
    from repro.photo_io.highlights import DEFAULT_HIGHLIGHT_GAIN

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
    p.add_argument("--focus-point", default=None, metavar="X,Y",
                   help="a pixel on the subject (column X, row Y of the upright photo, origin top left): the "
                        "floor is read there and, with --depth, the focus depth")
    p.add_argument("--keep-sharp", default=None, metavar="MASK",
                   help="a mask image (PNG, JPEG, TIFF; the photo's size or aspect ratio), white where the "
                        "subject must stay sharp")
    p.add_argument("--depth", default=None, metavar="DEPTH",
                   help="scatter only: what is in front of the subject, from a depth map (any unit) or a signed "
                        "defocus map (negative in front), .npy/.npz/.exr, the photo's size or aspect ratio: pixels "
                        "nearer than the focus depth (read at --focus-point, else where the map is sharpest) are "
                        "in front. Without it a blurrier pixel is taken to be behind the subject")
    p.add_argument("--highlights", nargs="?", const=str(DEFAULT_HIGHLIGHT_GAIN), default=None, metavar="GAIN",
                   help="scatter only, JPEG/PNG/TIFF photos: recover clipped highlights before the blur: the "
                        "photo's tone curve (--encoding; with auto the curve the estimate chose) decoded, its "
                        "near-white values rising smoothly to GAIN x white in linear light (default "
                        f"{DEFAULT_HIGHLIGHT_GAIN:g}, >= 1), so bright points bloom into aperture shapes; the "
                        "result is re-encoded with the same curve. An EXR keeps its highlights without it")
    p.add_argument("--html", default=None, metavar="PAGE",
                   help="also write one self-contained .html page: before/after sliders on the whole photo, "
                        "zoomed on the subject and on the background, the defocus map as an overlay")
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
    Resize rule: :func:`repro._magnify_inputs.fit_to_photo` (the photo's size, or its aspect ratio:
    resized bilinearly), then σ multiplied by s = W / w (px of the map → px of the photo).
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
    from repro._magnify_inputs import fit_to_photo

    fitted, resized, s = fit_to_photo(sigma, shape, what=f"--map {path}")
    if resized is None:
        return fitted, None
    return np.maximum(fitted * s, 0.0), f"{resized}, σ × {s:.4g}"


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


def parse_gain(text) -> float | None:
    """--highlights GAIN as a float ≥ 1 (None without the flag; CLIError naming the value otherwise)."""
    if text is None:
        return None
    try:
        gain = float(text)
    except ValueError:
        raise CLIError(f"--highlights {text!r} is not a number; allowed: a gain >= 1 (x white)") from None
    if not (math.isfinite(gain) and gain >= 1.0):
        raise CLIError(f"--highlights {text} is invalid; allowed: a finite gain >= 1 (x white)")
    return gain


def _check_scatter_flags(args, renderer: str) -> None:
    """--depth and --highlights need the scatter's occlusion and linear light (CLIError otherwise)."""
    from method.magnify.magnification import MAGNIFICATION_RENDERERS

    entry = MAGNIFICATION_RENDERERS[renderer]
    for flag, given, ok in (("--depth", args.depth, "occlusion" in MAGNIFICATION_RENDERERS.entry(renderer).capabilities),
                            ("--highlights", args.highlights, entry.default_light == "linear")):
        if given is not None and not ok:
            raise CLIError(f"{flag} applies to the scatter renderer, not to --renderer {renderer}; allowed: "
                           f"--renderer scatter {flag} ..., or --renderer {renderer} without {flag}")


def _output_paths(args, photo_path: Path, factor: float) -> tuple[Path, Path | None, Path | None]:
    """(photo, --save-map, --html) outputs, checked before any work; CLIError for a clash or a bad path."""
    from repro.photo_io import OUTPUT_SUFFIXES

    out = Path(args.output) if args.output else default_output_path(photo_path, factor)
    out = check_output_path(out, photo=photo_path, overwrite=args.overwrite, suffixes=OUTPUT_SUFFIXES, flag="output")
    taken = {out.resolve(): "the output photo"}
    paths = []
    for flag, given, suffixes in (("--save-map", args.save_map, MAP_OUTPUT_SUFFIXES), ("--html", args.html, (".html",))):
        path = None
        if given:
            path = check_output_path(given, photo=photo_path, overwrite=args.overwrite, suffixes=suffixes, flag=flag)
            if path.resolve() in taken:
                raise CLIError(f"{flag} {path} is {taken[path.resolve()]}'s path; choose another name")
            taken[path.resolve()] = flag
        paths.append(path)
    return out, *paths


def _subject(args, photo, *, prog):
    """(focus point, keep-sharp mask, depth map) of the command line, read and checked (CLIError)."""
    from repro._magnify_inputs import parse_focus_point, read_depth, read_keep_sharp

    shape = photo.image.shape
    point = None if args.focus_point is None else parse_focus_point(args.focus_point, shape)
    mask = None if args.keep_sharp is None else read_keep_sharp(args.keep_sharp, shape, max_pixels=args.max_pixels)
    depth = None
    if args.depth is not None:
        depth, resized = read_depth(args.depth, shape)
        if resized:
            note(prog, resized, quiet=args.quiet)
    return point, mask, depth


def _front_back(args, renderer, depth, point, sigma, *, prog):
    """``in_front`` for the scatter (None: blurrier = behind), said in one line on stderr."""
    from repro._magnify_inputs import front_back

    if renderer != "scatter":
        return None
    if depth is None:
        note(prog, "front and back: a blurrier pixel is taken to lie behind the subject (a blurry foreground "
                   "needs --depth DEPTH)", quiet=args.quiet)
        return None
    fb = front_back(depth, focus_point=point, sigma=sigma)
    note(prog, f"front and back from --depth: {100 * fb.in_front.mean():.3g}% of the pixels in front of the focus "
               f"depth {fb.focus_depth:.4g} (± {fb.tolerance:.2g}, {fb.where})", quiet=args.quiet)
    return fb.in_front


def _render(args, photo, sigma, params, *, factor, renderer, kernel, aperture, floor, gain, subject, progress):
    """(result in the magnifier's encoding, that encoding, display values of the result) of the whole photo."""
    from method.luma import to_light
    from method.magnify.magnification import check_extra_blur, preprocess_defocus_map
    from method.magnify.upsampling import magnify_defocus_tiled
    from repro.photo_io.highlights import compress_highlights, expand_highlights

    point, mask, depth = subject
    # Sec. 5 preprocessing on the whole map (a global operation: the floor, the subject), then tiled magnification
    processed = preprocess_defocus_map(sigma, clip_percent=params.map_clip_percent, smoothing=params.map_smoothing,
                                       floor=floor, focus_point=point, keep_sharp=mask)
    with user_input():  # --factor too large for this photo: before any big allocation
        check_extra_blur(factor, processed, photo.image.shape, name="--factor")
    in_front = _front_back(args, renderer, depth, point, sigma, prog=PROG)
    image, encoding = ((photo.image, photo.encoding) if gain is None
                       else (expand_highlights(photo.image, gain=gain, encoding=photo.encoding), "linear"))
    result = magnify_defocus_tiled(image, processed, factor=factor, kernel=kernel, preprocess=False, renderer=renderer,
                                   aperture=aperture, tile_pixels=args.tile_pixels, progress=progress,
                                   encoding=encoding, in_front=in_front)
    display = (to_light(result, "display", encoding=encoding) if gain is None  # in the photo's curve
               else compress_highlights(result, gain=gain, encoding=photo.encoding))
    return result, encoding, display


def main(argv=None) -> int:
    """Entry point; returns the exit status (errors raise; see :func:`repro._cli.run_cli`)."""
    from method.luma import to_light
    from method.magnify.magnification import MAP_FLOOR_MODES
    from repro._magnify_page import magnify_page, write_magnify_page
    from repro.photo_io import output_bit_depth, probe_photo, write_photo

    args = _parser().parse_args(argv)
    factor = parse_factor(args.factor)
    renderer, kernel, aperture = renderer_options(args)
    gain = parse_gain(args.highlights)
    _check_scatter_flags(args, renderer)
    with user_input():
        MAP_FLOOR_MODES.check(args.floor, what="--floor", optional=True)
    params = defocus_params(args)
    _check_map_flags(args)
    floor = args.floor or params.map_floor
    photo_path = Path(args.photo)
    with user_input():
        probe_photo(photo_path)  # a missing/bad photo is reported before anything about the output
    out, map_path, page_path = _output_paths(args, photo_path, factor)
    photo = load_photo(args, prog=PROG)
    if gain is not None and photo.encoding == "linear":
        raise CLIError(f"--highlights applies to display-encoded photos (JPEG, PNG, TIFF under a tone curve), not to "
                       f"{photo_path.name} (read as linear light: an EXR keeps its highlights as stored); allowed: drop "
                       "--highlights, or --encoding with a tone curve")
    subject = _subject(args, photo, prog=PROG)  # read and checked before any output is written
    given = None
    if args.map is not None:
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
        if photo.encoding == "auto":  # magnified and written in the curve fitted (by the estimate, or here)
            from method.edges.tone_curve import resolve_encoding

            photo = dataclasses.replace(photo, encoding=info["encoding"] if info else resolve_encoding(photo.image, "auto"))
        result, encoding, display = _render(args, photo, sigma, params, factor=factor, renderer=renderer,
                                            kernel=kernel, aperture=aperture, floor=floor, gain=gain,
                                            subject=subject, progress=progress)
        shape = f"{aperture or 'disk'} aperture" if renderer == "scatter" else f"{kernel or 'gaussian'} kernel"
        summary = (f"defocus map {map_summary(sigma)}{' (--map)' if given is not None else ''}; factor {factor:g}, "
                   f"{renderer} renderer, {shape}, {floor} floor"
                   + (f", highlights x{gain:g} ({photo.encoding} curve)" if gain is not None else ""))
        page = None
        if page_path is not None:
            progress("page")
            page = magnify_page(to_light(photo.image, "display", encoding=photo.encoding), display, sigma,
                                title=f"{photo_path.name} magnified x{factor:g}", summary=summary,
                                focus_point=subject[0], keep_sharp=subject[1])
        progress("write")
        if out.suffix.lower() == ".exr" or gain is None:
            write_photo(out, result, bit_depth=bits, exif=photo.exif, icc_profile=photo.icc_profile, encoding=encoding)
        else:  # recovered highlights go back through the inverse of their curve, in the photo's tone curve
            write_photo(out, display, bit_depth=bits, exif=photo.exif, icc_profile=photo.icc_profile,
                        encoding=photo.encoding)
        if map_path is not None:
            write_map(map_path, sigma)
        if page is not None:
            write_magnify_page(page_path, page)
    finally:
        progress.close()
    if info is None:
        note(PROG, summary, quiet=args.quiet)
    else:
        report_map(args, info, params, prog=PROG, no_edges_consequence=", so the photo is unchanged", summary=summary)
    print(out)
    if page_path is not None:
        print(page_path)
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, prog=PROG))
