"""Compile every numba kernel of the photo tools into numba's on-disk cache, once, after an install.

``python -m repro.warmup [--preset NAME ...] [-q]``

Every numba kernel of ``method/`` is compiled with ``cache=True``: the first run on a new install
compiles them (≈ 20 s of CPU for ``repro.estimate`` on a small photo), every later run loads them from
numba's cache (``__pycache__`` beside the sources, or ``$NUMBA_CACHE_DIR``). ``make setup`` runs this
command; after ``pip install`` run it once by hand. It runs ``repro.estimate`` as the command line does,
with each preset of ``--preset`` (default: every preset of :data:`method.PRESETS`), on a small photo
(:func:`warmup_photo`, ``skimage.data.astronaut`` resized, large enough for the propagation's coarse
mode), and ``repro.magnify`` on it with each preset (each preset's renderer). Everything it writes — the photo, the maps,
the map cache — goes to a temporary folder that is removed; only numba's cache keeps the result.
The first ``repro.estimate`` on a new install, with and without this warm-up, is timed by
``python -m repro.bench --first-photo`` (docs/performance.md).
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
import tempfile
from pathlib import Path

PROG = "python -m repro.warmup"

#: Side of the warm-up photo, px: above the 2¹⁵ px up to which Eq. (4) is solved without the coarse
#: mode (:data:`method.propagation.defocus.AUTO_MAX_EXACT_PIXELS`), so its kernels compile too.
WARMUP_SIDE = 192


def warmup_photo(path, *, side: int = WARMUP_SIDE) -> Path:
    """Write an 8-bit sRGB PNG of ``skimage.data.astronaut`` resized to ``side`` x ``side`` px.

    Parameters
    ----------
    path : str or Path
        Destination ``.png``.
    side : int, keyword-only
        Image side, px.

    Returns
    -------
    Path
    """
    from PIL import Image
    from skimage import data

    Image.fromarray(data.astronaut()).resize((side, side), Image.LANCZOS).save(path)
    return Path(path)


def _run_quietly(main, argv) -> None:
    """Run a tool's ``main`` with its stdout (the output path) dropped; a failure is a bug here."""
    with contextlib.redirect_stdout(io.StringIO()):
        status = main(argv)
    if status:
        raise RuntimeError(f"warm-up run {argv} exited with status {status}")


def warmup(presets=None, *, progress: bool = True) -> list[str]:
    """Run ``repro.estimate`` and ``repro.magnify`` per preset on a small photo (numba compiles).

    Parameters
    ----------
    presets : sequence of str, optional
        Keys of :data:`method.PRESETS` (default: all).
    progress : bool, keyword-only
        A progress bar on stderr.

    Returns
    -------
    list of str
        The runs made, e.g. ``["estimate --preset paper", "magnify --preset paper", ...]``.
    """
    from tqdm import tqdm

    from method import PRESETS
    from repro import estimate, magnify

    presets = list(PRESETS) if presets is None else PRESETS.check_all(presets, what="preset")
    runs = [(tool, p) for p in presets for tool in ("estimate", "magnify")]
    done = []
    old_cache = os.environ.get("DEFOCUS_CACHE_DIR")
    with tempfile.TemporaryDirectory(prefix="defocus-warmup-") as tmp:
        photo = warmup_photo(Path(tmp) / "warmup.png")
        os.environ["DEFOCUS_CACHE_DIR"] = str(Path(tmp) / "cache")  # the map cache of these runs only
        try:
            for tool, preset in tqdm(runs, desc="compiling numba kernels", unit="run", disable=not progress):
                out = Path(tmp) / f"{tool}-{preset}.npy"
                if tool == "estimate":
                    _run_quietly(estimate.main, [str(photo), "-o", str(out), "--preset", preset, "--quiet"])
                else:
                    _run_quietly(magnify.main, [str(photo), "-o", str(Path(tmp) / "magnified.png"),
                                                "--preset", preset, "--quiet"])
                done.append(f"{tool} --preset {preset}")
        finally:
            if old_cache is None:
                os.environ.pop("DEFOCUS_CACHE_DIR", None)
            else:
                os.environ["DEFOCUS_CACHE_DIR"] = old_cache
    return done


def _parser():
    from method import PRESETS
    from repro._cli import ArgumentParser, add_preset_option, add_quiet_option

    p = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    add_preset_option(p, default=tuple(PRESETS), many=True, extra="the presets whose pipeline is run")
    add_quiet_option(p, what="no progress display")
    return p


def main(argv=None) -> int:
    """Entry point; returns the exit status."""
    from method import PRESETS
    from repro._cli import user_input

    args = _parser().parse_args(argv)
    with user_input():
        PRESETS.check_all(args.preset, what="--preset")
    warmup(args.preset, progress=not args.quiet)
    if not args.quiet:
        print(f"numba kernels compiled and cached ({len(args.preset)} presets)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    from repro._cli import run_cli

    sys.exit(run_cli(main, prog=PROG))
