"""The compiled numba kernels of ``method/`` (numba's on-disk cache), copied where a subprocess looks for them.

Numba keeps a ``cache=True`` kernel beside its source (``__pycache__``) or under ``$NUMBA_CACHE_DIR`` (a
folder named after the source's folder and a hash of its path); an index file (``.nbi``) names each compiled
signature's code file (``.nbc``) and is valid while the source's bytes are unchanged (numba stamps it with
their SHA-256), wherever the source lives. Copying the files therefore lets a subprocess that runs a copy
of the sources, or another ``$NUMBA_CACHE_DIR``, load the kernels the set-up compiled
(``python -m repro.warmup``) instead of compiling them again.
"""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def kernel_dir(py_file, cache_dir=None) -> Path:
    """Folder of ``py_file``'s compiled kernels: under ``cache_dir`` (``$NUMBA_CACHE_DIR``) or ``__pycache__``."""
    from numba.core.caching import _CacheLocator

    if cache_dir is None:
        return Path(py_file).parent / "__pycache__"
    return Path(cache_dir) / _CacheLocator.get_suitable_cache_subpath(str(py_file))


def seed_kernels(dest_cache_dir=None, *, dest_root=ROOT, skip=()) -> dict[Path, tuple[int, bytes]]:
    """Copy this tree's compiled kernels of every ``method/`` source but ``skip`` to where numba looks for
    them when it runs ``dest_root``'s copy of that source with ``NUMBA_CACHE_DIR=dest_cache_dir``.

    Parameters
    ----------
    dest_cache_dir : str or Path, optional
        The subprocess's ``$NUMBA_CACHE_DIR`` (None: ``__pycache__`` beside each source of ``dest_root``).
    dest_root : Path, keyword-only
        The tree the subprocess imports (this checkout, or a copy of its files).
    skip : collection of Path, keyword-only
        Sources of this tree whose kernels are not copied.

    Returns
    -------
    dict
        ``{copied .nbc file: (its mtime in ns, its bytes)}``.
    """
    import numba

    here = numba.config.CACHE_DIR or None
    copied = {}
    for py in sorted((ROOT / "method").rglob("*.py")):
        src = kernel_dir(py, here)
        if py in skip or not src.is_dir():
            continue
        dst = kernel_dir(dest_root / py.relative_to(ROOT), dest_cache_dir)
        for f in sorted(src.glob(f"{py.stem}.*.nb[ic]")):
            dst.mkdir(parents=True, exist_ok=True)
            (dst / f.name).write_bytes(f.read_bytes())
            if f.suffix == ".nbc":
                copied[dst / f.name] = ((dst / f.name).stat().st_mtime_ns, f.read_bytes())
    return copied
