# mimicbench developer tasks. `make test` needs only Python 3.11 and pip on the machine.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV ?= .venv
PY := $(VENV)/bin/python
PYTEST_ARGS ?=

.PHONY: setup lint test test-fast demo docs clean

$(VENV)/.installed: pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -c constraints.txt -e ".[all]"
	touch $@

setup: $(VENV)/.installed  ## create .venv with every extra, versions from constraints.txt

lint: setup  ## ruff (rules in pyproject.toml)
	$(VENV)/bin/ruff check .

test: lint  ## ruff, then the full suite, slow end-to-end tests included (what CI runs)
	$(PY) -m pytest $(PYTEST_ARGS)

test-fast: lint  ## ruff, then the suite without the slow end-to-end tests
	$(PY) -m pytest -m "not slow" $(PYTEST_ARGS)

demo: setup  ## build a small zoo, run every bundled method, print the leaderboard
	$(VENV)/bin/mimicbench demo --out demo-output

docs: setup  ## build the documentation site into site/ (mkdocs-material, strict: a warning fails it)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

clean:
	rm -rf $(VENV) .pytest_cache demo-output site
