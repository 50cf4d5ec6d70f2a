"""Shared pytest configuration."""

import os
import warnings
from pathlib import Path

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
        "--cpu-durations", type=int, default=None, metavar="N",
        help="list the N tests that used the most CPU seconds (user + system of the pytest process and of its "
             "finished subprocesses, per phase; a shared fixture counts in the test that built it) and the total",
    )
    parser.addoption(
        "--regen-references", action="store_true", default=False,
        help="rewrite the rendered reference EXRs in tests/references/ from this run (review them!)",
    )


@pytest.fixture(scope="session")
def quick_figure():
    """``quick_figure(name)``: every case of a quick figure (:class:`experiments.figure_data.FigureData`),
    computed in this process through the shared figure cache once per test session (every test reads the
    same object; another pytest worker asking for a case being computed waits for it on the cache's lock)."""
    from tests.golden import quick_data

    done: dict = {}

    def get(name: str):
        if name not in done:
            done[name] = quick_data(name)
        return done[name]

    return get


@pytest.fixture(scope="session")
def quick_table(quick_figure):
    """The rows of every claim figure's quick cases (:class:`experiments.results_query.Results`), the table
    ``python -m repro.figures --quick`` writes. The figures are computed in an order that depends on the
    pytest-xdist worker, so two workers building it split the work through the cache's locks."""
    from experiments.results_query import Results
    from tests.golden import CLAIM_FIGURES

    order = list(CLAIM_FIGURES)
    if os.environ.get("PYTEST_XDIST_WORKER", "gw0") not in ("gw0", "master"):
        order.reverse()
    rows = {name: quick_figure(name).rows() for name in order}
    return Results([r for name in CLAIM_FIGURES for r in rows[name]])


@pytest.fixture(scope="session")
def photo_scores():
    """Every shipped photo × scored preset's region scores, ``{"<photo>.<preset>.<key>": value}``
    (:func:`tests.test_photo_scores.current_scores`): the photos figure's map cases, computed through the
    case store once per session (the photos figure test reads its coffee maps from the same stored cases)."""
    from tests.test_photo_scores import current_scores

    return current_scores()


@pytest.fixture
def goldens(request):
    """Golden-number checker (see tests/golden.py)."""
    from tests.golden import Goldens

    return Goldens(request.config.getoption("--regen-goldens"))


# --- which tests read renders: the `render` marker, checked -------------------------------------------
#: Set to a file path to append "<nodeid>\t<what>" for every render or figure-cache access of a test
#: (how the `render` markers were found; see docs/testing.md).
RENDER_LOG_ENV = "DEFOCUS_TEST_RENDER_LOG"
_current = {"item": None, "figure_depth": [], "fixtures": []}


def _render_log(what):
    item = _current["item"]
    path = os.environ.get(RENDER_LOG_ENV)
    if item is None or not path:
        return
    with open(path, "a") as fh:
        fh.write(f"{item.nodeid}\t{what}\n")


@pytest.fixture(autouse=True, scope="session")
def _watch_render_cache():
    """Wrap defocus_cache.Cache.get_or_build: a test not marked ``render`` that reads the render cache
    fails in a run that deselects ``render`` (``make test-fast``) and warns in any other run (in-process
    renders only; CLIs run in subprocesses are marked by hand)."""
    import defocus_cache

    real = defocus_cache.Cache.get_or_build

    def get_or_build(self, key, build):
        kind = Path(self.root).name
        if kind == "renders":
            _render_log("renders")
            for name in _current["figure_depth"]:
                _render_log(f"figure-needs-renders:{name}")
            for name in _current["fixtures"]:
                _render_log(f"fixture-needs-renders:{name}")
            item = _current["item"]
            if item is not None and item.get_closest_marker("render") is None and not os.environ.get(RENDER_LOG_ENV):
                msg = f"{item.nodeid} reads renders but is not marked @pytest.mark.render"
                if "not render" in (item.config.getoption("markexpr") or ""):
                    pytest.fail(msg, pytrace=False)  # a run that deselects renders must not render
                warnings.warn(msg, pytest.PytestWarning, stacklevel=2)
        elif kind in ("figures", "evaluate"):
            name = key.get("figure", key.get("name", kind)) if isinstance(key, dict) else kind
            _render_log(f"{kind}:{name}")
            _current["figure_depth"].append(f"{kind}:{name}")
            try:
                return real(self, key, build)
            finally:
                _current["figure_depth"].pop()
        return real(self, key, build)

    defocus_cache.Cache.get_or_build = get_or_build
    yield
    defocus_cache.Cache.get_or_build = real


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_setup(item):
    _current["item"] = item
    yield from _timed_phase(item, "setup")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item):
    yield from _timed_phase(item, "teardown")
    _current["item"] = None


@pytest.hookimpl(hookwrapper=True)
def pytest_fixture_setup(fixturedef, request):
    _current["fixtures"].append(fixturedef.argname)
    try:
        yield
    finally:
        _current["fixtures"].pop()


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist reads the marks (it appends "@group" to node ids)
def pytest_collection_modifyitems(config, items):
    """Keep the tests of one module that share a module-scoped fixture on one pytest-xdist worker
    (``--dist loadgroup``): the fixture (a mosaic ablation, a quick figure, a render) is then built once
    instead of once per worker. Other tests are spread one by one."""
    for item in items:
        if item.get_closest_marker("xdist_group") is not None:
            continue
        info = getattr(item, "_fixtureinfo", None)
        if info is None:
            continue
        shared = False
        for name in info.names_closure:
            for fdef in info.name2fixturedefs.get(name, ()):
                if fdef.scope in ("module", "class") and fdef.baseid and fdef.baseid != "tests":
                    shared = True
        if shared:
            item.add_marker(pytest.mark.xdist_group(item.nodeid.split("::")[0]))


# --- CPU seconds per test: --cpu-durations=N (docs/testing.md) ------------------------------------------
def _cpu_seconds() -> float:
    """User + system CPU seconds of this process and of its subprocesses that have finished."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def _timed_phase(item, when):
    t0 = _cpu_seconds()
    yield
    item.user_properties.append((f"cpu_{when}", _cpu_seconds() - t0))  # sent with the report (pytest-xdist too)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item):
    yield from _timed_phase(item, "call")


_cpu_by_test: dict = {}


def pytest_runtest_logreport(report):
    for name, value in getattr(report, "user_properties", ()):
        if name == f"cpu_{report.when}":
            _cpu_by_test.setdefault(report.nodeid, {})[report.when] = float(value)


def pytest_terminal_summary(terminalreporter, config):
    n = config.getoption("--cpu-durations")
    if n is None or not _cpu_by_test:
        return
    tr = terminalreporter
    total = {k: sum(v.values()) for k, v in _cpu_by_test.items()}
    tr.write_sep("=", f"{n} tests with the most CPU seconds (setup + call + teardown, subprocesses included)")
    for nodeid in sorted(total, key=total.get, reverse=True)[:n]:
        phases = _cpu_by_test[nodeid]
        detail = ", ".join(f"{w} {phases[w]:.1f}" for w in ("setup", "call", "teardown") if phases.get(w, 0) >= 0.05)
        tr.write_line(f"{total[nodeid]:8.1f} s  {nodeid}  ({detail})")
    tr.write_line(f"{sum(total.values()):8.1f} s  in all {len(total)} tests")
