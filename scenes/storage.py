"""Atomic writes, cross-process locks and a checksummed content-addressed cache.

Every output file of the project goes through :func:`atomic_write`: the bytes are written to a
temporary file in the destination folder, flushed and fsynced, then renamed over the target, so a
reader never sees a half-written file and an interrupted writer leaves only a stray ``*.tmp``.

Cache entries (:class:`Cache`) are folders named by a hash of *everything* that changes their
content (the caller passes that as a JSON-able key). Each entry carries a manifest with the
SHA-256 and size of every file; an entry whose files do not match (truncated by a killed process,
edited by hand) is treated as missing and rebuilt. Builders run under a file lock so two processes
asking for the same entry compute it once and both read one valid result.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

from filelock import FileLock

__all__ = ["Cache", "atomic_write", "atomic_write_bytes", "atomic_write_text", "hash_key", "sha256_file"]


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
