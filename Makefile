# Two entry points a fresh machine needs (see README):
#   make figures   - set up .venv, render what is missing, compute every figure and the report
#   make test      - set up .venv and run the test suite (what CI runs)
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
PYTEST_ARGS ?=
# pytest-xdist workers; tests that share a module fixture, a cache folder or a port carry an
# xdist_group mark (tests/conftest.py), which --dist loadgroup keeps on one worker.
PYTEST_WORKERS ?= 2

.PHONY: setup system-deps figures figures-quick report test test-fast bench clean-cache

setup: system-deps $(STAMP)

# Mitsuba's fast CPU variant (llvm_ad_rgb) needs libLLVM >= 16; Debian 12 ships 14/15, which
# abort the process. Install libllvm19 when we are root with apt; otherwise the code falls back
# to scalar_rgb with a warning (see README, "Rendering backend"). chromium (headless) renders
# report/index.html in tests/test_report_browser.py; installed the same way, else that test is skipped.
system-deps:
	@if ls /usr/lib/*/libLLVM*.so.19* /usr/lib/*/libLLVM-19.so* >/dev/null 2>&1; then \
	    true; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "installing libllvm19 for Mitsuba's llvm_ad_rgb variant"; \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19 >/dev/null) \
	      || echo "warning: could not install libllvm19; rendering will fall back to scalar_rgb"; \
	else \
	    echo "note: libLLVM 19 not found and cannot apt-get it; rendering falls back to scalar_rgb (see README)"; \
	fi
	@if command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1; then \
	    true; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "installing chromium for the report's browser test (tests/test_report_browser.py)"; \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium >/dev/null) \
	      || echo "warning: could not install chromium; the report's browser test will be skipped"; \
	else \
	    echo "note: chromium not found and cannot apt-get it; the report's browser test will be skipped (see README)"; \
	fi

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[all,test]'
	$(BIN)/python -m repro.warmup
	touch $(STAMP)

figures: setup
	$(BIN)/python -m repro.figures
	$(BIN)/python -m repro.report

# Exploratory: figures and report under the git-ignored report/quick/ (the committed report is untouched).
figures-quick: setup
	$(BIN)/python -m repro.figures --quick
	$(BIN)/python -m repro.report --figures report/quick/figures

report: setup
	$(BIN)/python -m repro.report

test: setup
	$(BIN)/python -m pytest -n $(PYTEST_WORKERS) --dist loadgroup --durations=15 --cpu-durations=25 $(PYTEST_ARGS)

# Everything that neither renders nor is slow (docs/testing.md): under 90 s with a warm numba cache.
test-fast: setup
	$(BIN)/python -m pytest -n $(PYTEST_WORKERS) --dist loadgroup -m "not slow and not render" --durations=15 $(PYTEST_ARGS)

bench: setup
	$(BIN)/python -m repro.bench

clean-cache:
	rm -rf .cache
