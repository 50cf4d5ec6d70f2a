"""The ``photos`` report figure and the packaging of the region files."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_region_files_are_package_data():
    """An installed copy finds the regions: pyproject ships experiments/photos/*.json with the package."""
    from experiments.photo_regions import PHOTO_DIR, available_photos

    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    patterns = cfg["tool"]["setuptools"]["package-data"]["experiments"]
    shipped = {p.name for pat in patterns for p in (ROOT / "experiments").glob(pat)}
    assert {f"{n}.json" for n in available_photos()} <= shipped
    assert PHOTO_DIR == ROOT / "experiments" / "photos"


def test_photos_figure_is_registered_with_the_scored_presets():
    from experiments.registry import FIGURES
    from repro.figures import figure_config

    fig = FIGURES["photos"]
    assert fig.config("full").presets == ("paper", "robust", "zhuo_sim")
    assert figure_config(fig, "quick", ("paper",)).presets == ("paper",)
    assert not fig.renders


@pytest.mark.slow
def test_photos_figure_quick_computes_scores_and_plots(tmp_path):
    """Quick config (coffee, every preset): arrays, scores equal to score_photo of the stored maps, PNG + PDF.

    Through the session's case store: the coffee maps are the photo-score golden's cases (a case is keyed by
    the fields it reads, not the whole config), computed by whichever test comes first."""
    from experiments.figS2_photos import photo_view
    from experiments.figure_data import run_figure
    from experiments.registry import FIGURES

    from experiments.photo_regions import score_photo

    fig = FIGURES["photos"]
    config = fig.config("quick")
    fd = run_figure(fig, config)
    data = photo_view(fd)

    class res:  # noqa: N801 - the view's metrics as the assertions below read them
        metrics = data["metrics"]
    assert list(data["items"]) == ["coffee"]
    assert data["coffee__input"].shape == (400, 600, 3) and data["coffee__magnified"].shape == (400, 600, 3)
    assert data["coffee__magnified_scatter"].shape == (400, 600, 3)
    assert not np.array_equal(data["coffee__magnified_scatter"], data["coffee__magnified"])
    y0, y1, x0, x1 = res.metrics["photos"]["coffee"]["border_crop"]
    assert 0 <= y0 < y1 <= 400 and 0 <= x0 < x1 <= 600 and y1 - y0 == x1 - x0 == 100
    inside = data["coffee__in_focus"][y0:y1, x0:x1]
    assert inside.any() and not inside.all()  # the crop holds the in-focus region's border
    assert data["coffee__in_focus"].dtype == bool and data["coffee__in_focus"].any()
    for p in config.presets:
        m = data[f"coffee__{p}__map"]
        assert m.shape == (400, 600) and np.isfinite(m).all()
        s = score_photo("coffee", m)
        assert s["auc"] == pytest.approx(res.metrics["photos"]["coffee"][p]["auc"], abs=1e-6)  # float32 storage
    assert set(res.metrics["summary"]) == set(config.presets)
    paths = fig.plot_function()(fd, config, tmp_path / "photos")
    assert [p.suffix for p in paths] == [".png", ".pdf"] and all(p.stat().st_size > 10_000 for p in paths)


def test_an_edited_region_file_changes_the_cache_key(tmp_path, monkeypatch):
    """The code fingerprint covers .py files only; the config's regions digest covers the region files
    (in the figure's key and in every case's)."""
    import shutil

    from experiments import figS2_photos, photo_regions
    from experiments.cache_keys import cache_key
    from experiments.cases import case_key
    from experiments.registry import FIGURES

    fig = FIGURES["photos"]

    def keys():
        config = figS2_photos.PhotosConfig()
        return cache_key(fig, config), [case_key(fig, config, c) for c in fig.cases(config)]

    before = keys()
    for p in photo_regions.PHOTO_DIR.glob("*.json"):
        shutil.copy(p, tmp_path / p.name)
    monkeypatch.setattr(photo_regions, "PHOTO_DIR", tmp_path)
    assert keys() == before  # same files, same keys
    doc = (tmp_path / "coffee.json").read_text().replace('"why": "the cup', '"why": "The cup')
    (tmp_path / "coffee.json").write_text(doc)
    after = keys()
    assert after[0] != before[0]
    assert all(a != b for a, b in zip(after[1], before[1], strict=True))


def test_a_photo_case_is_keyed_by_the_fields_it_reads():
    """The quick config's coffee cases are the full config's (same keys); a field a case reads moves its key:
    the magnification factor moves the magnified cases' keys and not the maps'."""
    import dataclasses

    from experiments.cases import case_key
    from experiments.registry import FIGURES

    fig = FIGURES["photos"]
    quick, full = fig.config("quick"), fig.config("full")
    full_keys = {c: case_key(fig, full, c) for c in fig.cases(full)}
    for c in fig.cases(quick):
        assert case_key(fig, quick, c) == full_keys[c], c.label
    doubled = dataclasses.replace(quick, factor=4.0)
    for c in fig.cases(quick):
        moved = case_key(fig, doubled, c) != case_key(fig, quick, c)
        assert moved == (c.variant != "map"), c.label


def test_border_crop_sits_on_the_sharp_subjects_outline_where_the_map_jumps():
    """The crop is centred on the in-focus region's outline pixel with the steepest map, kept inside."""
    from experiments.figS2_photos import MIN_CROP_PX, border_crop

    in_focus = np.zeros((120, 200), bool)
    in_focus[30:90, 40:100] = True
    m = np.zeros((120, 200))
    m[:, 100:] = 3.0  # the map jumps on the subject's right side only
    y0, y1, x0, x1 = border_crop(in_focus, m)
    assert y1 - y0 == x1 - x0 == MIN_CROP_PX  # min(120, 200) / 4 = 30 < 48
    assert x0 <= 99 < x1 and 99 - x0 in (MIN_CROP_PX // 2, MIN_CROP_PX // 2 - 1)
    y0, y1, x0, x1 = border_crop(np.zeros((120, 200), bool), m)  # no region: the centre
    assert (y0 + y1) // 2 == 60 and (x0 + x1) // 2 == 100
