# Two entry points for a newcomer: `make demo` and `make test`; `make docs` builds the reference.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
DOCS_STAMP := $(VENV)/.docs-installed

.PHONY: demo test test-all docs clean venv

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,cluster]'
	touch $(STAMP)

venv: $(STAMP)

# Runs the main job on the bundled templates: every design simulated, exported in every format
# that applies, checked as built, with report.md/report.json per design; everything in out/.
# A progress line per stage and per finished design goes to stderr, terminal or not (a CI log);
# then how long it took, and last the page to open, after any design's error; export's exit
# code is kept.
demo: $(STAMP)
	@start=$$(date +%s); \
	$(VENV)/bin/fabkit export templates -o out --jobs 2 --progress; status=$$?; \
	took=$$(( $$(date +%s) - start )); \
	echo "The demo took $$(( took / 60 )) min $$(( took % 60 )) s."; \
	if [ -f out/index.html ]; then \
		echo "Open out/index.html in a browser: every design's report, files and checks."; \
	fi; exit $$status

# The fast suite (what CI runs), on every core up to four (pytest-xdist; a test file stays on one
# worker, so its module fixtures are made once), the 25 slowest tests listed at the end;
# `make test-all` adds the slow studies.
TEST_WORKERS := -n auto --maxprocesses 4 --dist loadfile --durations=25
# One BLAS and OpenMP thread per process while testing, unless the shell sets its own: the test
# workers already take every core, the commands the tests start would each take them all again,
# and two threads on a design's small matrices cost 4 to 9 times the CPU of one (the AND gate's
# tolerance builds: 4.8 s with one thread, 18-44 s with two). tests/conftest.py limits the
# workers themselves; this reaches the processes they start.
test test-all: export OMP_NUM_THREADS ?= 1

test: $(STAMP)
	$(PY) -m pytest -q -m "not slow" $(TEST_WORKERS)

test-all: $(STAMP)
	$(PY) -m pytest -q $(TEST_WORKERS)

# The guide (docs/*.md) and the API reference (every public module, from the docstrings) as
# HTML in out/docs/ (open out/docs/index.html); built afresh, any warning fails it, and so does
# a public function or class, or a name of fabkit.__all__, that the reference leaves out.
$(DOCS_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e '.[docs]'
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	rm -rf docs/api/_autosummary
	$(PY) -m sphinx -E -W --keep-going -q -b html docs out/docs
	@echo "Open out/docs/index.html in a browser: the guide and the API reference."

clean:
	rm -rf $(VENV) out/*/ .pytest_cache docs/api/_autosummary
