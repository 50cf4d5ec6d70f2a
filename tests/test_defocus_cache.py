"""Atomic writes and the checksummed cache, including two processes building one entry."""

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from defocus_cache import Cache, atomic_write, atomic_write_text, hash_key

ROOT = Path(__file__).resolve().parents[1]


def test_atomic_write_success_and_no_leftovers(tmp_path):
    target = tmp_path / "a.txt"
    with atomic_write(target) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".txt" and tmp != target
        tmp.write_text("hello")
        assert not target.exists()
    assert target.read_text() == "hello"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


def test_atomic_write_failure_keeps_old_content(tmp_path):
    target = tmp_path / "a.txt"
    atomic_write_text(target, "old")
    with pytest.raises(RuntimeError):
        with atomic_write(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("killed")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


def test_atomic_write_missing_folder(tmp_path):
    with pytest.raises(FileNotFoundError):
        with atomic_write(tmp_path / "nope" / "a.txt"):
            pass


def test_hash_key_is_order_independent():
    assert hash_key({"a": 1, "b": [1, 2]}) == hash_key({"b": [1, 2], "a": 1})
    assert hash_key({"a": 1}) != hash_key({"a": 2})


def test_cache_builds_once_and_detects_truncation(tmp_path):
    cache = Cache(tmp_path / "c")
    calls = []

    def build(folder):
        calls.append(1)
        (folder / "data.bin").write_bytes(b"x" * 1000)

    key = {"scene": "planes", "spp": 4}
    folder = cache.get_or_build(key, build)
    assert cache.is_valid(key) and len(calls) == 1
    assert cache.get_or_build(key, build) == folder and len(calls) == 1
    # Truncate the file (a killed writer, a full disk): invalid, rebuilt on next request.
    with open(folder / "data.bin", "r+b") as fh:
        fh.truncate(10)
    assert not cache.is_valid(key)
    cache.get_or_build(key, build)
    assert len(calls) == 2 and cache.is_valid(key)
    assert (folder / "data.bin").stat().st_size == 1000
    # Same size, different bytes: caught by the checksum.
    (folder / "data.bin").write_bytes(b"y" * 1000)
    assert not cache.is_valid(key)
    # A different key is a different entry.
    assert cache.path_for({"scene": "planes", "spp": 8}) != folder
    manifest = json.loads((folder / Cache.MANIFEST).read_text())
    assert manifest["key"] == key
    cache.invalidate(key)
    assert not folder.exists()


def test_cache_failed_build_leaves_nothing(tmp_path):
    cache = Cache(tmp_path / "c")

    def build(folder):
        (folder / "partial").write_text("x")
        raise RuntimeError("renderer crashed")

    with pytest.raises(RuntimeError):
        cache.get_or_build({"k": 1}, build)
    assert not cache.is_valid({"k": 1})
    assert [p for p in (tmp_path / "c").iterdir() if not p.name.endswith(".lock")] == []


_WORKER = textwrap.dedent(
    """
    import sys, time, os
    sys.path.insert(0, sys.argv[1])
    from defocus_cache import Cache
    cache = Cache(sys.argv[2])
    log = sys.argv[3]

    def build(folder):
        with open(log, "a") as fh:
            fh.write(f"{os.getpid()}\\n")
        time.sleep(1.0)
        (folder / "result.txt").write_text("built")

    folder = cache.get_or_build({"entry": "shared"}, build)
    print((folder / "result.txt").read_text())
    """
)


def test_two_processes_build_one_entry(tmp_path):
    log = tmp_path / "builds.log"
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", _WORKER, str(ROOT), str(tmp_path / "cache"), str(log)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )
        for _ in range(2)
    ]
    outs = [p.communicate(timeout=120) for p in procs]
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err
        assert out.strip() == "built"
    assert len(log.read_text().split()) == 1  # the builder ran once
    cache = Cache(tmp_path / "cache")
    assert cache.is_valid({"entry": "shared"})
    entries = [p for p in (tmp_path / "cache").iterdir() if p.is_dir()]
    assert len(entries) == 1


def test_atomic_write_gives_ordinary_file_permissions(tmp_path):
    import os
    import stat

    from defocus_cache import atomic_write_text

    umask = os.umask(0o022)
    try:
        atomic_write_text(tmp_path / "out.txt", "x")
    finally:
        os.umask(umask)
    assert stat.S_IMODE((tmp_path / "out.txt").stat().st_mode) == 0o644
