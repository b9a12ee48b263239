# Both `make demo` and `make test` do all the set-up themselves (scripts/bootstrap.sh):
# create .venv, install the package, make sure drjit's LLVM backend renders.
VENV := .venv
BIN := $(VENV)/bin

.PHONY: setup demo test test-fast docs bench bless lint format clean

setup:
	@bash scripts/bootstrap.sh

demo: setup
	$(BIN)/pacam demo --out demo_out --force

test: setup
	$(BIN)/python -m pytest -q

# Everything that does not ray-trace (tests marked `render` are left out): about 3 min.
test-fast: setup
	$(BIN)/python -m pytest -q -m "not render"

# The documentation site, docs/_build/html: warnings are errors (-W), references are checked
# (-n), every document is read afresh (-E). Then tests/docs/test_docs_site.py checks every
# internal link, an API page for every public name and a CLI page for every command, and looks
# at the landing, an API and a study page in headless Chromium (screenshots in
# docs/_build/screenshots).
docs: setup
	$(BIN)/sphinx-build -W --keep-going -n -E -q -b html docs docs/_build/html
	PACAM_DOCS_HTML=docs/_build/html $(BIN)/python -m pytest -q -p no:cacheprovider tests/docs/test_docs_site.py

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
	rm -rf $(VENV) .pytest_cache .ruff_cache .hypothesis *.egg-info docs/_build docs/reference/api docs/reference/cli docs/jupyter_execute
