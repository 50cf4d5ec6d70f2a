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


# --------------------------------------------------------------------------------------------------
# one scorer of a render, one single_threaded, one long table


def _calls(name: str, packages=("experiments", "repro"), root: Path = ROOT) -> dict:
    """``{module path: number of calls}`` of a function called ``name`` (plain or attribute call)."""
    import ast

    out = {}
    for pkg in packages:
        for path in sorted((root / pkg).rglob("*.py")):
            n = sum(1 for node in ast.walk(ast.parse(path.read_text())) if isinstance(node, ast.Call)
                    and (getattr(node.func, "id", None) == name or getattr(node.func, "attr", None) == name))
            if n:
                out[path.relative_to(root).as_posix()] = n
    return out


def _defined(names) -> list[str]:
    import ast

    return sorted(f"{p.relative_to(ROOT).as_posix()}:{node.name}" for p in _sources()
                  for node in ast.walk(ast.parse(p.read_text()))
                  if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name in names)


def test_renders_are_scored_in_one_function():
    """evaluate_result (every metric of a pipeline run against σ_gt) is called by the one scorer only, and the
    scorer runs the pipeline exactly once; the three scorers it replaced are gone."""
    assert _calls("evaluate_result") == {"experiments/scoring.py": 1}
    assert _calls("estimate_defocus_map").get("experiments/scoring.py") == 1
    assert _calls("score_render").keys() >= {"experiments/units.py", "experiments/procedural_eval.py",
                                             "experiments/sweep_cells.py", "experiments/bench/accuracy.py"}
    import experiments.evaluation as evaluation
    import experiments.procedural_eval as procedural_eval

    assert not hasattr(evaluation, "evaluate_case") and not hasattr(procedural_eval, "_score_render")
    src = (ROOT / "experiments" / "sweep_cells.py").read_text()
    assert "score_render(" in src and "estimate_defocus_map" not in src and "evaluate_result(" not in src


def test_the_scan_finds_a_call_written_anywhere(tmp_path):
    """The call scan sees plain, attribute and nested calls (a copy hidden in a method would be found)."""
    pkg = tmp_path / "experiments"
    pkg.mkdir()
    (pkg / "a.py").write_text("import experiments.evaluation as ev\nclass C:\n    def f(self):\n"
                              "        return [ev.evaluate_result(1, 2) for _ in ()]\n")
    (pkg / "b.py").write_text("from x import evaluate_result\nevaluate_result(1)\nevaluate_result(2)\n")
    assert _calls("evaluate_result", packages=("experiments",), root=tmp_path) == {"experiments/a.py": 1,
                                                                                   "experiments/b.py": 2}


def test_single_threaded_is_defined_once():
    assert _defined({"single_threaded", "_single_threaded"}) == ["experiments/threads.py:single_threaded"]


def test_score_records_a_failing_pipeline_and_scores_a_given_result(monkeypatch):
    """No renderer: a synthetic render (a blurred step). A pipeline that raises is a recorded failure (flag 1,
    no other metric) unless the caller asks to raise; a given result is scored without running the pipeline."""
    import method
    from experiments.scoring import FAILED_METRIC, score_render
    from scenes.render import Render

    h, w = 40, 48
    x = np.linspace(0, 1, w)[None, :].repeat(h, 0)
    rgb = np.repeat((0.1 + 0.6 * (x > 0.5))[..., None], 3, axis=2).astype(np.float32)
    render = Render(rgb=rgb, depth=np.ones((h, w), np.float32), coc_px=np.zeros((h, w), np.float32),
                    sigma_px=np.full((h, w), 0.29, np.float32), occlusion_boundary=np.zeros((h, w), bool), metadata={})
    image = np.asarray(rgb, dtype=np.float64)
    ok = score_render(render, image, encoding="srgb", params=method.DefocusParams())
    assert not ok.failed and ok.flat()[FAILED_METRIC] == 0.0 and ok.flat()["sparse_n"] > 0
    again = score_render(render, image, encoding="srgb", result=ok.result)
    assert again.flat() == ok.flat() and again.seconds == 0.0

    def broken(image, params, **kw):
        raise RuntimeError("did not converge")

    monkeypatch.setattr(method, "estimate_defocus_map", broken)
    bad = score_render(render, image, encoding="srgb", params=method.DefocusParams())
    assert bad.failed and bad.flat() == {FAILED_METRIC: 1.0} and "did not converge" in bad.error
    import pytest

    with pytest.raises(RuntimeError, match="did not converge"):
        bad.raise_failure()
    with pytest.raises(ValueError, match="encoding='raw' is invalid"):
        score_render(render, image, encoding="raw")


def test_the_sweep_writes_the_long_table_of_every_evaluation(tmp_path):
    """The sweep's results.parquet has the long columns of experiments.results_table (the evaluations' format);
    its wide view is results_wide.parquet. Two cells on a synthetic render, no renderer, no Dask."""
    pytest = __import__("pytest")
    pytest.importorskip("pyarrow")
    from experiments.cases import CaseOutput
    from experiments.results_table import column_names, read_results
    from repro._sweep_engine import long_rows, sweep_cases
    from repro.sweep import build_grid

    grid = build_grid(scenes=["planes"], f_numbers=[8], estimators=["zero_crossing"], presets=["paper"],
                      params=[("alpha", [0.5, 2.0])])
    cases = sweep_cases(grid)
    outputs = {c: CaseOutput(case=c, metrics={"pipeline_failed": 0.0, "dense_textured_mae": 0.1 * i})
               for i, c in enumerate(cases)}
    rows = long_rows(grid, cases, outputs, "sweep-x")
    from experiments.results_table import write_results

    paths = write_results(tmp_path, rows, {"evaluation_id": "sweep-x"})
    table, _ = read_results(paths[0])
    assert list(table[0]) == list(column_names())
    assert {(r["variant"], r["metric"]) for r in table} == {
        (f"paper/zero_crossing alpha={a}", m) for a in ("0.5", "2") for m in ("pipeline_failed", "dense_textured_mae")}
    assert {r["source"] for r in table} == {"sweep"} and {r["aperture"] for r in table} == {8.0}
    assert len({c.needs for c in cases}) == 1  # both cells need the one render case


def test_every_table_called_results_is_the_long_table():
    """The sweep, the named-scene and the procedural evaluations write results.* through the long table's writer;
    nothing writes a wide table under that name."""
    assert _calls("write_results").keys() >= {"repro/_sweep_engine.py", "repro/evaluate.py",
                                              "repro/_evaluate_procedural.py"}
    for path in _sources():
        text = path.read_text()
        assert 'write_table(out / "results.parquet"' not in text and "results.parquet\", rows" not in text, path
