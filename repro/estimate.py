"""Estimate the defocus map of a photo (Bae & Durand 2007) and write it.

``python -m repro.estimate PHOTO [-o MAP.exr|MAP.png|MAP.npy] [--preset NAME] [--estimator NAME] [--alpha A]
[--encoding NAME]``

``--encoding`` says what the photo's values are (default from the file type: OpenEXR holds linear
light, JPEG/PNG/TIFF sRGB display values), a key of ``method.edges.tone_curve.INPUT_ENCODINGS``: a tone
curve (srgb, gamma1.8, gamma2.2, filmic), linear, or auto (the curve fitted per photo from its
strongest edges); the method converts it once into the light each stage measures in and says on
stderr which curve it read the photo with.

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

This module also holds the pieces ``repro.magnify`` shares (argument parsing, the run's notes); the
cached estimation and the map writers are :mod:`repro._photo_map`'s, imported from here.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path

import numpy as np

from repro._cli import (ArgumentParser, CLIError, add_force_option, add_preset_option, add_quiet_option,
                        check_output_path, run_cli, user_input)
from repro._photo_map import (MAP_CACHE_VERSION, PREVIEW_MAX_PIXELS, estimate_photo_map, map_cache_key,  # noqa: F401
                              write_map, write_map_preview)

PROG = "python -m repro.estimate"

#: Map output extensions.
MAP_OUTPUT_SUFFIXES = (".exr", ".png", ".npy")

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
    from method.edges.tone_curve import INPUT_ENCODINGS
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
    p.add_argument("--encoding", default=None, choices=tuple(INPUT_ENCODINGS), metavar="NAME",
                   help=f"what the photo's values are: {INPUT_ENCODINGS.describe()}. Default: from the file "
                        "type, linear for OpenEXR, srgb for JPEG, PNG and TIFF. The method converts it once "
                        "into the light each stage measures in")
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
    """Probe (size limits before decoding) and read the photo named by ``args.photo``; ``--encoding``,
    when given, replaces the encoding the reader declared from the file type.

    Raises :class:`repro._cli.CLIError` for a file the decoders refuse (missing, not an image,
    corrupt, too large or too small, NaN/Inf).
    """
    from method.validation import MIN_IMAGE_SIDE
    from repro.photo_io import probe_photo, read_photo

    header = probe_photo(args.photo)
    if min(header.width, header.height) < MIN_IMAGE_SIDE:
        raise CLIError(f"{header.path}: {header.width}x{header.height} px is too small; "
                         f"the smallest supported side is {MIN_IMAGE_SIDE} px")
    photo = read_photo(header.path, max_pixels=args.max_pixels, repair_nonfinite=args.repair_nonfinite)
    encoding = getattr(args, "encoding", None)
    if encoding is None:
        return photo
    if encoding != "linear" and photo.image.size and float(photo.image.max()) > 1.0:  # display values are <= 1
        photo = dataclasses.replace(photo, image=np.minimum(photo.image, 1.0),
                                    notes=(*photo.notes, f"--encoding {encoding}: values above 1 clipped to 1"))
    return dataclasses.replace(photo, encoding=encoding)


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
    if info.get("encoding") is not None:
        how = " (fitted to this photo's edges, --encoding auto)" if getattr(args, "encoding", None) == "auto" else ""
        note(prog, f"tone curve assumed: {info['encoding']}{how}", quiet=args.quiet)
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
