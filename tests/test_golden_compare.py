"""The golden comparison itself (tests/golden.py): per-metric tolerances, exact booleans/strings, NaN."""

from __future__ import annotations

import json

import pytest

from tests import golden as G


def test_flatten_keeps_numbers_bools_strings_and_nan():
    flat = G.flatten({"a": {"b": 1, "ok": True, "v": "reproduced", "n": None, "lst": [1, 2]}, "c": 2.5})
    assert flat == {"a.b": 1.0, "a.ok": True, "a.v": "reproduced", "a.n": None, "c": 2.5}
    assert isinstance(flat["a.ok"], bool)


def test_numbers_use_their_measured_tolerance():
    tol = {"x": {"tol": 0.1}, "y": {"tol": 0.0}}
    assert G.compare("g", {"x": 1.09, "y": 2.0}, {"x": 1.0, "y": 2.0}, tol) == []
    bad = G.compare("g", {"x": 1.11, "y": 2.0 + 1e-12}, {"x": 1.0, "y": 2.0}, tol)
    assert len(bad) == 2 and bad[0].startswith("x:") and "±0.1" in bad[0]
    # a number without a measured tolerance is a failure, not a silent pass
    assert "no measured tolerance" in G.compare("g", {"z": 1.0}, {"z": 1.0}, tol)[0]
    # the explicit rule (analytic goldens)
    assert G.compare("g", {"z": 1.0 + 1e-7}, {"z": 1.0}, None, rtol=1e-6, atol=0) == []
    assert G.compare("g", {"z": 1.1}, {"z": 1.0}, None, rtol=1e-6, atol=0)


def test_booleans_and_strings_are_compared_exactly():
    assert G.compare("g", {"b": True, "s": "reproduced"}, {"b": True, "s": "reproduced"}, {}) == []
    assert "compared exactly" in G.compare("g", {"b": False}, {"b": True}, {})[0]
    assert G.compare("g", {"s": "partly reproduced"}, {"s": "reproduced"}, {})
    assert G.compare("g", {"b": 1.0}, {"b": True}, {"b": {"tol": 1.0}})  # a bool is not the number 1


def test_nan_must_stay_nan_and_key_sets_must_match():
    assert G.compare("g", {"x": float("nan")}, {"x": None}, {"x": {"tol": 1}}) == []
    assert G.compare("g", {"x": 1.0}, {"x": None}, {"x": {"tol": 1}})
    assert G.compare("g", {"x": None}, {"x": 1.0}, {"x": {"tol": 1}})
    assert "missing from the run" in G.compare("g", {}, {"x": 1.0}, {"x": {"tol": 1}})[0]
    assert "new metric" in G.compare("g", {"x": 1.0, "y": 2.0}, {"x": 1.0}, {"x": {"tol": 1}})[0]


def test_an_infinity_must_stay_the_same_infinity():
    from tests.golden import compare

    inf = float("inf")
    assert compare("g", {"a": inf}, {"a": inf}, {"a": {"tol": 0.1}}) == []
    assert compare("g", {"a": 1e9}, {"a": inf}, {"a": {"tol": 0.1}}) and compare("g", {"a": -inf}, {"a": inf}, {})


def test_every_render_golden_has_its_tolerances_recorded_with_how_they_were_measured():
    doc = json.loads(G.TOLERANCE_FILE.read_text())
    for field in ("how", "rule", "command", "runs", "baseline", "library_versions", "metrics"):
        assert field in doc, field
    assert {r["variant"] for r in doc["runs"]} >= {"llvm_ad_rgb", "scalar_rgb"}
    assert len({r["seed"] for r in doc["runs"]}) >= 2
    for name in G.RENDER_GOLDENS:
        golden = json.loads((G.GOLDEN_DIR / f"{name}.json").read_text())
        numbers = {k for k, v in golden.items() if not isinstance(v, (bool, str))}
        assert numbers <= set(doc["metrics"].get(name, {})), (name, sorted(numbers - set(doc["metrics"].get(name, {})))[:5])
        for k in numbers:
            e = doc["metrics"][name][k]
            assert e["tol"] >= G.SPREAD_FACTOR * e["spread"] - 1e-15 and e["tol"] > 0, (name, k, e)


def test_goldens_fail_on_a_drifted_metric(tmp_path, monkeypatch):
    monkeypatch.setattr(G, "GOLDEN_DIR", tmp_path)
    monkeypatch.setattr(G, "TOLERANCE_FILE", tmp_path / "tolerances.json")
    (tmp_path / "tolerances.json").write_text(json.dumps({"metrics": {"t": {"a.x": {"tol": 0.01}}}}))
    G.Goldens(regenerate=True).check("t", {"a": {"x": 1.0, "flag": True}})
    G.Goldens(regenerate=False).check("t", {"a": {"x": 1.005, "flag": True}})
    with pytest.raises(AssertionError, match="a.x"):
        G.Goldens(regenerate=False).check("t", {"a": {"x": 1.02, "flag": True}})
    with pytest.raises(AssertionError, match="a.flag"):
        G.Goldens(regenerate=False).check("t", {"a": {"x": 1.0, "flag": False}})
    assert not list(tmp_path.glob("*.tmp"))
