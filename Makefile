# The two set-up commands (../shared/contract.md): each creates .venv when missing and installs
# what it needs. Nothing else is needed on a fresh machine with Python >= 3.11.
#
# Every install is the lock: requirements.lock pins every direct and transitive dependency (pip
# and the build backend included) with its hashes, for every Python >= 3.11 (one universal lock,
# environment markers where versions differ). The project itself goes in last without
# dependencies, so nothing unpinned is ever resolved. `make lock` re-locks after pyproject.toml
# changes keeping every pin it can; `make lock-upgrade` moves every pin on purpose and runs the
# suite on the result. Both need the network; the rest works offline from `make wheels`.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp
LOCK := requirements.lock
LOCK_TOOL := uv==0.13.9
LOCK_VENV := .venv-lock
WHEELS ?= wheels

.PHONY: run test test-under-load launch-under-load lint bench clean coverage-gate interop test-variants \
        check-env lock lock-upgrade wheels install-offline test-offline

# pip first, on its own (the lock's pip, hash-checked), so the pip that installs the rest is the
# locked one rather than one replacing itself half-way through an install.
PIP_PIN = awk '/^pip==/{p=1;print;next} p&&/^ /{print;next} {p=0}' $(LOCK) > $(VENV)/pip.lock

$(STAMP): pyproject.toml $(LOCK)
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@$(PIP_PIN)
	$(PY) -m pip install --quiet --require-hashes -r $(VENV)/pip.lock
	$(PY) -m pip install --quiet --require-hashes -r $(LOCK)
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	@touch $(STAMP)

# Stops `make test` and `make run` early, naming each package whose version is not the lock's.
check-env: $(STAMP)
	@$(PY) scripts/check_env.py $(LOCK)

LOCK_TOOL_STAMP := $(LOCK_VENV)/.$(LOCK_TOOL)

$(LOCK_TOOL_STAMP):
	@test -x $(LOCK_VENV)/bin/python || $(PYTHON) -m venv $(LOCK_VENV)
	$(LOCK_VENV)/bin/python -m pip install --quiet '$(LOCK_TOOL)'
	@touch '$(LOCK_TOOL_STAMP)'

LOCK_COMPILE = printf 'setuptools>=77\npip>=23.2\n' | $(LOCK_VENV)/bin/uv pip compile --quiet \
	pyproject.toml - --extra test --universal --python-version 3.11 --generate-hashes \
	--custom-compile-command "make lock" -o $(LOCK)

lock: $(LOCK_TOOL_STAMP)
	$(LOCK_COMPILE)

lock-upgrade: $(LOCK_TOOL_STAMP)
	$(LOCK_COMPILE) --upgrade
	@git --no-pager diff --stat -- $(LOCK) || true
	$(MAKE) test

# Offline vehicle computers: `make wheels` on a connected machine of the vehicle's platform and
# Python version (pip evaluates the lock's markers for the Python that runs it) fills wheels/ with
# every file the lock pins, hash-checked; copy the checkout with wheels/ to the vehicle and run
# `make install-offline` there: no package index is ever asked (--no-index; PIP_CONFIG_FILE=/dev/null
# and --isolated: no pip configuration file and no PIP_* variable is read).
wheels: $(STAMP)
	$(PY) -m pip download --quiet --require-hashes --no-deps --only-binary=:all: -r $(LOCK) -d $(WHEELS)

install-offline:
	@test -d $(WHEELS) || { echo "install-offline: no $(WHEELS)/ folder: run 'make wheels' on a connected machine and copy it here" >&2; exit 2; }
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@$(PIP_PIN)
	PIP_CONFIG_FILE=/dev/null $(PY) -m pip --isolated install --quiet --no-index --find-links $(WHEELS) --require-hashes -r $(VENV)/pip.lock
	PIP_CONFIG_FILE=/dev/null $(PY) -m pip --isolated install --quiet --no-index --find-links $(WHEELS) --require-hashes -r $(LOCK)
	PIP_CONFIG_FILE=/dev/null $(PY) -m pip --isolated install --quiet --no-index --no-deps --no-build-isolation -e .
	@touch $(STAMP)
	@$(PY) scripts/check_env.py $(LOCK)

