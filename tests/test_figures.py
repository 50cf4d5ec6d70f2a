"""The figure framework: registry, cached compute, and the ``python -m repro.figures`` CLI."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests import tolerances as tol

ROOT = Path(__file__).resolve().parents[1]


def _cli(*args, cache_dir=None, timeout=900):
    env = os.environ.copy()
    if cache_dir is not None:
        env["DEFOCUS_CACHE_DIR"] = str(cache_dir)
        # keep compiled kernels in the project's cache (only the figure results are fresh)
        env.setdefault("DRJIT_CACHE_DIR", str(ROOT / ".cache" / "drjit"))
    return subprocess.run([sys.executable, "-m", "repro.figures", *map(str, args)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout)


# --- registry (no rendering) -------------------------------------------------------------------
@dataclasses.dataclass(frozen=True, kw_only=True)
class _ToyConfig:
    n: int = 5  # number of samples


def _toy_compute(config):
    _toy_compute.calls += 1
    x = np.arange(config.n, dtype=np.float64)
    return {"x": x, "y": x**2, "metrics": {"sum": float((x**2).sum()), "nan": float("nan")}}


_toy_compute.calls = 0


def _toy_figure():
    from experiments.registry import Figure

    return Figure(name="toy", title="toy", compute=_toy_compute, plot="none:none",
                  configs={"quick": _ToyConfig(n=3), "full": _ToyConfig()}, renders=False)


def test_compute_cached_roundtrip_and_force(tmp_path):
    from experiments.registry import compute_cached

    fig = _toy_figure()
    _toy_compute.calls = 0
    a = compute_cached(fig, fig.config("full"), cache_dir=tmp_path)
    b = compute_cached(fig, fig.config("full"), cache_dir=tmp_path)
    assert (a.cached, b.cached, _toy_compute.calls) == (False, True, 1)
    np.testing.assert_array_equal(b.arrays["y"], [0, 1, 4, 9, 16])
    assert b.metrics == a.metrics and b.metrics["sum"] == 30.0 and b.metrics["nan"] is None
    c = compute_cached(fig, fig.config("quick"), cache_dir=tmp_path)  # other config → other entry
    assert not c.cached and c.arrays["x"].size == 3
    d = compute_cached(fig, fig.config("full"), cache_dir=tmp_path, force=True)
    assert not d.cached and _toy_compute.calls == 3


def test_figure_rejects_mutable_config_and_bad_mode():
    from experiments.registry import Figure

    @dataclasses.dataclass
    class Mutable:
        n: int = 1

    with pytest.raises(ValueError, match="frozen"):
        Figure(name="x", title="x", compute=_toy_compute, plot="a:b", configs={"quick": Mutable(), "full": Mutable()})
    with pytest.raises(ValueError, match="mode"):
        _toy_figure().config("medium")


def test_registry_has_fig2_and_fig10_with_frozen_configs():
    from experiments.registry import FIGURES

    assert {"fig2", "fig10"} <= set(FIGURES)
    for fig in FIGURES.values():
        for mode in ("quick", "full"):
            cfg = fig.config(mode)
            with pytest.raises(dataclasses.FrozenInstanceError):
                setattr(cfg, dataclasses.fields(cfg)[0].name, None)


# --- CLI ---------------------------------------------------------------------------------------
def test_cli_list():
    proc = _cli("--list")
    assert proc.returncode == 0, proc.stderr
    names = [line.split()[0] for line in proc.stdout.splitlines() if line.strip()]
    assert "fig2" in names and "fig10" in names


def test_cli_unknown_name_exits_2_with_one_line(tmp_path):
    proc = _cli("fig99", "--out", tmp_path)
    assert proc.returncode == 2
    lines = [l for l in proc.stderr.splitlines() if l.strip()]
    assert len(lines) == 1 and "fig99" in lines[0], proc.stderr
    assert not list(tmp_path.iterdir())


def test_cli_bad_jobs_exits_2(tmp_path):
    proc = _cli("fig10", "--jobs", "0", "--out", tmp_path)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1


@pytest.fixture(scope="module")
def fig10_quick(tmp_path_factory):
    """Two runs of ``repro.figures fig10 --quick`` against a fresh cache: outputs and both metrics files."""
    cache = tmp_path_factory.mktemp("cache")
    out = tmp_path_factory.mktemp("figures")
    first = _cli("fig10", "--quick", "--out", out, cache_dir=cache)
    assert first.returncode == 0, first.stderr[-3000:]
    m1 = json.loads((out / "fig10.metrics.json").read_text())
    second = _cli("fig10", "--quick", "--out", out, cache_dir=cache)
    assert second.returncode == 0, second.stderr[-3000:]
    m2 = json.loads((out / "fig10.metrics.json").read_text())
    return {"out": out, "m1": m1, "m2": m2, "cache": cache}


@pytest.mark.render
def test_fig10_quick_writes_outputs_and_matches_eq5(fig10_quick):
    out, m = fig10_quick["out"], fig10_quick["m1"]
    for name in ("fig10.png", "fig10.pdf", "fig10.metrics.json"):
        assert (out / name).stat().st_size > 1000 or name.endswith(".json")
    assert (out / "fig10.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "fig10.pdf").read_bytes()[:5] == b"%PDF-"
    assert m["mode"] == "quick" and m["cache"]["hit"] is False
    assert m["config"]["spp"] > 0 and "sigma_convention" in m and m["versions"]["mitsuba"]
    assert m["metrics"]["n_points"] >= 12
    assert m["metrics"]["max_rel_err"] < tol.FIG10_MAX_REL_ERR
    assert not list(out.glob("*.tmp*"))


@pytest.mark.render
def test_fig10_second_run_uses_cache(fig10_quick):
    m1, m2 = fig10_quick["m1"], fig10_quick["m2"]
    assert m2["cache"]["hit"] is True
    assert m2["metrics"] == m1["metrics"]


@pytest.mark.render
def test_fig2_and_fig10_in_parallel(fig10_quick, tmp_path):
    """``--jobs 2``: fig2 computed in one worker while fig10 comes from the cache in another."""
    proc = _cli("fig2", "fig10", "--quick", "--jobs", "2", "--out", tmp_path, cache_dir=fig10_quick["cache"])
    assert proc.returncode == 0, proc.stderr[-3000:]
    for stem in ("fig2", "fig10"):
        for ext in (".png", ".pdf", ".metrics.json"):
            assert (tmp_path / f"{stem}{ext}").is_file()
    m10 = json.loads((tmp_path / "fig10.metrics.json").read_text())
    assert m10["cache"]["hit"] is True and m10["metrics"] == fig10_quick["m1"]["metrics"]
    m2 = json.loads((tmp_path / "fig2.metrics.json").read_text())["metrics"]
    assert m2["max_ratio_rel_err"] < tol.FIG2_RATIO_RTOL
    # the small sensor blurs ~3× less at the same field of view and f-number (Eq. 6)
    assert 2.5 < m2["measured_ratio_median"] < 4.0


def test_code_fingerprint_ignores_plots_and_claims_but_not_compute_code(tmp_path, monkeypatch):
    import experiments.registry as reg

    for rel, text in {"method/a.py": "x = 1\n", "scenes/s.py": "v = 1\n", "experiments/fig.py": "y = 1\n",
                      "experiments/claims.py": "z = 1\n", "experiments/plotting/p.py": "w = 1\n"}.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    # the fingerprint of a fake checkout: packages resolved to its folders, paths relative to its root
    import types

    import defocus_cache as storage

    monkeypatch.setattr(reg, "importlib", types.SimpleNamespace(import_module=lambda name: tmp_path / name))
    monkeypatch.setattr(storage, "_PROJECT_ROOT", tmp_path)

    def fp():
        reg.code_fingerprint.cache_clear()
        return reg.code_fingerprint()

    base = fp()
    (tmp_path / "experiments/claims.py").write_text("z = 2\n")
    (tmp_path / "experiments/plotting/p.py").write_text("w = 2\n")
    assert fp() == base
    (tmp_path / "method/a.py").write_text("x = 2\n")
    assert fp() != base
    reg.code_fingerprint.cache_clear()


# --- --preset (method parameter presets of the figures with a `presets` config field) ------------
def test_preset_names_keep_paper_first_and_reject_unknown():
    from repro.figures import preset_names

    assert preset_names(["robust", "zhuo_sim"]) == ("paper", "robust", "zhuo_sim")
    assert preset_names(["zhuo_sim", "paper", "zhuo_sim"]) == ("paper", "zhuo_sim")
    assert preset_names(["paper"]) == ("paper",)
    with pytest.raises(ValueError, match=r"unknown preset\(s\) 'nope'; allowed: 'paper', 'robust', 'zhuo_sim'"):
        preset_names(["robust", "nope"])


def test_figure_config_sets_presets_only_where_the_config_has_the_field():
    from experiments.registry import FIGURES
    from repro.figures import figure_config

    with_field = set()
    for name, fig in FIGURES.items():
        base = fig.config("quick")
        assert figure_config(fig, "quick") is base  # no --preset: the config as registered
        cfg = figure_config(fig, "quick", ("paper", "zhuo_sim"))
        if any(f.name == "presets" for f in dataclasses.fields(base)):
            with_field.add(name)
            assert cfg.presets == ("paper", "zhuo_sim")
            assert dataclasses.replace(cfg, presets=base.presets) == base  # nothing else changed
        else:
            assert cfg is base
    assert {"fig6", "fig7", "fig11"} <= with_field and "fig10" not in with_field


def test_cli_preset_reaches_every_selected_figure(tmp_path, monkeypatch):
    """``--preset`` is passed to every figure (the ones without a `presets` field ignore it)."""
    import repro.figures as rf

    calls = []

    def fake(name, mode, out_dir, force, presets=None):
        calls.append((name, mode, presets))
        return {"name": name, "cached": True, "seconds": 0.0, "files": [], "metrics": {}}

    monkeypatch.setattr(rf, "_make_figure_safe", fake)
    assert rf.main(["fig6", "fig10", "--quick", "--preset", "zhuo_sim", "robust", "--out", str(tmp_path)]) == 0
    assert calls == [("fig6", "quick", ("paper", "zhuo_sim", "robust")),
                     ("fig10", "quick", ("paper", "zhuo_sim", "robust"))]
    calls.clear()
    assert rf.main(["fig6", "--out", str(tmp_path)]) == 0
    assert calls == [("fig6", "full", None)]


def test_cli_unknown_preset_exits_2_with_one_line(tmp_path, capsys):
    from repro._cli import run_cli
    from repro.figures import PROG, main

    out = tmp_path / "out"
    assert run_cli(main, ["fig6", "--quick", "--preset", "robust", "nope", "--out", str(out)], prog=PROG) == 2
    lines = [l for l in capsys.readouterr().err.splitlines() if l.strip()]
    assert len(lines) == 1 and "nope" in lines[0] and "'paper', 'robust', 'zhuo_sim'" in lines[0], lines
    assert not out.exists()
