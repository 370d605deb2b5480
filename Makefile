# orthospec: the one entry point.  `make demo` and `make test` set everything up on a fresh machine.
SHELL := /bin/bash
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
PIP := $(VENV)/bin/pip
DEMO_OUT ?= reports/demo
DEMO_DATE ?= 2026-11-21

.PHONY: demo test lint sysdeps venv install install-test examples coverage clean bench

sysdeps:
	@bash scripts/sysdeps.sh

$(VENV)/bin/activate:
	$(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip

venv: $(VENV)/bin/activate

install: sysdeps venv
	$(PIP) install -q -e ".[all]"

install-test: sysdeps venv
	$(PIP) install -q -e ".[test]"

demo: install
	@mkdir -p $(DEMO_OUT)
	$(VENV)/bin/orthospec check examples/deliveries/aerial-pass --profile jrc-v3 \
		--checker examples/checker/aerial-pass \
		--out $(DEMO_OUT) --date $(DEMO_DATE) --format terminal,json,csv,junit,html,pdf
	@echo "demo reports written to $(DEMO_OUT)/"

test: install-test
	$(PY) -m pytest -q -n 2 --dist loadfile

lint: install-test
	$(VENV)/bin/ruff check src tests benchmarks examples scripts
	MYPY=$(VENV)/bin/mypy bash scripts/typecheck.sh

examples: install
	$(PY) examples/generate.py

coverage: install
	$(PY) scripts/coverage_doc.py

bench: install-test
	$(PY) benchmarks/evaluator.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache reports/demo dist build
