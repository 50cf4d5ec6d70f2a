"""The registry type every choice by name in ``method`` is a key of (method.registry)."""

import pytest

from method import BLUR_ESTIMATORS, PRESETS, DefocusParams
from method.registry import Entry, Registry


def _double(x):
    """Twice x."""
    return 2 * x


def _registry():
    return Registry("widget", {"double": Entry(_double, "2x", capabilities={"fast"}, hooks={"inverse": abs}),
                               "plain": len, "described": "a choice with a summary only"})


def test_mapping_gives_the_value_and_entry_the_rest():
    reg = _registry()
    assert reg["double"] is _double and reg["double"](3) == 6 and reg["plain"] is len
    assert reg["described"] is None and list(reg) == ["double", "plain", "described"] and len(reg) == 3
    e = reg.entry("double")
    assert e.summary == "2x" and e.capabilities == {"fast", "inverse"} and e.hooks["inverse"] is abs
    assert reg.entry("plain").capabilities == frozenset() and reg.entry("described").summary.startswith("a choice")
    assert reg.having("inverse") == {"double"} and reg.having("slow") == frozenset()
    assert reg.hook("double", "inverse") is abs and reg.hook("plain", "inverse") is None


def test_a_plain_function_is_registered_with_its_docstring_as_summary():
    reg = _registry()
    reg["again"] = _double
    assert reg.entry("again").summary == "Twice x." and reg.entry("again").capabilities == frozenset()
    del reg["again"]
    assert "again" not in reg and 3 not in reg


def test_unknown_names_are_one_message_listing_the_allowed_names():
    reg = _registry()
    assert reg.check("plain") == "plain" and reg.check(None, optional=True) is None
    with pytest.raises(ValueError, match=r"^--widget='nope' is invalid \(unknown widget\); allowed: 'described', 'double', 'plain'$"):
        reg.check("nope", what="--widget")
    with pytest.raises(ValueError, match=r"^widget=None is invalid \(unknown widget\); allowed: 'described'"):
        reg.check(None)
    with pytest.raises(ValueError, match=r"allowed: None, 'described'"):
        reg.check(3, optional=True)
    with pytest.raises(ValueError, match="widget='x' is invalid"):
        reg.entry("x")
    with pytest.raises(ValueError, match="is invalid"):
        reg.resolve("x")
    assert reg.resolve("double") is _double


def test_check_all_names_every_unknown_name_at_once():
    reg = _registry()
    assert reg.check_all(("plain", "double")) == ["plain", "double"]
    with pytest.raises(ValueError, match=r"^unknown widget\(s\) 'a', 'b'; allowed: 'described', 'double', 'plain'$"):
        reg.check_all(["plain", "a", "b"])
    with pytest.raises(ValueError, match="no widget given"):
        reg.check_all([])


def test_bad_names_cannot_be_registered():
    with pytest.raises(ValueError, match="non-empty str"):
        Registry("widget", {"": len})


def test_describe_lists_names_with_summaries_for_help():
    assert _registry().describe().startswith("double (2x), plain (Return the number of items")


def test_the_method_registries_are_read_by_validation_and_capabilities():
    assert isinstance(BLUR_ESTIMATORS, Registry) and isinstance(PRESETS, Registry)
    assert BLUR_ESTIMATORS.having("detector_hessians") == {"model_fit", "model_fit_checked"}
    assert BLUR_ESTIMATORS.having("confidence") == {"model_fit_checked"}
    assert PRESETS["paper"] == DefocusParams() and DefocusParams.preset("robust") is PRESETS["robust"]
    with pytest.raises(ValueError, match=r"^preset='fast' is invalid \(unknown preset\); allowed: 'paper', 'robust', 'zhuo_sim'$"):
        DefocusParams.preset("fast")
