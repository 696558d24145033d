# The two set-up commands (../shared/contract.md): each creates .venv when missing and installs
# what it needs. Nothing else is needed on a fresh machine with Python >= 3.11.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp

.PHONY: run test test-under-load launch-under-load lint bench clean coverage-gate interop test-variants

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

run: $(STAMP)
	$(VENV)/bin/overdrive sim scenarios/demo.yaml

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests bench fuzz

# Safety-critical modules (issue 9): 100 % line and branch coverage, enforced.
SAFETY_MODULES := overdrive.servers.speed_table overdrive.vehicle.modes overdrive.safety.watchdog \
                  overdrive.safety.gate overdrive.safety.monitor
SAFETY_TESTS := tests/test_modes.py tests/safety/test_gate.py tests/safety/test_monitor.py tests/safety/test_watchdog.py \
                tests/servers/test_speed_table.py tests/servers/test_speed_server.py

# Wall-clock and OpenJAUS interop tests (real processes, sockets, fixed ports) run serially
# after the parallel suite; the interop ones build OpenJAUS once into ~/.cache/overdrive
# (tests/interop/conftest.py) and skip, saying why, without ../shared/interop/openjaus.
test: lint
	$(PY) -m pytest -n 2 -p no:cacheprovider -m "not wallclock and not interop"
	$(PY) -m pytest -p no:cacheprovider -m "wallclock or interop" -rs
	@$(MAKE) --no-print-directory coverage-gate

# Issue 16's whole-run variant sweeps in full (`make test` runs one case in four: tests/conftest.py).
test-variants: $(STAMP)
	OVERDRIVE_ALL_VARIANTS=1 $(PY) -m pytest -n 2 -p no:cacheprovider $(addprefix tests/safety/,test_faults_radar.py test_faults_rollback.py test_faults_actuators.py test_faults_hints.py test_faults_sense.py)

interop: $(STAMP)
	$(PY) -m pytest -p no:cacheprovider -m interop -rs

# Issue 20: the whole suite while two busy loops occupy both cores (stopped by PID on any exit).
test-under-load: $(STAMP)
	scripts/test-under-load.sh

# Issue 20: `overdrive launch` of the demo and a 60 s MOVE under two busy loops, each compared with
# its embedded run (exit 0, no violation, final position within 0.5 m).
launch-under-load: $(STAMP)
	$(PY) scripts/launch_under_load.py

coverage-gate: $(STAMP)
	$(PY) -m pytest -p no:cacheprovider $(SAFETY_TESTS) --no-header \
	    $(addprefix --cov=,$(SAFETY_MODULES)) --cov-branch --cov-report=term-missing \
	    --cov-fail-under=100

bench: $(STAMP)
	$(PY) bench/run.py

clean:
	rm -rf $(VENV) runs .pytest_cache
