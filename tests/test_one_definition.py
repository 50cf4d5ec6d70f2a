"""Each shared rule is defined once: luma weights, the image check, code fingerprints for caches."""

from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("method", "scenes", "experiments", "repro", "defocus_cache")


def _sources():
    for pkg in PACKAGES:
        yield from sorted((ROOT / pkg).rglob("*.py"))


def test_luma_weights_written_once():
    where = [p.relative_to(ROOT).as_posix() for p in _sources()
             if any(w in p.read_text() for w in ("0.2126", "0.7152", "0.299", "0.587"))]
    assert where == ["method/luma.py"]


def test_luminance_is_the_weighted_sum():
    from method import luminance
    from method.luma import LUMA_WEIGHTS

    img = np.random.default_rng(0).random((9, 8, 3))
    np.testing.assert_allclose(luminance(img), img @ np.array(LUMA_WEIGHTS))
    assert sum(LUMA_WEIGHTS) == 1.0
    np.testing.assert_array_equal(luminance(np.array([[[1.0, 0.0, 0.0]]])), [[0.2126]])


def test_cache_fingerprints_only_in_the_cache_layer():
    """hashlib-based code fingerprints (getsource, hashing .py files) live in defocus_cache/__init__.py only."""
    where = [p.relative_to(ROOT).as_posix() for p in _sources()
             if "getsource" in p.read_text() or 'glob("*.py")' in p.read_text() or "rglob(\"*.py\")" in p.read_text()]
    assert where == ["defocus_cache/__init__.py"]


def test_image_checks_only_in_method_validation():
    """No module of method/ (its stage subpackages included) words its own image/array check: they all
    call method.validation."""
    assert _image_check_modules(ROOT / "method") == ["validation.py"]


def _image_check_modules(root: Path) -> list[str]:
    phrases = ("must be a numpy array", "contains NaN or Inf", "must be a float array", "floating-point array")
    return sorted({p.relative_to(root).as_posix() for p in root.rglob("*.py")
                   if any(ph in p.read_text() for ph in phrases)})


def test_the_image_check_search_reaches_subpackages(tmp_path):
    (tmp_path / "blur").mkdir()
    (tmp_path / "validation.py").write_text("msg = 'image must be a numpy array'\n")
    (tmp_path / "blur" / "own.py").write_text("msg = 'image contains NaN or Inf'\n")
    (tmp_path / "blur" / "fine.py").write_text("from ..validation import check_image\n")
    assert _image_check_modules(tmp_path) == ["blur/own.py", "validation.py"]
