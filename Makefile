# The two commands of the README. Each sets up what it needs (scripts/setup.sh).
.PHONY: setup demo test test-explore test-fast docs benchmark plugins clean

setup:
	@bash scripts/setup.sh

demo: setup
	.venv/bin/python examples/demo.py

# Every test, on every core (pytest-xdist).
test: setup
	.venv/bin/python -m pytest -q -n auto

# Every test, the property-based ones drawing new examples on every run (make test and CI repeat theirs).
test-explore: setup
	HYPOTHESIS_PROFILE=explore .venv/bin/python -m pytest -q -n auto

# The loop while editing: the tests not marked slow (subprocesses, ngspice, Dask clusters; tests/conftest.py).
test-fast: setup
	.venv/bin/python -m pytest -q -n auto -m "not slow"

# The documentation site (docs/_build/html): the README as the guide, page by page (docs/guide), the gallery, the
# notes' notebook executed, the plugin author's guide, the API by public names; any Sphinx warning is an error.
docs: setup
	.venv/bin/python -m pip install -q -e ".[docs]"
	rm -rf docs/_api
	.venv/bin/python -m sphinx -b html -W --keep-going -q docs docs/_build/html
	@echo "docs: docs/_build/html/index.html"

benchmark: setup
	.venv/bin/python -m pip install -q -e ".[bench]"
	.venv/bin/python benchmarks/simulation.py
	.venv/bin/python benchmarks/linear.py
	.venv/bin/python benchmarks/spice.py
	.venv/bin/python benchmarks/derivation.py
	.venv/bin/python benchmarks/integrators.py
	.venv/bin/python benchmarks/rhs.py
	.venv/bin/python benchmarks/simulate.py
	.venv/bin/python benchmarks/spatial.py
	.venv/bin/python benchmarks/routh.py
	.venv/bin/python benchmarks/scenes.py
	.venv/bin/python benchmarks/impacts.py
	.venv/bin/python benchmarks/scale.py
	.venv/bin/python benchmarks/coldstart.py
	.venv/bin/python benchmarks/ac.py
	.venv/bin/python benchmarks/sweep.py
	.venv/bin/python benchmarks/bicycle.py
	.venv/bin/python benchmarks/travel.py

plugins: setup
	.venv/bin/lagrangian plugins

clean:
	rm -rf .venv build *.egg-info core/*.egg-info examples/plugins/*/*.egg-info .pytest_cache docs/_build docs/_api docs/gallery docs/notes.ipynb docs/jupyter_execute