# Both steps in a fresh clone of HEAD, the install with no network (scripts/offline-install-check.sh).
test-offline:
	scripts/offline-install-check.sh

run: check-env
	$(VENV)/bin/overdrive sim scenarios/demo.yaml

lint: check-env
	$(VENV)/bin/ruff check src tests bench fuzz scripts

# Safety-critical modules (issue 9): 100 % line and branch coverage, enforced: every module of
# overdrive.safety (command gate, watchdog, motion-sensing plausibility, actuator monitoring), the
# direction hold (no rollback against the gear), the speed table, the vehicle modes and the run
# judge; measured with the tests below only (each module's own unit tests among them). One worker:
# with -n 2 it took 64 s against 43 s serially (back to back on a loaded host, 2026-11-26).
SAFETY_FILES := $(filter-out %/__init__.py,$(wildcard src/overdrive/safety/*.py))
SAFETY_MODULES := $(subst /,.,$(patsubst src/%.py,%,$(SAFETY_FILES))) \
                  overdrive.servers.speed_table overdrive.servers.direction_hold \
                  overdrive.vehicle.modes overdrive.observe.judge overdrive.observe.secondary_audit
SAFETY_TESTS := tests/test_modes.py tests/safety/test_gate.py tests/safety/test_monitor.py tests/safety/test_watchdog.py \
                tests/safety/test_plausibility_cross_checks.py \
                tests/safety/test_plausibility.py tests/safety/test_actuators.py \
                tests/servers/test_speed_table.py tests/servers/test_speed_server.py \
                tests/servers/test_direction_hold.py tests/safety/test_secondary_audit.py \
                tests/safety/test_rollover_limit.py::test_the_judge_flags_lateral_force_beyond_the_static_limit \
                tests/safety/test_unasked_stops.py::test_the_judge_flags_motion_after_a_watchdog_stop_without_a_new_command \
                tests/safety/test_unasked_stops.py::test_the_judge_holds_the_vehicle_after_an_emergency_stop_nobody_asked_for \
                tests/safety/test_unasked_stops.py::test_the_judge_holds_a_set_speed_client_to_a_stop_it_did_not_ask_for \
                tests/safety/test_unasked_stops.py::test_the_judge_counts_a_speed_server_restart_or_a_rise_of_its_unasked_stops \
                tests/safety/test_unasked_stops.py::test_a_notice_with_a_hostile_code_never_crashes_the_judge_nor_stops_it

# Wall-clock tests (real processes, sockets, fixed ports; the OpenJAUS runs among them carry
# both `interop` and `wallclock`) run serially after the parallel suite. The OpenJAUS codec
# comparison (pipes to ojcodec, no clock, no port) is `interop` only and runs in the parallel
# phase, which also builds OpenJAUS once into ~/.cache/overdrive on a cold cache
# (tests/interop/conftest.py); interop tests skip, saying why, without ../shared/interop/openjaus.
# Serially on purpose: on a host loaded by others (load 12 on 2 cores, 2026-11-26) two workers
# here, with launches and xgv-sim runs kept one at a time, failed real-time runs beside a launch
# (an OpenJAUS drive saw a software pause; a 5 %-loss MOVE faulted; a flood RTT of 55 ms over
# its 50 ms bound) and saved nothing once every real-time run shared one lane. (Lanes need a
# scheduler of their own: xdist 3.8's --dist loadgroup groups nothing under pytest 9.2, whose
# node ids no longer read the item._nodeid it sets.)
test: check-env lint
	$(PY) -m pytest -n 2 -p no:cacheprovider -m "not wallclock"
	$(PY) -m pytest -p no:cacheprovider -m wallclock -rs
	@$(MAKE) --no-print-directory coverage-gate

# The whole-run variant sweeps (tests marked `variants`) in full (`make test` runs one case in four
# and every case marked `variant_edge`: tests/conftest.py).
test-variants: $(STAMP)
	OVERDRIVE_ALL_VARIANTS=1 $(PY) -m pytest -n 2 -p no:cacheprovider -m variants

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
	rm -rf $(VENV) $(LOCK_VENV) runs .pytest_cache
