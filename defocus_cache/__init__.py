"""The cache layer: atomic writes, cross-process locks and a checksummed content-addressed cache.

Used by every layer of the harness but ``method`` (pure numerics); imports no project package
(tests/test_architecture.py).

Every output file of the project goes through :func:`atomic_write`: the bytes are written to a
temporary file in the destination folder, flushed and fsynced, then renamed over the target, so a
reader never sees a half-written file and an interrupted writer leaves only a stray ``*.tmp``.

Cache entries (:class:`Cache`) are folders named by a hash of *everything* that changes their
content (the caller passes that as a JSON-able key). Each entry carries a manifest with the
SHA-256 and size of every file; an entry whose files do not match (truncated by a killed process,
edited by hand) is treated as missing and rebuilt. Builders run under a file lock so two processes
asking for the same entry compute it once and both read one valid result.

Cache keys are built from three helpers defined here and nowhere else: :func:`source_fingerprint`
(the code that computes an entry), :func:`library_versions` (the numerical libraries it ran on) and
:func:`hash_key`; :func:`default_cache_root` chooses where caches live.
"""

from __future__ import annotations

import ast
import contextlib
import functools
import hashlib
import inspect
import json
import os
import shutil
import sys
import tempfile
import textwrap
import types
from collections.abc import Callable, Iterator
from pathlib import Path

from filelock import FileLock

__all__ = [
    "CACHE_ENV",
    "KEY_LIBRARIES",
    "Cache",
    "atomic_write",
    "atomic_write_bytes",
    "atomic_write_text",
    "default_cache_root",
    "hash_key",
    "library_versions",
    "sha256_file",
    "source_fingerprint",
]

#: Environment variable naming the cache folder (overrides :func:`default_cache_root`).
CACHE_ENV = "DEFOCUS_CACHE_DIR"

#: Distributions whose versions enter every cache key of renders, figure data and photo maps: a
#: different numpy/scipy/scikit-image/pyamg/numba/pymatting (numerics), mitsuba/drjit (renders),
#: colour-science (every sRGB encoding and decoding), Pillow (the JPEG round trip of an input, the text
#: textures, 8-bit photos), OpenEXR (renders read back) or tifffile/imagecodecs (16-bit and raw photos
#: decoded) can change the numbers, so an upgrade recomputes instead of serving stale entries.
KEY_LIBRARIES = ("numpy", "scipy", "scikit-image", "pyamg", "numba", "pymatting", "mitsuba", "drjit",
                 "colour-science", "Pillow", "OpenEXR", "tifffile", "imagecodecs")

#: Folder holding the packages (``method``, ``scenes``, ``experiments``, ``repro``).
_PROJECT_ROOT = Path(__file__).resolve().parents[1]


