"""``paper`` is bit-identical, in one process, to the method as it was before ``method/`` became subpackages.

The start commit's ``method/`` (all relative imports) is extracted with ``git archive`` and imported
under another package name, ``method_before``; both copies then run the paper preset on the same image
in this process, on this CPU, so any difference is a change of the code, not of the machine. The
stored golden (tests/golden/paper_astronaut.npz) covers other CPUs at a measured tolerance; this test
covers the last bits. It is skipped where git history is absent (a tarball, a shallow clone).
"""

from __future__ import annotations

import importlib
import io
import os
import shutil
import subprocess
import sys
import tarfile
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The commit before ``method/`` was split into subpackages.
BEFORE_COMMIT = "51b70455c8b6c3f056844865b77868f867f9a3ce"
PACKAGE = "method_before"

pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("method_identity")]


def _extract_before(folder: Path) -> Path:
    """Write the start commit's ``method/`` as ``folder/method_before`` (once); return ``folder``."""
    target = folder / PACKAGE
    if (target / "__init__.py").exists():
        return folder
    try:
        blob = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", BEFORE_COMMIT, "method"],
                              check=True, capture_output=True).stdout
    except (OSError, subprocess.CalledProcessError) as exc:
        pytest.skip(f"git history with {BEFORE_COMMIT[:10]} is not available: {exc}")
    staging = folder / f".{PACKAGE}.{os.getpid()}"
    with tarfile.open(fileobj=io.BytesIO(blob)) as tar:
        tar.extractall(staging, filter="data")
    try:
        (staging / "method").rename(target)      # atomic: a half-extracted copy is never imported
    except OSError:                              # another worker won the race
        pass
    shutil.rmtree(staging, ignore_errors=True)
    return folder


@pytest.fixture(scope="module")
def before(tmp_path_factory):
    base = Path(os.environ.get("DEFOCUS_CACHE_DIR", ROOT / ".cache")) / "method_before" / BEFORE_COMMIT[:12]
    base.mkdir(parents=True, exist_ok=True)
    folder = _extract_before(base)
    sys.path.insert(0, str(folder))
    try:
        yield importlib.import_module(PACKAGE)
    finally:
        sys.path.remove(str(folder))


def _image() -> np.ndarray:
    from skimage import data

    return data.astronaut()[::4, ::4].astype(np.float64) / 255.0


def _maps(package) -> dict[str, np.ndarray]:
    image = _image()
    res = package.estimate_defocus_map(image, package.DefocusParams())
    out = package.magnify_defocus(image, res.defocus_map, factor=2.0)
    return {"sparse_sigma": res.sparse_sigma, "refined_sigma": res.refined_sigma,
            "defocus_map": res.defocus_map, "magnified": np.asarray(out)}


def test_paper_is_bit_identical_to_the_code_before_the_move(before):
    import method

    assert before.__file__ != method.__file__
    got, want = _maps(method), _maps(before)
    for name in want:
        assert got[name].shape == want[name].shape, name
        assert np.array_equal(got[name], want[name], equal_nan=True), (
            f"{name}: max |Δ| = {np.nanmax(np.abs(got[name] - want[name])):.3g}")
