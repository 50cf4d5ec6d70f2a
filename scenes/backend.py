"""Mitsuba variant selection and the project's cache location.

Variants are tried in the order ``cuda_ad_rgb`` → ``llvm_ad_rgb`` → ``scalar_rgb``. Each is probed in
a *subprocess* that renders a tiny scene: with Debian's libLLVM 15 the LLVM backend aborts the
process ("LLVM ERROR: Cannot select … fminimum"), which no ``try`` can catch. Probe results are
cached on disk, keyed by the Mitsuba version, the Python executable and the libLLVM files present.

Override with the environment variable ``DEFOCUS_MITSUBA_VARIANT`` (or a CLI ``--variant`` flag);
an explicitly requested variant that fails its probe is an error, not a silent fallback.

Mitsuba 3 and Dr.Jit are the ``render`` pip extra (``pip install -e '.[render]'``), not core
dependencies: importing this module does not import them, and :func:`require_mitsuba` (called before
any variant is chosen) raises a ``ModuleNotFoundError`` naming the extra when they are missing.
"""

from __future__ import annotations

import functools
import glob
import hashlib
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

from defocus_cache import CACHE_ENV, default_cache_root

__all__ = [
    "CACHE_ENV",
    "VARIANT_CANDIDATES",
    "VARIANT_ENV",
    "BackendError",
    "cache_root",
    "import_mitsuba",
    "probe_variant",
    "require_mitsuba",
    "select_variant",
]

#: Environment variable forcing a Mitsuba variant.
VARIANT_ENV = "DEFOCUS_MITSUBA_VARIANT"
#: Variants in order of preference.
VARIANT_CANDIDATES = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
#: The pip extra (pyproject ``[project.optional-dependencies]``) that installs Mitsuba 3 and Dr.Jit.
RENDER_EXTRA = "render"


class BackendError(RuntimeError):
    """No usable Mitsuba variant, or a requested one does not work here."""


def cache_root() -> Path:
    """The project's cache folder (:func:`defocus_cache.default_cache_root`: ``$DEFOCUS_CACHE_DIR``, else
    ``<checkout>/.cache`` in a source checkout, else the platformdirs user cache), created if missing."""
    root = default_cache_root()
    root.mkdir(parents=True, exist_ok=True)
    return root


def _configure_drjit_cache() -> None:
    # Dr.Jit caches compiled kernels in ~/.drjit unless told otherwise; keep them with the project.
    if "DRJIT_CACHE_DIR" not in os.environ:
        d = cache_root() / "drjit"
        d.mkdir(parents=True, exist_ok=True)
        os.environ["DRJIT_CACHE_DIR"] = str(d)


_PROBE_SCRIPT = r"""
import sys
import mitsuba as mi
mi.set_variant(sys.argv[1])
scene = mi.load_dict({
    "type": "scene",
    "integrator": {"type": "direct"},
    "sensor": {"type": "thinlens", "aperture_radius": 0.01, "focus_distance": 2.0, "fov": 40,
               "film": {"type": "hdrfilm", "width": 8, "height": 8}},
    "shape": {"type": "sphere", "center": [0, 0, 3], "radius": 1.0, "emitter": {"type": "area"}},
})
img = mi.render(scene, spp=4)
import numpy as np
a = np.asarray(img)
assert a.shape == (8, 8, 3) and np.isfinite(a).all() and a.max() > 0
print("ok")
"""


def _probe_key(variant: str) -> str:
    try:
        from importlib.metadata import version

        mver = version("mitsuba")
    except Exception:  # pragma: no cover - mitsuba missing
        mver = "missing"
    libs = sorted(glob.glob("/usr/lib/*/libLLVM*") + glob.glob("/usr/lib/libLLVM*"))
    blob = json.dumps([variant, mver, sys.executable, libs, os.environ.get("DRJIT_LIBLLVM_PATH")])
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


#: Marks a probe result that only says the probe ran out of time: never stored, so it is probed again.
_TIMED_OUT = "probe timed out"


