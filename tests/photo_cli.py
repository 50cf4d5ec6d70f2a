"""Shared helpers of the photo-CLI tests (repro.estimate, repro.magnify)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from repro._cli import run_cli


def textured_photo(h=96, w=128, *, seed=3, blur_right=2.5):
    """Blocky colour texture (sharp edges) whose right half is Gaussian-blurred, float in [0, 1]."""
    rng = np.random.default_rng(seed)
    blocks = rng.random((h // 8 + 1, w // 8 + 1, 3))
    img = np.repeat(np.repeat(blocks, 8, axis=0), 8, axis=1)[:h, :w]
    blurred = np.stack([ndimage.gaussian_filter(img[..., c], blur_right) for c in range(3)], axis=-1)
    img[:, w // 2:] = blurred[:, w // 2:]
    return np.clip(img, 0, 1)


def cli_runner(main, prog):
    """``(run, assert_one_line_error)`` for a CLI ``main`` called in-process under ``prog``.

    ``run(argv, capsys)`` returns (exit status, stdout, non-empty stderr lines);
    ``assert_one_line_error(status, err, *needles)`` checks exit 2 with one ``prog: error:`` line
    containing every needle (case-insensitive).
    """

    def run(argv, capsys):
        status = run_cli(main, [str(a) for a in argv], prog=prog)
        out, err = capsys.readouterr()
        return status, out, [line for line in err.splitlines() if line.strip()]

    def assert_one_line_error(status, err, *needles):
        assert status == 2
        assert len(err) == 1, err
        assert err[0].startswith(f"{prog}: error: ")
        for n in needles:
            assert n.lower() in err[0].lower(), err[0]

    return run, assert_one_line_error


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    """A private map cache for the photo tools (``DEFOCUS_CACHE_DIR``) under the test's tmp_path."""
    d = tmp_path / "cache"
    monkeypatch.setenv("DEFOCUS_CACHE_DIR", str(d))
    return d


@pytest.fixture
def photo(tmp_path):
    """:func:`textured_photo` written as an 8-bit PNG; its path."""
    from repro.photo_io import write_photo

    return write_photo(tmp_path / "photo.png", textured_photo())
