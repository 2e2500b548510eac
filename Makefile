# gevsim: the two commands of the README.
#   make demo   renders the built-in office scene: basis images, a flickering
#               irradiance sequence, a contact sheet and a waveform plot (out/demo),
#               then runs the comparison study (experiments/demo.toml): DVS, gradient and
#               center-surround events in the office and on the sodium-lit street, with
#               flicker/noise counterfactuals and reconstructions; table + report in
#               out/demo_study (report.md)
#   make test   runs the test suite, ruff and mypy included (tests/test_lint.py,
#               tests/test_typing.py), in one pytest-xdist worker per core (at most 4);
#               pytest -m "not slow" leaves out the seconds-long renders
#   make lock   regenerates requirements.lock (exact versions) from pyproject.toml's ranges
# Both bootstrap .venv with the exact versions of requirements.lock (gevsim and its
# extras), and the LLVM runtime that Mitsuba's fast CPU variant needs (apt-get, when
# run as root). Re-running either redoes nothing that is finished.

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.gevsim-installed
DEMO_OUT ?= out/demo

.PHONY: demo test llvm lock clean

$(PY):
	$(PYTHON) -m venv $(VENV)

LOCK   := requirements.lock
EXTRAS := plot,test,dask,denoise,aedat4,learn

$(STAMP): pyproject.toml $(LOCK) | $(PY)
	$(PY) -m pip install -q -c $(LOCK) --upgrade pip
	$(PY) -m pip install -q -c $(LOCK) -e '.[$(EXTRAS)]'
	$(PY) -m pip install -q -r $(LOCK)
	touch $@

lock:
	PYTHON=$(PYTHON) EXTRAS=$(EXTRAS) bash scripts/lock.sh

llvm:
	@bash scripts/ensure-llvm.sh

demo: $(STAMP) llvm
	$(VENV)/bin/gevsim info
	$(VENV)/bin/gevsim render office --out $(DEMO_OUT) --width 96 --height 72 --frames 4000 --plots --cache .gevsim-cache
	$(VENV)/bin/gevsim study experiments/demo.toml --out out/demo_study --cache .gevsim-cache
	$(VENV)/bin/gevsim emulate experiments/office_small.toml --out out/office_small.h5 --cache .gevsim-cache -q
	$(VENV)/bin/gevsim view out/office_small.h5 --out out/office_small.gif --window-ms 1
	$(VENV)/bin/gevsim emulate experiments/street_small.toml --out out/street_small.h5 --cache .gevsim-cache -q
	$(VENV)/bin/gevsim view out/street_small.h5 --out out/street_small.gif --window-ms 2

# One pytest worker per usable core, at most 4 (each holds numba, Mitsuba and torch: ~1 GB), whole modules per
# worker (module fixtures are built once), in collection order (tests/conftest.py puts the longest modules first;
# xdist would otherwise start with the modules of most tests); one core: no workers. TEST_WORKERS=0: in-process.
TEST_WORKERS ?= $(shell $(PYTHON) -c "import os; c = len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') \
                  else os.cpu_count() or 1; n = min(4, c); print(n if n > 1 else 0)")

test: $(STAMP) llvm
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

clean:
	rm -rf out .gevsim-cache .pytest_cache .hypothesis
