"""Estimators and presets of other packages (repro._plugins): the flags of every tool, the entry points, the
worker check, the cache keys and every bad input (one line, exit status 2). The README recipe run as written,
installed with pip and scored on Dask workers: tests/test_plugin_recipe.py."""

from __future__ import annotations

import importlib.metadata
import sys

import numpy as np
import pytest

from method import BLUR_ESTIMATORS, PRESETS, DefocusParams
from method.registry import Entry, Registry
from repro import _plugins
from repro._cli import CLIError, run_cli

PLUGIN = '''
"""A package outside the checkout."""
import numpy as np

from method import DefocusParams


def estimate_blur_one(gray, edge_map, *, params):
    """σ = 1 px at every edge pixel."""
    out = np.full(gray.shape, np.nan)
    out[edge_map.edges] = 1.0
    return out


def estimate_blur_buggy(gray, edge_map, *, params):
    """A bug inside an estimator."""
    return np.zeros(gray.shape) / undefined_name  # noqa: F821


HALF_ALPHA = DefocusParams(alpha=0.5)


def one_preset():
    """The paper with the estimator above (registered before this is called)."""
    return DefocusParams.preset("paper").replace(estimator="one")


NOT_A_FUNCTION = 3
'''


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """A module ``extpkg_blur`` on sys.path, and registries restored after the test."""
    (tmp_path / "extpkg_blur.py").write_text(PLUGIN)
    (tmp_path / "extpkg_broken.py").write_text("raise RuntimeError('boom at import')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for reg in (BLUR_ESTIMATORS, PRESETS):
        monkeypatch.setattr(reg, "_entries", dict(reg._entries))
        monkeypatch.setattr(reg, "_registered", set(reg._registered))
    monkeypatch.setattr(_plugins, "_LOADED", {})
    yield tmp_path
    for name in ("extpkg_blur", "extpkg_broken"):
        sys.modules.pop(name, None)


def _entry_points(monkeypatch, *eps):
    """Installed entry points as ``importlib.metadata.entry_points(group=...)`` returns them."""
    def fake(*, group):
        return [ep for ep in eps if ep.group == group]

    monkeypatch.setattr(importlib.metadata, "entry_points", fake)


def _ep(name, value, kind="estimator"):
    return importlib.metadata.EntryPoint(name, value, _plugins.ENTRY_POINT_GROUPS[kind])


# --- the public registration function -------------------------------------------------------------------
def test_register_adds_a_name_refuses_a_taken_one_and_accepts_the_same_entry_again():
    reg = Registry("widget", {"a": len})
    entry = reg.register("b", abs)
    assert reg["b"] is abs and entry.summary.startswith("Return the absolute") and reg.plugin_names() == ("b",)
    assert reg.register("b", abs) is entry  # the same module loaded twice: a no-op
    with pytest.raises(ValueError, match=r"^widget name='b' is invalid \(already registered: .*allowed: a name not in 'a', 'b'"):
        reg.register("b", len)
    with pytest.raises(ValueError, match="already registered"):
        reg.register("a", abs)
    with pytest.raises(ValueError, match="non-empty str"):
        reg.register("", abs)
    assert reg["a"] is len and reg.plugin_names() == ("b",)
    del reg["b"]
    assert reg.plugin_names() == ()


# --- specs ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("text, name, module, attribute", [
    ("pkg.mod:estimate_blur_x", "estimate_blur_x", "pkg.mod", "estimate_blur_x"),
    ("my_idea=pkg.mod:estimate_blur_x", "my_idea", "pkg.mod", "estimate_blur_x"),
    (" my-idea = pkg:Cls.attr ", "my-idea", "pkg", "Cls.attr"),
])
def test_a_spec_names_module_attribute_and_name(text, name, module, attribute):
    spec = _plugins.parse_spec(text, kind="estimator")
    assert (spec.name, spec.module, spec.attribute) == (name, module, attribute)
    assert _plugins.parse_spec(spec.text, kind="estimator") == dataclass_replace(spec, origin=f"--estimator-module {spec.text}")


def dataclass_replace(spec, **kw):
    import dataclasses

    return dataclasses.replace(spec, **kw)


