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


def _cli(*args, cache_dir=None, env=None, timeout=900):
    env = os.environ.copy() if env is None else dict(env)
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


def test_a_one_unit_figure_is_one_cached_case_and_force_recomputes(tmp_path):
    from experiments.cases import run_case

    fig = _toy_figure()
    (case,) = fig.cases(fig.config("full"))
    _toy_compute.calls = 0
    a = run_case(fig, fig.config("full"), case, cache_dir=tmp_path)
    b = run_case(fig, fig.config("full"), case, cache_dir=tmp_path)
    assert (a.cached, b.cached, _toy_compute.calls) == (False, True, 1)
    np.testing.assert_array_equal(b.arrays()["y"], [0, 1, 4, 9, 16])
    assert b.metrics == a.metrics == {"sum": 30.0, "nan": None} and b.info == {"sum": 30.0, "nan": None}
    c = run_case(fig, fig.config("quick"), case, cache_dir=tmp_path)  # other config → other entry
    assert not c.cached and c.arrays()["x"].size == 3
    d = run_case(fig, fig.config("full"), case, cache_dir=tmp_path, force=True)
    assert not d.cached and _toy_compute.calls == 3


def test_figure_rejects_mutable_config_bad_mode_and_a_half_declared_unit():
    from experiments.registry import Figure

    @dataclasses.dataclass
    class Mutable:
        n: int = 1

    with pytest.raises(ValueError, match="frozen"):
        Figure(name="x", title="x", compute=_toy_compute, plot="a:b", configs={"quick": Mutable(), "full": Mutable()})
    with pytest.raises(ValueError, match="mode"):
        _toy_figure().config("medium")
    cfgs = {"quick": _ToyConfig(), "full": _ToyConfig()}
    with pytest.raises(ValueError, match="cases_fn and case_fn, or compute"):
        Figure(name="x", title="x", plot="a:b", configs=cfgs, cases_fn=lambda c: ())
    with pytest.raises(ValueError, match="cases_fn and case_fn, or compute"):
        Figure(name="x", title="x", plot="a:b", configs=cfgs, compute=_toy_compute, cases_fn=lambda c: (),
               case_fn=lambda c, k, i: {})


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
    assert "--workers/--jobs" in proc.stderr


def _store_all_but_the_last_case(data, cache) -> None:
    """Copy every case of ``data`` (a quick figure computed in this session) but its last from the session's
    case store into the case store of the cache folder ``cache`` (same keys, so the same entries)."""
    import shutil

    from defocus_cache import Cache
    from experiments.cache_keys import CACHE_SUBDIR
    from experiments.cases import case_key, stored_case

    for case in list(data.outputs)[:-1]:
        src = stored_case(data.figure, data.config, case)
        assert src is not None, case.label
        shutil.copytree(src, Cache(Path(cache) / CACHE_SUBDIR).path_for(case_key(data.figure, data.config, case)))


@pytest.fixture(scope="module")
def fig10_quick(tmp_path_factory, quick_figure):
    """Two runs of ``repro.figures fig10 --quick`` against a fresh cache holding fig10's quick cases but the last
    (from the session's case store, where the calibration tests and the claims golden read them): the first
    run computes that case and reads the others, the second reads all. Outputs and both metrics files."""
    cache = tmp_path_factory.mktemp("cache")
    out = tmp_path_factory.mktemp("figures")
    _store_all_but_the_last_case(quick_figure("fig10"), cache)
    first = _cli("fig10", "--quick", "--workers", "1", "--out", out, cache_dir=cache)
    assert first.returncode == 0, first.stderr[-3000:]
    m1 = json.loads((out / "fig10.metrics.json").read_text())
    t1 = read_table(out).where(figure="fig10").rows
    second = _cli("fig10", "--quick", "--workers", "1", "--out", out, cache_dir=cache)
    assert second.returncode == 0, second.stderr[-3000:]
    m2 = json.loads((out / "fig10.metrics.json").read_text())
    return {"out": out, "m1": m1, "m2": m2, "t1": t1, "t2": read_table(out).where(figure="fig10").rows, "cache": cache}


def read_table(folder):
    from experiments.results_query import read_table as read

    return read(folder)


