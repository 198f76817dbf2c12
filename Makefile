# downhole: the two set-up commands are `make run` and `make test`; both create .venv themselves.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-$(shell cksum pyproject.toml | cut -d' ' -f1)

.PHONY: run test test-slow bench clean clean-cache chromium

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test]'
	rm -f $(VENV)/.installed-*; touch $(STAMP)

venv: $(STAMP)

run: $(STAMP)
	$(VENV)/bin/downhole demo --out out

# Browser tests (tests/test_dashboard*.py) drive Debian's chromium through Playwright.
chromium:
	@test -x /usr/bin/chromium || (apt-get update && apt-get install -y --no-install-recommends chromium)

# ruff (the config in pyproject.toml) and the layering contracts of .importlinter (docs/architecture.md, "Layering") run before pytest.
# Paced real-time tests (marker `realtime`) run alone after the parallel run: on a core shared
# with another test they miss deadlines; `sync` first, so that the parallel run's writes are not
# flushed to disk during them. A paced test that fails gets one more run (--lf): a deadline missed
# because the machine was busy is not a defect of the loop; one that fails twice fails the target.
# Pacing logic itself is tested deterministically on a virtual clock (tests/test_sil_runtime.py).
test: $(STAMP) chromium
	$(VENV)/bin/ruff check downhole tests benchmarks
	$(VENV)/bin/lint-imports
	$(PY) -m pytest -q -n 2 -m "not slow and not realtime" --durations=15
	sync
	$(PY) -m pytest -q -m "realtime and not slow" || $(PY) -m pytest -q -m "realtime and not slow" --lf

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow

bench: $(STAMP)
	$(VENV)/bin/downhole bench --out out/bench.json

clean:
	rm -rf out .pytest_cache
	find . -name __pycache__ -prune -exec rm -rf {} +

clean-cache:
	find downhole -path '*__pycache__*' \( -name '*.nbi' -o -name '*.nbc' \) -delete