@pytest.mark.parametrize("text", ["pkg.mod", "pkg.mod:", ":f", "pkg..mod:f", "1pkg:f", "9x=pkg:f", "a b=pkg:f",
                                  "pkg:f(1)"])
def test_a_malformed_spec_names_the_form(text):
    with pytest.raises(ValueError, match=r"--estimator-module .*(allowed: \[NAME=\]package\.module:function|"
                                         r"is invalid; allowed: letters)"):
        _plugins.parse_spec(text, kind="estimator")


# --- every tool takes the flags -------------------------------------------------------------------------
@pytest.mark.parametrize("tool, extra", [("evaluate", []), ("figures", []), ("sweep", ["--out", "x"]),
                                         ("bench", [])])
def test_every_tool_registers_the_flags_when_it_parses(tool, extra, plugin):
    import importlib

    module = importlib.import_module(f"repro.{tool}")
    parser = module._parser()
    args = parser.parse_args([*extra, "--estimator-module", "extpkg_blur:estimate_blur_one",
                              "--estimator-module", "one=extpkg_blur:estimate_blur_one",
                              "--preset-module", "extpkg_blur:HALF_ALPHA", "--preset-module", "extpkg_blur:one_preset"])
    assert args.estimator_module == ["extpkg_blur:estimate_blur_one", "one=extpkg_blur:estimate_blur_one"]
    from extpkg_blur import HALF_ALPHA, estimate_blur_one

    assert BLUR_ESTIMATORS["estimate_blur_one"] is estimate_blur_one and BLUR_ESTIMATORS["one"] is estimate_blur_one
    assert PRESETS["HALF_ALPHA"] is HALF_ALPHA and PRESETS["one_preset"].estimator == "one"
    assert DefocusParams(estimator="one").estimator == "one"
    assert [s.text for s in _plugins.loaded_specs()] == [
        "estimate_blur_one=extpkg_blur:estimate_blur_one", "one=extpkg_blur:estimate_blur_one",
        "HALF_ALPHA=extpkg_blur:HALF_ALPHA", "one_preset=extpkg_blur:one_preset"]
    assert _plugins.plugin_argv()[:2] == ["--estimator-module", "estimate_blur_one=extpkg_blur:estimate_blur_one"]


def test_entry_points_register_estimators_before_presets_and_flags_after(plugin, monkeypatch):
    _entry_points(monkeypatch, _ep("preset_one", "extpkg_blur:one_preset", "preset"),
                  _ep("one", "extpkg_blur:estimate_blur_one"))
    specs = _plugins.load_plugins(presets=["extpkg_blur:HALF_ALPHA"])
    assert [(s.kind, s.name) for s in specs] == [("estimator", "one"), ("preset", "preset_one"),
                                                  ("preset", "HALF_ALPHA")]
    assert PRESETS["preset_one"] == DefocusParams(estimator="one")
    assert set(BLUR_ESTIMATORS.plugin_names()) == {"one"} and set(PRESETS.plugin_names()) == {"preset_one", "HALF_ALPHA"}


# --- bad input: one line, exit status 2 --------------------------------------------------------------------
def _evaluate(argv):
    from repro.evaluate import main

    return run_cli(main, argv, prog="python -m repro.evaluate")


