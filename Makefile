# Two entry points for a newcomer: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test test-all clean venv

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,cluster]'
	touch $(STAMP)

venv: $(STAMP)

# Runs the main job on the bundled templates: every design simulated, exported in every format
# that applies, checked as built, with report.md/report.json per design; everything in out/.
# Its last line names the page to open, after any design's error, and keeps export's exit code.
demo: $(STAMP)
	@$(VENV)/bin/fabkit export templates -o out --jobs 2; status=$$?; \
	if [ -f out/index.html ]; then \
		echo "Open out/index.html in a browser: every design's report, files and checks."; \
	fi; exit $$status

# The fast suite (what CI runs); `make test-all` adds the slow studies.
test: $(STAMP)
	$(PY) -m pytest -q -m "not slow"

test-all: $(STAMP)
	$(PY) -m pytest -q

clean:
	rm -rf $(VENV) out/*/ .pytest_cache
