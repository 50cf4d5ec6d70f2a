"""Shared pytest configuration."""

import os

import pytest

# Keep CI's caches inside the project unless the caller chose another place.
os.environ.setdefault("DEFOCUS_CACHE_DIR", os.path.join(os.path.dirname(os.path.dirname(__file__)), ".cache"))


@pytest.fixture
def rng():
    """A seeded generator: tests are deterministic."""
    import numpy as np

    return np.random.default_rng(20070101)


def pytest_addoption(parser):
    parser.addoption(
        "--regen-goldens", action="store_true", default=False,
        help="rewrite tests/golden/*.json from this run instead of comparing (review the diff!)",
    )
    parser.addoption(
        "--regen-references", action="store_true", default=False,
        help="rewrite the rendered reference EXRs in tests/references/ from this run (review them!)",
    )


@pytest.fixture
def goldens(request):
    """Golden-number checker (see tests/golden.py)."""
    from tests.golden import Goldens

    return Goldens(request.config.getoption("--regen-goldens"))