def probe_variant(variant: str, *, timeout: float = 300.0, use_cache: bool = True) -> tuple[bool, str]:
    """Render a tiny scene with ``variant`` in a subprocess.

    Returns
    -------
    (ok, reason) : (bool, str)
        ``reason`` is the last line the subprocess printed when it failed.

    Notes
    -----
    Results are kept in ``cache_root() / "variant-probes.json"`` under a key of the variant, the
    Mitsuba version, the interpreter, the libLLVM files and ``$DRJIT_LIBLLVM_PATH``; the file is read
    and rewritten under a file lock (atomically), so concurrent probes do not lose each other's
    results. A timeout is not a property of the variant (a busy machine): it is not stored, and the next
    call probes again.
    """
    from filelock import FileLock

    from defocus_cache import atomic_write_text

    _configure_drjit_cache()
    cache_file = cache_root() / "variant-probes.json"
    key = _probe_key(variant)
    if use_cache:
        cached = _read_probes(cache_file)
        if key in cached and not str(cached[key][1]).startswith(_TIMED_OUT):
            return tuple(cached[key])  # type: ignore[return-value]
    try:
        proc = subprocess.run(
            [sys.executable, "-c", _PROBE_SCRIPT, variant],
            capture_output=True, text=True, timeout=timeout, env=os.environ.copy(),
        )
        ok = proc.returncode == 0 and proc.stdout.strip().endswith("ok")
        tail = (proc.stderr.strip().splitlines() or [f"exit status {proc.returncode}"])[-1]
        result = (ok, "ok" if ok else tail[:300])
    except subprocess.TimeoutExpired:
        return (False, f"{_TIMED_OUT} after {timeout:.0f} s")
    if use_cache:
        cache_file.parent.mkdir(parents=True, exist_ok=True)
        with FileLock(str(cache_file) + ".lock"):
            cached = _read_probes(cache_file)  # another process may have added its own meanwhile
            cached[key] = list(result)
            atomic_write_text(cache_file, json.dumps(cached, indent=1))
    return result


def _read_probes(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def select_variant(requested: str | None = None) -> str:
    """Choose the Mitsuba variant: ``requested`` or ``$DEFOCUS_MITSUBA_VARIANT``, else the fastest that works.

    Falls back to ``scalar_rgb`` with a one-line warning when the LLVM variant does not work. The choice
    is remembered per process for each (``requested``, ``$DEFOCUS_MITSUBA_VARIANT``): setting the
    variable later in the same process takes effect.

    Raises
    ------
    BackendError
        If a requested variant is unknown or fails its probe, or no variant works.
    ModuleNotFoundError
        Without the ``render`` extra (:func:`require_mitsuba`).
    """
    return _select_variant(requested or None, os.environ.get(VARIANT_ENV) or None)


@functools.lru_cache(maxsize=None)
def _select_variant(requested: str | None, env_variant: str | None) -> str:
    """:func:`select_variant` for an explicit (argument, environment variable) pair: the cache key."""
    requested = requested or env_variant
    if requested is not None:
        if requested not in _available_variants():
            raise BackendError(
                f"unknown Mitsuba variant {requested!r}; this Mitsuba has {sorted(_available_variants())}"
            )
        ok, reason = probe_variant(requested)
        if not ok:
            raise BackendError(f"Mitsuba variant {requested!r} does not work here: {reason}")
        return requested
    reasons = {}
    for variant in VARIANT_CANDIDATES:
        if variant not in _available_variants():
            reasons[variant] = "not built into this Mitsuba"
            continue
        if variant.startswith("cuda") and not _maybe_gpu():
            reasons[variant] = "no GPU"
            continue
        ok, reason = probe_variant(variant)
        if ok:
            if variant == "scalar_rgb":
                warnings.warn(
                    f"Mitsuba llvm_ad_rgb unavailable ({reasons.get('llvm_ad_rgb', '?')}); rendering "
                    "with scalar_rgb (~5x slower). Fix: apt-get install -y libllvm19",
                    RuntimeWarning, stacklevel=2,
                )
            return variant
        reasons[variant] = reason
    raise BackendError(f"no Mitsuba variant works here: {reasons}")


def _maybe_gpu() -> bool:
    return bool(glob.glob("/dev/nvidia[0-9]*")) or bool(os.environ.get("CUDA_VISIBLE_DEVICES"))


def require_mitsuba() -> None:
    """Import Mitsuba 3 and Dr.Jit, or say which pip extra installs them.

    Raises
    ------
    ModuleNotFoundError
        ``"rendering needs the 'render' extra (mitsuba is not installed): pip install -e '.[render]'"``;
        its ``name`` is the missing module.
    """
    _configure_drjit_cache()  # before the first import of drjit, which reads it
    try:
        import mitsuba  # noqa: F401
        import drjit  # noqa: F401
    except ModuleNotFoundError as exc:
        if (exc.name or "").split(".")[0] not in ("mitsuba", "drjit"):
            raise
        raise ModuleNotFoundError(
            f"rendering needs the {RENDER_EXTRA!r} extra ({exc.name} is not installed): "
            f"pip install -e '.[{RENDER_EXTRA}]'", name=exc.name) from None


@functools.lru_cache(maxsize=None)
def _available_variants() -> tuple[str, ...]:
    require_mitsuba()
    import mitsuba as mi

    return tuple(mi.variants())


def import_mitsuba(variant: str | None = None):
    """Import Mitsuba with the selected variant set; returns ``(mitsuba_module, variant)``."""
    chosen = select_variant(variant)
    _configure_drjit_cache()
    import mitsuba as mi

    if mi.variant() != chosen:
        mi.set_variant(chosen)
    return mi, chosen