@pytest.mark.render
def test_fig10_quick_writes_outputs_and_matches_eq5(fig10_quick):
    out, m = fig10_quick["out"], fig10_quick["m1"]
    for name in ("fig10.png", "fig10.pdf", "fig10.metrics.json"):
        assert (out / name).stat().st_size > 1000 or name.endswith(".json")
    assert (out / "fig10.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "fig10.pdf").read_bytes()[:5] == b"%PDF-"
    assert m["mode"] == "quick" and m["cache"]["hit"] is False
    assert (m["cache"]["cases"], m["cache"]["cached_cases"]) == (3, 2)  # one case computed, two read back
    assert m["config"]["spp"] > 0 and "sigma_convention" in m and m["versions"]["mitsuba"]
    paper = read_table(out).where(figure="fig10", variant="paper")
    assert paper.value("n_points") >= 12
    assert paper.value("max_rel_err") < tol.FIG10_MAX_REL_ERR
    # the held-out scenes' cameras at their own depths obey Eq. (5) as well
    held_out = read_table(out).where(figure="fig10", scene_set="procedural_test")
    assert len(held_out.distinct("scene")) == 2
    assert max(r["value"] for r in held_out.where(metric="max_rel_err")) < tol.FIG10_MAX_REL_ERR
    assert not list(out.glob("*.tmp*"))


@pytest.mark.render
def test_fig10_second_run_uses_cache(fig10_quick):
    m1, m2 = fig10_quick["m1"], fig10_quick["m2"]
    assert m2["cache"]["hit"] is True and m1["cases"] == m2["cases"]
    assert fig10_quick["t2"] == fig10_quick["t1"]


@pytest.mark.render
def test_fig2_and_fig10_on_two_dask_workers(fig10_quick, tmp_path):
    """``--jobs 2`` (= ``--workers 2``): the cases on a LocalCluster of two workers; fig2 computed, fig10 from
    the cache; the table rows of fig10 are the serial run's. Its case store holds a copy of the fig10 run's
    cases, its renders are the session's (fig2's renders made once for every test that needs them)."""
    import shutil

    from tests.test_interrupts import _store_sharing_renders

    env = _store_sharing_renders(tmp_path / "cache")
    shutil.copytree(fig10_quick["cache"] / "figures", tmp_path / "cache" / "figures")
    out = tmp_path / "out"
    proc = _cli("fig2", "fig10", "--quick", "--jobs", "2", "--out", out, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "engine: LocalCluster with 2 worker(s)" in proc.stderr
    for stem in ("fig2", "fig10"):
        for ext in (".png", ".pdf", ".metrics.json"):
            assert (out / f"{stem}{ext}").is_file()
    m10 = json.loads((out / "fig10.metrics.json").read_text())
    assert m10["cache"]["hit"] is True and read_table(out).where(figure="fig10").rows == fig10_quick["t1"]
    fig2 = read_table(out).where(figure="fig2")
    assert fig2.value("max_ratio_rel_err") < tol.FIG2_RATIO_RTOL
    # the small sensor blurs ~3× less at the same field of view and f-number (Eq. 6)
    assert 2.5 < fig2.value("measured_ratio_median") < 4.0


def test_code_fingerprint_ignores_plots_and_claims_but_not_compute_code(tmp_path, monkeypatch):
    import experiments.cache_keys as reg

    for rel, text in {"method/a.py": "x = 1\n", "scenes/s.py": "v = 1\n", "experiments/fig.py": "y = 1\n",
                      "experiments/claims/rules.py": "z = 1\n", "experiments/plotting/p.py": "w = 1\n"}.items():
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
    (tmp_path / "experiments/claims/rules.py").write_text("z = 2\n")
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
    """``--preset`` is set on every figure whose config has the field (the others keep theirs)."""
    import repro._runner as runner
    import repro.figures as rf

    calls = []

    def fake(jobs, **kwargs):
        calls.append([(j.figure.name, j.mode, getattr(j.config, "presets", None)) for j in jobs])
        return [runner.FigureRun(job=j) for j in jobs]

    monkeypatch.setattr(runner, "run_figures", fake)
    assert rf.main(["fig6", "fig10", "--quick", "--preset", "zhuo_sim", "robust", "--workers", "1",
                    "--out", str(tmp_path)]) == 0
    assert calls == [[("fig6", "quick", ("paper", "zhuo_sim", "robust")), ("fig10", "quick", None)]]
    calls.clear()
    assert rf.main(["fig6", "--workers", "1", "--out", str(tmp_path)]) == 0
    assert calls == [[("fig6", "full", ("paper", "robust"))]]


def test_cli_unknown_preset_exits_2_with_one_line(tmp_path, capsys):
    from repro._cli import run_cli
    from repro.figures import PROG, main

    out = tmp_path / "out"
    assert run_cli(main, ["fig6", "--quick", "--preset", "robust", "nope", "--out", str(out)], prog=PROG) == 2
    lines = [l for l in capsys.readouterr().err.splitlines() if l.strip()]
    assert len(lines) == 1 and "nope" in lines[0] and "'paper', 'robust', 'zhuo_sim'" in lines[0], lines
    assert not out.exists()


def test_fig5_to_fig8_expose_at_least_16_independent_cases_at_the_full_preset():
    """The unit of parallel work is a case (scene set × scene × preset × aperture …), not a figure: at the full
    preset each of figs. 5–8 has at least 16 cases that do not need one another."""
    from experiments.cases import order_cases
    from experiments.registry import FIGURES

    for name in ("fig5", "fig6", "fig7", "fig8"):
        fig = FIGURES[name]
        cases = order_cases(fig.cases(fig.config("full")))
        needed = {n for c in cases for n in c.needs}
        leaves = [c for c in cases if c not in needed]  # no other case waits for these
        assert len(leaves) >= 16, (name, len(leaves))
        assert len(set(cases)) == len(cases)
        assert {c.scene_size for c in cases if c.scene} <= {"full", None}


@pytest.mark.parametrize("argv, out", [(["--quick"], "report/quick/figures"), ([], "report/figures"),
                                       (["--quick", "--out", "mine"], "mine")])
def test_cli_quick_runs_default_to_the_ignored_report_quick(tmp_path, monkeypatch, argv, out):
    """A quick run never writes into the committed report/figures unless --out says so."""
    import repro._runner as runner
    import repro.figures as rf

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(runner, "run_figures", lambda jobs, **kw: [runner.FigureRun(job=j) for j in jobs])
    assert rf.main(["fig10", "--workers", "1", *argv]) == 0
    made = sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*") if p.is_dir())
    assert made == [out.rsplit("/", i)[0] for i in range(out.count("/"), -1, -1)]

