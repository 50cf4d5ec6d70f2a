"""Validators of what a user gives a command-line tool: numbers, ``WxH``, output paths, scene names.

Each raises :class:`repro._cli.CLIError` (one line naming the value and what is allowed, exit status 2
from :func:`repro._cli.run_cli`), or is an argparse ``type=`` whose errors argparse reports the same
way. Everything here is re-exported by :mod:`repro._cli`; import it from there.
"""

from __future__ import annotations

import argparse
import os
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

from repro._cli_errors import CLIError, user_input

__all__ = ["check_output_path", "check_scene_names", "float_type", "int_type", "parse_resolution", "scene_grid"]


def int_type(name: str, *, minimum: int = 1) -> Callable[[str], int]:
    """argparse ``type=`` for an integer ≥ ``minimum`` (argparse prefixes the flag ``name`` to errors)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is invalid; allowed: integer >= {minimum}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{text!r} is invalid; allowed: integer >= {minimum}")
        return value

    return parse


def float_type(name: str, *, positive: bool = True) -> Callable[[str], float]:
    """argparse ``type=`` for a finite (positive) float (argparse prefixes the flag ``name`` to errors)."""
    import math

    allowed = "finite number > 0" if positive else "finite number"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is invalid; allowed: {allowed}") from None
        if not math.isfinite(value) or (positive and value <= 0):
            raise argparse.ArgumentTypeError(f"{text!r} is invalid; allowed: {allowed}")
        return value

    return parse


def parse_resolution(text: str) -> tuple[int, int]:
    """``"640x480"`` → (640, 480); raises :class:`CLIError` naming the value and the format."""
    parts = str(text).lower().split("x")
    allowed = "WxH with positive integers, e.g. 640x480"
    if len(parts) != 2:
        raise CLIError(f"--resolution {text!r} is invalid; allowed: {allowed}")
    try:
        w, h = int(parts[0]), int(parts[1])
    except ValueError:
        raise CLIError(f"--resolution {text!r} is invalid; allowed: {allowed}") from None
    if w <= 0 or h <= 0:
        raise CLIError(f"--resolution {text!r} is invalid; allowed: {allowed}")
    return w, h


def check_output_path(path, *, suffixes: Sequence[str] = (".exr",), flag: str = "--out", photo=None,
                      overwrite: bool = False) -> Path:
    """Refuse an output path before any work; nothing is left behind.

    Parameters
    ----------
    path : str or Path
        Where the output will be written (``~`` expanded).
    suffixes : sequence of str, keyword-only
        Allowed extensions (case-insensitive), e.g. ``(".exr", ".png", ".npy")``.
    flag : str, keyword-only
        How the output is named in messages (``"--out"``, ``"output map"``, ``"--save-map"``).
    photo : str or Path, optional, keyword-only
        The input photo: an output may replace it only with ``overwrite``.
    overwrite : bool, keyword-only
        Allow ``path`` to be ``photo``.

    Returns
    -------
    Path
        ``path`` with ``~`` expanded.

    Raises
    ------
    CLIError
        Naming the path and what is allowed: bad extension, a folder, a missing or unwritable folder
        (a real probe file, so read-only mounts and ACLs that ``os.access`` misses are caught too),
        the input photo without ``overwrite``.
    """
    p = Path(path).expanduser()
    shown = f"{flag} {str(path)!r}"
    writable = "allowed: a file path in an existing writable folder"
    if p.suffix.lower() not in tuple(s.lower() for s in suffixes):
        raise CLIError(f"{shown}: extension {p.suffix or '(none)'!r} is not supported; "
                       f"allowed: a file name ending in {', '.join(suffixes)}")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.exists():
        raise CLIError(f"{shown} is not writable: folder {str(folder)!r} does not exist; {writable}")
    if not folder.is_dir():
        raise CLIError(f"{shown} is not writable: {str(folder)!r} is not a folder; {writable}")
    if p.is_dir():
        raise CLIError(f"{shown} is a directory; allowed: a file path in a writable folder")
    if not os.access(folder, os.W_OK | os.X_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise CLIError(f"{shown} is not writable; {writable}")
    if photo is not None and p.exists() and Path(photo).exists() and os.path.samefile(p, photo) and not overwrite:
        raise CLIError(f"{shown} is the input photo; allowed: another path, or --overwrite to replace the photo")
    try:  # a real probe: read-only mounts and ACLs that os.access does not see
        fd, probe = tempfile.mkstemp(prefix=f".{p.name}.probe.", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise CLIError(f"{shown} is not writable: cannot write in {str(folder)!r} ({exc.strerror or exc}); "
                       f"{writable}") from None
    return p


def check_scene_names(names, *, what: str = "scene") -> list[str]:
    """``names`` as a list if each is a scene of :data:`scenes.SCENES` or ``procedural_<seed>[_<camera>]``.

    Raises
    ------
    CLIError
        Naming the unknown ones and the allowed names (the registry's message, plus the procedural form).
    """
    from method.registry import Registry
    from scenes import SCENES
    from scenes.library import is_procedural_name

    names = list(names)
    named = [n for n in names if not is_procedural_name(n)]
    try:
        if named or not names:  # (an empty list is refused by the registry, naming the scenes)
            Registry("scene", SCENES).check_all(named, what=what)
    except ValueError as exc:
        raise CLIError(f"{exc}, or procedural_<seed>") from exc
    return names


def scene_grid(scenes, f_numbers, scene_size: str, *, out=None) -> tuple[list[str], list[float]]:
    """Validated scenes × f-numbers of a render grid, duplicates dropped, before anything is rendered.

    Parameters
    ----------
    scenes : sequence of str or None
        Keys of :data:`scenes.SCENES` (None: all).
    f_numbers : sequence of float
    scene_size : str
        Render size (``--scene-size``, a key of :data:`scenes.library.PRESETS`).
    out : path, optional, keyword-only
        An output folder, refused when it is a file.

    Raises
    ------
    CLIError
        One line naming the unknown scene(s), the bad f-number or size, or the ``--out`` that is a file.
    """
    from scenes import SCENES
    from scenes.render import validate_render_options

    names = check_scene_names(dict.fromkeys(scenes or list(SCENES)))
    numbers = list(dict.fromkeys(float(n) for n in f_numbers))
    with user_input():
        for s in names:
            for n in numbers:
                validate_render_options(s, preset=scene_size, f_number=n)  # ValueError on a bad N
    if out is not None and Path(out).exists() and not Path(out).is_dir():
        raise CLIError(f"--out {str(out)!r} is a file; allowed: a folder")
    return names, numbers
