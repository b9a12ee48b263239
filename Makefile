# Both `make demo` and `make test` do all the set-up themselves (scripts/bootstrap.sh):
# create .venv, install the package, make sure drjit's LLVM backend renders.
VENV := .venv
BIN := $(VENV)/bin

.PHONY: setup demo test test-fast bench bless lint format clean

setup:
	@bash scripts/bootstrap.sh

demo: setup
	$(BIN)/pacam demo --out demo_out --force

test: setup
	$(BIN)/python -m pytest -q

# Everything that does not ray-trace (tests marked `render` are left out): about 3 min.
test-fast: setup
	$(BIN)/python -m pytest -q -m "not render"

bench: setup
	$(BIN)/python benchmarks/run_all.py

# Re-create the regression images in tests/regression/ (after an intended change to renders).
bless: setup
	$(BIN)/python -m pacam_render.experiments.regression --bless

lint: setup
	$(BIN)/ruff format --check pacam_render tests benchmarks
	$(BIN)/ruff check pacam_render tests benchmarks

format: setup
	$(BIN)/ruff format pacam_render tests benchmarks
	$(BIN)/ruff check --fix pacam_render tests benchmarks

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache .hypothesis *.egg-info
