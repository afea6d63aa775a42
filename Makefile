# legbench. Two commands on a fresh machine: `make compare` (the full comparison) and `make test`.
# Both create .venv and install everything on first use.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
JOBS ?= 2
TASKS := scenarios/position.yaml scenarios/ellipse.yaml scenarios/effort.yaml scenarios/combined.yaml
# the runs of the four tasks: every backend, matched in both contact modes and engine-defaults in native contact
RUN_TASKS = $(LEGBENCH) run $(TASKS) --backends all --jobs $(JOBS) --quiet --no-compare \
	--variant matched:native --variant matched:reference --variant engine-defaults:native
LEGBENCH := $(BIN)/legbench
VERIFY = $(LEGBENCH) verify --jobs $(JOBS) --force
## after a verify: its exit status 1 (some checks fail: the report lists them) goes on; any other (2: bad input or
## a refused output, 4: an I/O error, 130: interrupted) stops the target
FAILING_CHECKS_ONLY = s=$$?; if [ $$s = 1 ]; then echo 'verify: some checks fail; the report lists them'; \
	elif [ $$s != 0 ]; then exit $$s; fi

.PHONY: setup system-deps test lint runs compare check baseline bench sweep verify urdf clean reproduce

$(STAMP): pyproject.toml
	@$(MAKE) --no-print-directory system-deps
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev,drake,dart,ros,dask]'
	touch $(STAMP)

setup: system-deps $(STAMP)

## system libraries of engines pip cannot install: ODE's libode8 (the ode backend), and Chromium for the
## report's browser test (tests/test_browser.py), with apt where we are root and apt exists (idempotent,
## quiet); elsewhere the ode backend reports itself missing and the browser test skips, each with its command
system-deps:
	@if ldconfig -p 2>/dev/null | grep -q 'libode\.so'; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  apt-get update -qq >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libode8 >/dev/null; \
	else echo "note: the ode backend needs libode8 (as root: apt-get install -y libode8)"; fi
	@if command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  apt-get update -qq >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; \
	else echo "note: the report's browser test needs Chromium (as root: apt-get install -y chromium)"; fi

## the test suite
test: $(STAMP)
	$(BIN)/pytest -q -n 2 --dist loadfile

lint: $(STAMP)
	$(BIN)/ruff check legbench tests
	$(BIN)/ruff format --check legbench tests
	$(BIN)/mypy legbench

## the main job: four tasks x all backends x both contact modes (matched profile) and the engine-defaults profile
## (native contact), verification and contact calibration (both profiles) -> results/latest/report.html
compare: $(STAMP)
	$(RUN_TASKS) --out results/latest --force || [ $$? = 3 ]  # a backend that failed (exit 3): said, the rest goes on
	$(VERIFY) --out results/latest/verification; $(FAILING_CHECKS_ONLY)
	$(VERIFY) --profile engine-defaults --out results/latest/verification__engine-defaults; $(FAILING_CHECKS_ONLY)
	$(LEGBENCH) calibrate-contact --out results/latest/calibration --jobs $(JOBS) --force
	$(LEGBENCH) calibrate-contact --profile engine-defaults --out results/latest/calibration__engine-defaults \
		--jobs $(JOBS) --force
	$(LEGBENCH) compare results/latest --jobs $(JOBS) || [ $$? = 3 ]  # exit 3: the failed backend named again

## the four tasks x all backends x both contact modes (matched) and engine-defaults (native) -> results/latest.
## --force replaces these twelve runs (and the studies above) as legbench does: your own runs in results/latest
## under other names stay, and a file legbench did not write there stops the target with one line naming it
runs: $(STAMP)
	$(RUN_TASKS) --out results/latest --force

## regression check of a fresh run of the four tasks against the committed baseline (CI), in its own tree;
## a backend that fails its run (exit 3) is checked too (FAILED, with check.md and the JUnit file), then make fails
## (results/check: `make compare`'s results/latest, with its verification and calibration, is left as it is).
## The baseline holds the tasks' metrics only; verification and calibration are asserted by the test suite, so
## CI does not run them twice
check: $(STAMP)
	rm -rf results/check
	$(RUN_TASKS) --out results/check; s=$$?; if [ $$s != 0 ] && [ $$s != 3 ]; then exit $$s; fi; \
	$(LEGBENCH) compare results/check --jobs $(JOBS); c=$$?; if [ $$c != 0 ] && [ $$c != 3 ]; then exit $$c; fi; \
	$(LEGBENCH) check results/check --baseline results/baseline && exit $$s

## refresh the committed baseline on purpose (review the diff of results/baseline before committing)
baseline: compare
	rm -rf results/baseline
	mkdir -p results/baseline
	cd results/latest && set -e && for t in $(basename $(notdir $(TASKS))); do \
		for d in $$t $${t}__reference $${t}__engine-defaults; do \
		mkdir -p ../baseline/$$d && cp $$d/metrics.json $$d/run.json ../baseline/$$d; done; done

## the lab report's comparison (its table 10, legbench's steady force and Fn tables, task 4's contact and switch
## torque, simulation error % between its frameworks' analogues, as scenarios/reproduce.yaml maps them)
## -> results/reproduce/reproduce.{md,html,json}
reproduce: $(STAMP)
	$(LEGBENCH) reproduce --out results/reproduce --jobs $(JOBS) --quiet --force

## harness overhead per backend and task -> results/bench/bench.{json,md}
bench: $(STAMP)
	$(LEGBENCH) bench $(TASKS) --out results/bench --force

## the time-step study (convergence order, speed-accuracy) -> results/sweeps/timestep/
sweep: $(STAMP)
	$(LEGBENCH) sweep scenarios/sweeps/timestep.yaml --out results/sweeps/timestep --jobs $(JOBS) --force

## verification cases and contact calibration (both profiles) on their own
verify: $(STAMP)
	$(VERIFY) --out results/latest/verification; $(FAILING_CHECKS_ONLY)
	$(VERIFY) --profile engine-defaults --out results/latest/verification__engine-defaults; $(FAILING_CHECKS_ONLY)
	$(LEGBENCH) calibrate-contact --out results/latest/calibration --jobs $(JOBS) --force
	$(LEGBENCH) calibrate-contact --profile engine-defaults --out results/latest/calibration__engine-defaults \
		--jobs $(JOBS) --force

urdf: $(STAMP)
	$(LEGBENCH) model urdf

clean:
	rm -rf $(VENV) results/latest
