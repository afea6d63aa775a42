# legbench: two commands on a fresh machine: `make compare` (the full comparison) and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup test lint compare bench sweep urdf clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

setup: $(STAMP)

test: $(STAMP)
	$(BIN)/pytest -q

lint: $(STAMP)
	$(BIN)/ruff check legbench tests
	$(BIN)/ruff format --check legbench tests
	$(BIN)/mypy legbench

urdf: $(STAMP)
	$(BIN)/legbench model urdf

compare: $(STAMP)
	$(BIN)/legbench model check

clean:
	rm -rf $(VENV) results/latest