@contextlib.contextmanager
def atomic_write(path, *, suffix=None) -> Iterator[Path]:
    """Context manager yielding a temporary path; on success it is renamed to ``path``.

    The temporary file lives in the destination folder (same filesystem, so the rename is atomic)
    and keeps ``path``'s extension (or ``suffix``) so that writers choosing a format from the
    extension still work. On an exception the temporary file is removed and ``path`` is untouched.

    Parameters
    ----------
    path : str or Path
        Final destination. Its folder must exist and be writable.
    suffix : str, optional, keyword-only
        Extension of the temporary file (default: that of ``path``).
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise FileNotFoundError(f"output folder does not exist: {folder}")
    # The temporary name keeps the real extension last (writers pick the format from it).
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.tmp.", suffix=suffix or path.suffix, dir=folder)
    os.close(fd)
    tmp_path = Path(tmp)
    # mkstemp creates the file 0600; give the final file the permissions a plain open() would.
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp_path, 0o666 & ~umask)
    try:
        yield tmp_path
        with open(tmp_path, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp_path, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp_path.unlink()
        raise


def atomic_write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_write(path) as tmp:
        tmp.write_bytes(data)


def atomic_write_text(path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    atomic_write_bytes(path, text.encode("utf-8"))


def sha256_file(path, *, chunk=1 << 20) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(chunk), b""):
            h.update(block)
    return h.hexdigest()


@functools.lru_cache(maxsize=8)
def library_versions(packages: tuple[str, ...] = KEY_LIBRARIES) -> dict:
    """Installed version of each distribution (None when missing), plus the Python version.

    Parameters
    ----------
    packages : tuple of str
        Distribution names (default :data:`KEY_LIBRARIES`).

    Returns
    -------
    dict
        ``{"python": "3.11.2", "numpy": "2.1.0", ..., "pyamg": None}`` (JSON-able).
    """
    import platform
    from importlib.metadata import PackageNotFoundError, version

    out = {"python": platform.python_version()}
    for pkg in packages:
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = None
    return out


def _source_files(item) -> list[Path]:
    """The ``.py`` files of a package (recursively), a module, a path or a folder."""
    if isinstance(item, types.ModuleType):
        f = Path(getattr(item, "__file__", "") or "")
        if f.name == "__init__.py":
            return sorted(f.parent.rglob("*.py"))
        return [f] if f.is_file() else []
    p = Path(item)
    return sorted(p.rglob("*.py")) if p.is_dir() else [p]


def _code_meaning(text: str) -> bytes:
    """The parsed code of ``text`` without docstrings or comments (``ast.dump``), as bytes.

    Comments never reach the AST; docstrings (a string constant opening a module, class or function
    body) are dropped, so editing either keeps every cache entry, while any change of a token that
    the interpreter executes changes the result. Text that does not parse is returned as is.
    """
    try:
        tree = ast.parse(textwrap.dedent(text))
    except SyntaxError:
        return text.encode()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                and body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)):
            node.body = body[1:] or [ast.Pass()]
    return ast.dump(tree, include_attributes=False).encode()


def source_fingerprint(*items, exclude: tuple[str, ...] = ()) -> str:
    """SHA-256 (16 hex digits) of the code, by meaning, that computes a cache entry.

    The one way the project fingerprints code for its caches: a change of any listed code
    invalidates the entries that depend on it, with no version number to remember to bump; an edit
    of docstrings or comments only keeps them (:func:`_code_meaning`).

    Parameters
    ----------
    *items : module, str, Path or callable
        A package (every ``.py`` below it), a module or a file/folder path, or a function/class (its
        module, qualified name and code; used for code registered at run time, e.g. a blur
        estimator defined in a test).
    exclude : tuple of str, keyword-only
        Posix path prefixes, relative to the project root, left out (modules that only read
        results, such as plots).

    Returns
    -------
    str
        16 hex digits; equal code gives equal fingerprints in any process of one Python minor
        version (the AST's dump format is the interpreter's, so it is part of the key).
    """
    h = hashlib.sha256()
    h.update(f"ast-py{sys.version_info[0]}.{sys.version_info[1]}".encode())
    for item in items:
        if callable(item) and not isinstance(item, (str, Path)):
            name = f"{getattr(item, '__module__', '')}.{getattr(item, '__qualname__', repr(item))}"
            h.update(name.encode())
            try:
                h.update(_code_meaning(inspect.getsource(item)))
            except (OSError, TypeError):
                h.update(repr(item).encode())
            continue
        for path in _source_files(item):
            path = path.resolve()
            try:
                rel = path.relative_to(_PROJECT_ROOT).as_posix()
            except ValueError:
                rel = path.as_posix()
            if any(rel.startswith(ex) for ex in exclude):
                continue
            h.update(rel.encode())
            h.update(_code_meaning(path.read_text(encoding="utf-8")))
    return h.hexdigest()[:16]


def _is_source_checkout(root: Path) -> bool:
    parts = set(root.parts)
    return (root / "pyproject.toml").is_file() and not parts & {"site-packages", "dist-packages"}


def default_cache_root(*, project_root=None) -> Path:
    """Where caches live (not created): ``$DEFOCUS_CACHE_DIR``, else ``<checkout>/.cache`` in a source
    checkout (also an editable install), else the user cache folder of platformdirs
    (``~/.cache/defocus-repro`` on Linux) -- never inside site-packages.

    Parameters
    ----------
    project_root : path, optional, keyword-only
        The folder holding the packages (default: this installation's); tests pass others.
    """
    env = os.environ.get(CACHE_ENV)
    if env:
        return Path(env).expanduser()
    root = Path(project_root) if project_root is not None else _PROJECT_ROOT
    if _is_source_checkout(root):
        return root / ".cache"
    import platformdirs

    return Path(platformdirs.user_cache_dir("defocus-repro", appauthor=False))


def hash_key(key) -> str:
    """Stable 20-hex-digit hash of a JSON-able key (dict keys sorted, floats by repr)."""
    blob = json.dumps(key, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(blob.encode("utf-8")).hexdigest()[:20]


class Cache:
    """A folder of checksummed entries, one sub-folder per key.

    Parameters
    ----------
    root : str or Path
        Cache folder (created if missing), e.g. ``scenes.backend.cache_root() / "renders"``.

    Examples
    --------
    >>> cache = Cache(tmp_path)                                     # doctest: +SKIP
    >>> folder = cache.get_or_build({"scene": "planes", "spp": 64},
    ...                              lambda out: (out / "a.txt").write_text("x"))  # doctest: +SKIP
    """

    MANIFEST = "manifest.json"

    def __init__(self, root):
        self.root = Path(root)
        self.root.mkdir(parents=True, exist_ok=True)

    def path_for(self, key) -> Path:
        """Folder an entry with this key lives in (it may not exist yet)."""
        return self.root / hash_key(key)

    def is_valid(self, key) -> bool:
        """True when the entry exists and every file matches its manifest (size and SHA-256)."""
        folder = self.path_for(key)
        manifest = folder / self.MANIFEST
        try:
            data = json.loads(manifest.read_text())
        except (OSError, ValueError):
            return False
        if data.get("key_hash") != hash_key(key):
            return False
        for name, meta in data.get("files", {}).items():
            f = folder / name
            try:
                if f.stat().st_size != meta["size"] or sha256_file(f) != meta["sha256"]:
                    return False
            except OSError:
                return False
        return True

    def get_or_build(self, key, build: Callable[[Path], object]) -> Path:
        """Return the entry's folder, building it first with ``build(tmp_folder)`` if missing or invalid.

        ``build`` writes its files into the temporary folder it is given; the folder is then
        checksummed and renamed into place. A lock file serialises concurrent builders.
        """
        folder = self.path_for(key)
        if self.is_valid(key):
            return folder
        with FileLock(str(folder) + ".lock"):
            if self.is_valid(key):  # another process built it while we waited
                return folder
            tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".tmp", dir=self.root))
            try:
                build(tmp)
                files = {
                    p.name: {"size": p.stat().st_size, "sha256": sha256_file(p)}
                    for p in sorted(tmp.iterdir()) if p.is_file()
                }
                manifest = {"key_hash": hash_key(key), "key": key, "files": files}
                (tmp / self.MANIFEST).write_text(json.dumps(manifest, indent=1, sort_keys=True, default=str))
                if folder.exists():
                    shutil.rmtree(folder)
                os.replace(tmp, folder)
            except BaseException:
                shutil.rmtree(tmp, ignore_errors=True)
                raise
        return folder

    def invalidate(self, key) -> None:
        """Remove an entry (no error if missing)."""
        shutil.rmtree(self.path_for(key), ignore_errors=True)
