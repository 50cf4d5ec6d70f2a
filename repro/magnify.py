"""Magnify the defocus of a photo (Bae & Durand 2007, Sec. 5): blur each pixel so its blur becomes
``factor`` × its estimated blur, as if shot with a ``factor``× wider aperture.

``python -m repro.magnify PHOTO --factor 2 [-o OUT.jpg] [--save-map MAP.exr] [--kernel gaussian|disk]
[--floor clamp|subtract|shift] [--preset NAME]``

``--preset`` (a key of ``method.PRESETS``; default ``robust``, beyond the paper; ``paper`` is the
literal reproduction) chooses the parameters of the defocus map and of its Sec. 5 preprocessing, as
in ``repro.estimate``; the preset in use is said in one line on stderr (not with ``-q``).

Output (``-o``; default ``<photo folder>/<stem>.magnified-x<factor><photo's extension>``): same size,
upright (EXIF orientation applied, orientation tag reset), format from the extension (JPEG, PNG,
TIFF, EXR); 16-bit PNG/TIFF input gives 16-bit PNG/TIFF output, 8-bit input 8-bit output; EXIF and
ICC profile are passed through to JPEG, 8-bit PNG and TIFF.

The defocus map is estimated (or reused from the cache, whatever the factor) as in
``repro.estimate``: at most ``--max-working-pixels`` (default 1.5 MP), upsampled edge-aware to full
resolution (the cache does not depend on ``--factor``, ``--kernel`` or ``--floor``). Before
magnifying, the map is preprocessed as in Sec. 5 (crop the lower and upper 5 %, remove the floor as
``--floor`` says, blur by 0.5 % of the image size). The magnification itself runs at full
resolution, in overlapping tiles of ``--tile-pixels`` (default 4 MP) so its memory stays ≈ 1.1 GiB
per tile whatever the photo's size.

Memory: ≈ 75 B per photo pixel (photo, result, map, all float64) + one tile (≈ 290 B/px × 4 MP).
Measured on a 24 MP JPEG: peak RSS 2.9 GiB, 42 s wall (estimation included) on 2 busy cores.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from repro._cli import ArgumentParser, check_output_path, run_cli
from repro.estimate import (
    MAP_OUTPUT_SUFFIXES,
    add_estimation_arguments,
    announce,
    by_preset,
    defocus_params,
    estimate_from_args,
    load_photo,
    map_summary,
    pixel_count,
    report_map,
    write_map,
)

PROG = "python -m repro.magnify"


def _parser() -> ArgumentParser:
    from method.magnify.magnification import MAGNIFICATION_KERNELS, MAP_FLOOR_MODES
    from method.magnify.upsampling import DEFAULT_TILE_PIXELS

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
    p.add_argument("--kernel", default="gaussian", metavar="NAME",
                   help=f"shape of the added blur (method.MAGNIFICATION_KERNELS): {', '.join(MAGNIFICATION_KERNELS)}; "
                        "gaussian (default) or disk (lens-like bokeh)")
    p.add_argument("--floor", default=None, metavar="MODE",
                   help="how the paper's 'clamp the map's minimum to 0' is read: clamp (the "
                        "literal reading: only negative values are raised to 0, so the estimated map's "
                        "in-focus floor, about 0.3-0.7 px of pixel/sensor blur, is magnified too and "
                        "sharp regions soften) or subtract (the map's lower-5%% value is removed in "
                        "quadrature, sqrt(max(σ² − floor², 0)): pixels at that floor get no extra "
                        "blur, in-focus pixels estimated above it still get some); shift subtracts "
                        f"it linearly (method.magnify.magnification.MAP_FLOOR_MODES: {', '.join(MAP_FLOOR_MODES)}). "
                        f"Default: the preset's map_floor, {by_preset('map_floor')}")
    p.add_argument("--save-map", default=None, metavar="MAP",
                   help="also write the defocus map: .exr (float σ px), .png (preview) or .npy")
    p.add_argument("--bit-depth", type=int, choices=(8, 16), default=None,
                   help="bits per sample of a PNG/TIFF output (default: 16 for 16-bit or float input, else 8)")
    p.add_argument("--tile-pixels", type=pixel_count, default=DEFAULT_TILE_PIXELS, metavar="N",
                   help=f"magnify in tiles of N pixels to bound memory (default {DEFAULT_TILE_PIXELS:,}, "
                        "about 1.1 GiB)")
    add_estimation_arguments(p)
    return p


def parse_factor(text) -> float:
    """--factor as a float ≥ 1 (ValueError naming the value and the allowed range otherwise)."""
    try:
        k = float(text)
    except (TypeError, ValueError):
        raise ValueError(f"--factor {text!r} is not a number; allowed: a number >= 1") from None
    if not math.isfinite(k):
        raise ValueError(f"--factor {text} is invalid; allowed: a finite number >= 1")
    if k <= 0:
        raise ValueError(f"--factor {text} is invalid; allowed: a number >= 1 (a blur cannot be scaled by {text})")
    if k < 1:
        raise ValueError(f"--factor {text} is invalid; allowed: a number >= 1 (factors below 1 would "
                         "need deblurring, which the magnifier does not do)")
    return k


def default_output_path(photo: Path, factor: float) -> Path:
    """``<folder>/<stem>.magnified-x<factor><ext>`` (PNG when the photo's extension is not writable)."""
    from repro.photo_io import OUTPUT_SUFFIXES

    photo = Path(photo)
    suffix = photo.suffix if photo.suffix.lower() in OUTPUT_SUFFIXES else ".png"
    return photo.with_name(f"{photo.stem}.magnified-x{factor:g}{suffix}")


def main(argv=None) -> int:
    """Entry point; returns the exit status (errors raise; see :func:`repro._cli.run_cli`)."""
    from method.magnify.magnification import MAGNIFICATION_KERNELS, MAP_FLOOR_MODES, check_extra_blur, preprocess_defocus_map
    from method.magnify.upsampling import magnify_defocus_tiled
    from repro.photo_io import OUTPUT_SUFFIXES, output_bit_depth, probe_photo, write_photo

    args = _parser().parse_args(argv)
    factor = parse_factor(args.factor)
    MAGNIFICATION_KERNELS.check(args.kernel, what="--kernel")
    MAP_FLOOR_MODES.check(args.floor, what="--floor", optional=True)
    params = defocus_params(args)
    floor = args.floor or params.map_floor
    photo_path = Path(args.photo)
    probe_photo(photo_path)  # a missing/bad photo is reported before anything about the output
    out = Path(args.output) if args.output else default_output_path(photo_path, factor)
    check_output_path(out, photo=photo_path, overwrite=args.overwrite, suffixes=OUTPUT_SUFFIXES, flag="output")
    if args.save_map:
        map_path = check_output_path(args.save_map, photo=photo_path, overwrite=args.overwrite,
                                     suffixes=MAP_OUTPUT_SUFFIXES, flag="--save-map")
        if map_path.resolve() == out.resolve():
            raise ValueError(f"--save-map {map_path} is the output photo's path; choose another name")
    photo = load_photo(args, prog=PROG)
    bits = args.bit_depth or output_bit_depth(out.suffix, photo.bit_depth)
    progress = announce(args, photo, prog=PROG)
    try:
        sigma, info = estimate_from_args(photo, params, args, prog=PROG, progress=progress)
        if args.save_map:
            progress("save map")
            write_map(args.save_map, sigma)
        # Sec. 5 preprocessing on the whole map (a global operation), then tiled magnification
        processed = preprocess_defocus_map(sigma, clip_percent=params.map_clip_percent,
                                           smoothing=params.map_smoothing, floor=floor)
        check_extra_blur(factor, processed, photo.image.shape, name="--factor")  # before any big allocation
        result = magnify_defocus_tiled(
            photo.image, processed, factor=factor, kernel=args.kernel, preprocess=False,
            tile_pixels=args.tile_pixels, progress=progress,
        )
        progress("write")
        write_photo(out, result, bit_depth=bits, exif=photo.exif, icc_profile=photo.icc_profile)
    finally:
        progress.close()
    report_map(args, info, params, prog=PROG, no_edges_consequence=", so the photo is unchanged",
               summary=f"defocus map {map_summary(sigma)}; factor {factor:g}, {args.kernel} kernel, {floor} floor")
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, prog=PROG))