@pytest.mark.parametrize("flags, needle", [
    (["--estimator-module", "nocolon"], "--estimator-module nocolon is invalid; allowed: [NAME=]package.module:function"),
    (["--estimator-module", "extpkg_nowhere:f"], "module 'extpkg_nowhere' does not import (ModuleNotFoundError"),
    (["--estimator-module", "extpkg_broken:f"], "module 'extpkg_broken' does not import (RuntimeError: boom at import)"),
    (["--estimator-module", "extpkg_blur:nothing"], "has no attribute 'nothing'; allowed: a name defined in it ("),
    (["--estimator-module", "extpkg_blur:NOT_A_FUNCTION"], "is a int; allowed: a function fn(gray, edge_map"),
    (["--estimator-module", "extpkg_blur:HALF_ALPHA"], "is a DefocusParams; allowed: a function"),
    (["--preset-module", "extpkg_blur:estimate_blur_one"], "raised TypeError"),
    (["--preset-module", "extpkg_blur:NOT_A_FUNCTION"], "is a int; allowed: a method.DefocusParams"),
    (["--estimator-module", "model_fit=extpkg_blur:estimate_blur_one"],
     "blur estimator name='model_fit' is invalid (already registered"),
    (["--preset-module", "paper=extpkg_blur:HALF_ALPHA"], "preset name='paper' is invalid (already registered"),
    (["--estimator-module", "x=extpkg_blur:estimate_blur_one", "--estimator-module", "x=extpkg_blur:estimate_blur_buggy"],
     "name='x' is invalid (already registered"),
    (["--procedural", "2", "--split", "dev", "--preset", "zhuo_sim", "--estimator", "model_fit"],
     "--estimator model_fit with --preset zhuo_sim: DefocusParams.edge_detector='canny' is invalid"),
    (["--procedural", "2", "--split", "dev", "--estimator", "nope"], "unknown estimator(s) 'nope'"),
])
def test_bad_plugin_input_is_one_line_and_exit_2(flags, needle, plugin, capsys, monkeypatch):
    from repro import _runner

    monkeypatch.setattr(_runner, "start_client", lambda **k: pytest.fail("an engine was started"))
    out = plugin / "out"
    assert _evaluate([*flags, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err, err
    assert not out.exists()


def test_an_entry_point_that_raises_on_import_is_one_line_naming_it(plugin, capsys, monkeypatch):
    _entry_points(monkeypatch, _ep("boom", "extpkg_broken:f"))
    assert _evaluate(["--scenes", "planes", "--out", str(plugin / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert ("entry point boom = extpkg_broken:f (group defocus_repro.estimators" in err
            and "RuntimeError: boom at import" in err), err
    # --debug shows the plugin's own traceback first
    assert _evaluate(["--scenes", "planes", "--debug", "--out", str(plugin / "out")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" in err and "extpkg_broken.py" in err and "raise RuntimeError('boom at import')" in err


def test_without_plugins_nothing_is_registered_and_the_flags_parse_empty(monkeypatch):
    from repro.evaluate import _parser

    monkeypatch.setattr(_plugins, "_LOADED", {})
    _entry_points(monkeypatch)
    args = _parser().parse_args([])
    assert args.estimator_module == [] and args.preset_module == [] and _plugins.loaded_specs() == ()


# --- a bug inside a registered estimator keeps its traceback --------------------------------------------------
def _threaded_client(*, workers, scheduler):
    """``repro._runner.start_client`` on a LocalCluster of one worker thread in this process: the Dask path
    (futures, the worker's exception and traceback sent back) without starting worker processes."""
    import logging

    from dask.distributed import Client, LocalCluster

    from repro._runner import _with_plugins

    cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None,
                           silence_logs=logging.ERROR)
    return _with_plugins(Client(cluster), cluster)


@pytest.mark.render
@pytest.mark.parametrize("engine", ["here", "dask"])
def test_a_bug_inside_a_registered_estimator_shows_its_traceback(engine, plugin, monkeypatch):
    """In this process (``--workers 1``) and on a Dask worker (``--workers 2``, the worker a thread here: the
    traceback crosses Dask's future, not a process), the estimator's NameError and its own frame are shown."""
    started = []
    if engine == "dask":
        pytest.importorskip("distributed")
        monkeypatch.setattr("repro._runner.start_client", lambda **kw: started.append(kw) or _threaded_client(**kw))
    with pytest.raises(RuntimeError) as info:
        _evaluate(["--estimator-module", "extpkg_blur:estimate_blur_buggy", "--estimator", "estimate_blur_buggy",
                   "--scenes", "planes", "--fnumber", "8", "--workers", "1" if engine == "here" else "2",
                   "--out", str(plugin / "out"), "-q"])
    text = str(info.value)
    assert "NameError: name 'undefined_name' is not defined" in text, text
    assert "extpkg_blur.py" in text and "estimate_blur_buggy" in text, text  # the plugin's own frame
    assert started == ([{"workers": 2, "scheduler": None}] if engine == "dask" else [])


# --- Dask workers: the paths go along, other run-time entries are refused -------------------------------------
class _FakeClient:
    """What install_on_workers uses of a dask Client: register_plugin and run (one worker)."""

    def __init__(self, worker_names):
        self.plugins, self.worker_names = [], worker_names

    def register_plugin(self, plugin):
        self.plugins.append(plugin)

    def run(self, fn):
        assert fn is _plugins.registered_names
        return {"tcp://worker:1": self.worker_names}


def test_workers_get_the_import_paths_and_a_name_they_lack_is_refused(plugin):
    pytest.importorskip("distributed")
    _plugins.load_plugins(["one=extpkg_blur:estimate_blur_one"], entry_points=False)
    client = _FakeClient(_plugins.registered_names())
    from repro._plugin_worker import install_on_workers

    install_on_workers(client)
    (sent,) = client.plugins
    assert sent.specs == (("estimator", "one=extpkg_blur:estimate_blur_one"),)
    import pickle

    assert pickle.loads(pickle.dumps(sent)).specs == sent.specs  # by value: paths, never a registry
    lacking = _FakeClient({**_plugins.registered_names(),
                           "estimator": [n for n in BLUR_ESTIMATORS if n != "one"]})
    with pytest.raises(CLIError, match=r"blur estimator\(s\) 'one' registered in this process are unknown on the "
                                       r"Dask worker tcp://worker:1; allowed: entries registered by import path"):
        install_on_workers(lacking)


def test_the_worker_plugin_registers_the_paths_in_a_workers_process(plugin):
    pytest.importorskip("distributed")
    from repro._plugin_worker import LoadPlugins

    LoadPlugins([("estimator", "one=extpkg_blur:estimate_blur_one"), ("preset", "p=extpkg_blur:one_preset")]).setup(None)
    assert BLUR_ESTIMATORS.plugin_names() == ("one",) and PRESETS["p"].estimator == "one"


# --- caches are keyed by other packages' code ---------------------------------------------------------------
def test_cache_keys_hold_plugin_code_only_when_plugins_are_loaded(plugin):
    from experiments.cache_keys import cache_key, plugin_fingerprints
    from experiments.registry import FIGURES

    fig = FIGURES["fig10"]
    before = cache_key(fig, fig.config("quick"))
    assert plugin_fingerprints() == {} and "plugins" not in before
    _plugins.load_plugins(["one=extpkg_blur:estimate_blur_one"], ["extpkg_blur:HALF_ALPHA"], entry_points=False)
    fp = plugin_fingerprints()
    assert set(fp) == {"blur estimator", "preset"} and fp["preset"]["HALF_ALPHA"]["alpha"] == 0.5
    after = cache_key(fig, fig.config("quick"))
    assert after["plugins"] == fp and {k: v for k, v in after.items() if k != "plugins"} == before
    # another estimator body under the same name: another key
    (plugin / "extpkg_blur.py").write_text(PLUGIN.replace("out[edge_map.edges] = 1.0", "out[edge_map.edges] = 2.0"))
    sys.modules.pop("extpkg_blur")
    import importlib

    new = importlib.import_module("extpkg_blur")
    BLUR_ESTIMATORS._entries["one"] = Entry(new.estimate_blur_one)
    assert plugin_fingerprints()["blur estimator"]["one"] != fp["blur estimator"]["one"]


# --- --procedural --estimator: the plan ------------------------------------------------------------------------
def test_a_procedural_plan_with_estimators_runs_each_preset_with_each():
    from experiments.procedural_eval import ProceduralPlan, plan_evaluation

    plain = plan_evaluation(2, split="dev", presets=["paper"])
    assert plain.runs() == [("paper", None)] and "estimators" not in plain.to_dict()
    assert "--estimator" not in plain.command()
    plan = plan_evaluation(2, split="dev", estimators=["model_fit", "zero_crossing"])
    assert plan.presets == ("paper",) and plan.runs() == [("paper", "model_fit"), ("paper", "zero_crossing")]
    assert plan.to_dict()["estimators"] == ["model_fit", "zero_crossing"]
    assert plan.command()[-3:] == ["--estimator", "model_fit", "zero_crossing"]
    assert plan.evaluation_id != plain.evaluation_id
    assert ProceduralPlan(**{k: tuple(v) if isinstance(v, list) else v for k, v in plan.to_dict().items()}) == plan
    both = plan_evaluation(2, split="dev", presets=["paper", "robust"], estimators=["model_fit"])
    assert both.runs() == [("paper", "model_fit"), ("robust", "model_fit")]


def test_procedural_scoring_labels_rows_by_preset_and_estimator(monkeypatch):
    """The scoring loop gives each run its estimator (checked without rendering: the method is stubbed)."""
    import types

    from experiments import procedural_eval as pe

    plan = pe.plan_evaluation(2, split="dev", presets=["paper"], estimators=["model_fit", "zero_crossing"])
    seen = []
    monkeypatch.setattr("method.estimate_defocus_map", lambda image, params, **kw: seen.append(params.estimator) or "r")
    monkeypatch.setattr("experiments.evaluation.input_image", lambda render, **k: np.zeros((4, 4, 3)))
    monkeypatch.setattr("experiments.baselines.baseline_rows", lambda render, ids, **k: [])
    monkeypatch.setattr("experiments.evaluation.evaluate_result", lambda result, render, image, **k: {"m": 1.0})
    monkeypatch.setattr("experiments.evaluation.flatten_metrics", lambda m: m)
    rows, seconds = pe._render_rows(types.SimpleNamespace(), {"aperture": 8.0, "scene": "s"}, plan, 0, [], [])
    assert seen == ["model_fit", "zero_crossing"] and set(seconds) == {"paper+model_fit", "paper+zero_crossing"}
    assert {(r["preset"], r["estimator"]) for r in rows} == {("paper", "model_fit"), ("paper", "zero_crossing")}
    summary = pe.summary_rows([{**r, "split": "dev", "scene_size": "small"} for r in rows
                               if r["metric"] == "pipeline_failed"])
    assert sorted(r["estimator"] for r in summary) == ["model_fit", "zero_crossing"]


def test_a_failing_run_keeps_its_traceback(monkeypatch):
    import types

    from experiments import procedural_eval as pe

    def buggy(image, params, **kw):
        return undefined_in_test  # noqa: F821

    plan = pe.plan_evaluation(2, split="dev", presets=["paper"])
    monkeypatch.setattr("method.estimate_defocus_map", buggy)
    monkeypatch.setattr("experiments.evaluation.input_image", lambda render, **k: np.zeros((4, 4, 3)))
    monkeypatch.setattr("experiments.baselines.baseline_rows", lambda render, ids, **k: [])
    failures, tracebacks = [], []
    pe._render_rows(types.SimpleNamespace(), {"aperture": 8.0, "scene": "s"}, plan, 0, failures, tracebacks)
    assert failures == ["paper on s f/8 srgb none: NameError: name 'undefined_in_test' is not defined"]
    assert "Traceback" in tracebacks[0] and "in buggy" in tracebacks[0]


def test_readme_names_the_groups_the_code_loads():
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    for group in _plugins.ENTRY_POINT_GROUPS.values():
        assert group in text


@pytest.mark.slow
def test_a_worker_that_joins_later_registers_the_plugins_too(plugin):
    """On a real LocalCluster: the client's plugins reach its first worker and one added afterwards."""
    pytest.importorskip("distributed")
    from repro._runner import start_client

    _plugins.load_plugins(["one=extpkg_blur:estimate_blur_one"], ["extpkg_blur:one_preset"], entry_points=False)
    client, cluster = start_client(workers=1, scheduler=None)
    try:
        cluster.scale(2)
        client.wait_for_workers(2, timeout=120)
        names = client.run(_plugins.registered_names)
        files = client.run(lambda: sys.modules["extpkg_blur"].__file__)
    finally:
        client.close()
        cluster.close()
    assert len(names) == 2
    for got in names.values():
        assert "one" in got["estimator"] and "one_preset" in got["preset"], names
    assert set(files.values()) == {str(plugin / "extpkg_blur.py")}  # imported by path on each worker
