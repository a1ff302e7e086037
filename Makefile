# Two commands on a fresh Debian machine: `make run` and `make test`.
# Both create .venv and install what is missing (torch CPU wheel first, then the package).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
OUT    ?= outputs/cover
N      ?= 50
TASKS  ?= 10

.PHONY: run test bench results experiment lint clean system-deps browser-deps

$(STAMP): pyproject.toml examples/bpns_stack/pyproject.toml examples/bpns_drawer/pyproject.toml
	@$(MAKE) --no-print-directory system-deps
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -e ".[dev,viz,lerobot]"  # the extras too: their tests run
	$(PY) -m pip install -q --no-deps -e examples/bpns_stack  # the worked example (docs/NEW_TASK.md)
	$(PY) -m pip install -q --no-deps -e examples/bpns_drawer  # the articulated-part example
	@touch $(STAMP)

# Headless rendering needs OSMesa; python3-venv is needed for the virtual environment.
system-deps:
	@missing=""; \
	ldconfig -p 2>/dev/null | grep -q libOSMesa || missing="$$missing libosmesa6"; \
	$(PYTHON) -c "import ensurepip, venv" 2>/dev/null || missing="$$missing python3-venv"; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing$$missing with apt-get"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing >/dev/null; \
	  else \
	    echo "note: please install$$missing (sudo apt-get install$$missing);"; \
	    echo "      without libosmesa6 everything but video rendering works."; \
	  fi; \
	fi

# The report.html test drives Debian's headless Chromium (tests/inspect/test_report_page.py).
browser-deps:
	@if ! command -v chromium >/dev/null || ! command -v chromedriver >/dev/null; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing chromium chromium-driver with apt-get"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null; \
	  else \
	    echo "note: the report.html test needs chromium (sudo apt-get install chromium chromium-driver)"; \
	  fi; \
	fi

run: $(STAMP)
	$(VENV)/bin/bpns run --env cover --demos $(N) --tasks $(TASKS) --timeout 30 --out $(OUT) --overwrite

# Two pytest workers (CI has 2 cores; each worker holds ~1 GB, so more is yours to ask
# for); a test file stays on one worker, so its module fixtures (a learned run, demos) are
# built once. `make test TEST_WORKERS=0`: one process.
TEST_WORKERS ?= 2
test: $(STAMP) browser-deps
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile

bench: $(STAMP)
	$(PY) scripts/bench_control.py
	$(PY) scripts/bench_planning.py --env cover --demos 100 -n 20

# Each environment's section of docs/RESULTS.md; `make results ENVS=stick_button` for one.
ENVS ?= cover stick_button coffee doors
results: $(STAMP)
	@for e in $(ENVS); do \
	  case $$e in \
	    cover) extra="--learn 100 1000 --ablations --bench";; \
	    doors) extra="--learn 250 1000 --seed 3";; \
	    *) extra="--learn 250 1000";; \
	  esac; \
	  $(PY) scripts/make_results.py --env $$e $$extra || exit 1; \
	done

# A resumable sweep (docs/experiments/README.md); `make experiment PRESET=smoke`.
PRESET  ?= small
WORKERS ?= 2
experiment: $(STAMP)
	$(VENV)/bin/bpns experiment --preset $(PRESET) --workers $(WORKERS)

lint: $(STAMP)
	$(VENV)/bin/ruff check bpns ik mj_envs scripts tests

clean:
	rm -rf $(VENV) outputs .pytest_cache
