# The two commands of the README: `make demo` and `make test`.
# Both create .venv (with the Python found as $(PYTHON)) and install the project into it.
# `make docs` builds the documentation site into site/ (strict: any warning fails it).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DOCS_STAMP := $(VENV)/.installed-docs

.PHONY: venv demo test test-all docs lint format bench clean

$(STAMP): setup.cfg pyproject.toml constraints.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet torch==2.13.0
	$(BIN)/python -m pip install --quiet -c constraints.txt -e ".[test,ray,jax]"
	@# the jax-adapters extra of setup.cfg: gymnax and jaxued without their gymnasium<1.4 bound
	$(BIN)/python -m pip install --quiet -c constraints.txt flax chex seaborn six
	$(BIN)/python -m pip install --quiet --no-deps -c constraints.txt gymnax jaxued
	touch $(STAMP)

$(DOCS_STAMP): $(STAMP) setup.cfg constraints.txt
	$(BIN)/python -m pip install --quiet -c constraints.txt -e ".[docs]"
	touch $(DOCS_STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m experiments.demo

# `make test`: lint, import contracts and the fast tier (unit, differential and a short run of
# each trainer and regime); `make test-all` adds the slow tier (`-m slow`: kill/resume, Ray,
# browser and long end-to-end runs). CI runs both.
test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports
	$(BIN)/python -m pytest -n 2 --dist loadgroup --durations=15 -m "not slow"

test-all: test
	$(BIN)/python -m pytest -n 2 --dist loadgroup --durations=15 -m slow

# NO_MKDOCS_2_WARNING: the theme's notice about MkDocs' future, printed on every build.
docs: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --site-dir site

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports
	$(BIN)/ruff format --check .

format: $(STAMP)
	$(BIN)/ruff format .
	$(BIN)/ruff check --fix .

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_generation.py
	$(BIN)/python benchmarks/bench_metrics.py
	$(BIN)/python benchmarks/bench_engine.py
	$(BIN)/python benchmarks/bench_gym_env.py
	$(BIN)/python benchmarks/bench_evaluation.py
	$(BIN)/python benchmarks/bench_jax_env.py

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .hypothesis demo_output site .jax-cache
