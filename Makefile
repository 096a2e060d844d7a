# JointBench. Two commands do all the set-up on a fresh machine (each creates .venv when missing):
#   make reproduce   # every implemented paper study -> results/<study>/
#   make test        # the test suite (what .ci/run calls)
# Any study target takes BACKEND=mujoco (or another simulation backend): every part then runs on it and
# writes results/<study>/backend-<name>/, e.g. `make xu1998 BACKEND=mujoco`.
PYTHON  ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed-stamp
BACKEND ?=
RUN_ARGS ?=
RUN     := $(BIN)/jointbench run $(if $(BACKEND),--backend $(BACKEND)) $(RUN_ARGS)
SHARED  ?= ../shared
PAPER_STUDIES := westwick2012 xu1998 vanderuit2018_table1

.PHONY: help venv test lint reproduce-where test-slow bench bench-save bench-studies reproduce westwick2012 westwick2012-fig2 westwick2012-fig3 \
        westwick2012-fig4 westwick2012-fig5 westwick2012-fig6 westwick2012-table1 westwick2012-fig7 \
        westwick2012-fig8 xu1998 xu1998-fig2 xu1998-fig3 xu1998-calibration vanderuit2018-table1 \
        vanderuit2018-table2 apparatus matrix reproduce-mujoco example-ankle clean-results nightly chromium \
        reflex lpv example-reflex parity-reklab conformance

help:
	@echo "make reproduce   run every implemented paper study (results/<study>/report.md)"
	@echo "make test        run the tests (creates .venv when missing; installs every extra: .[all,test]) on two"
	@echo "                 processes (pytest-xdist; TEST_WORKERS=0 for one process, TEST_WORKERS=N for N)"
	@echo "make lint        ruff on the code (what .ci/run calls after the tests)"
	@echo "make test-slow   exact-value tests of the full studies (slow marker)"
	@echo "make conformance the conformance kit's full version on every estimator (jointbench.testing: more seeds,"
	@echo "                 the whole settings grid; the quick version is part of make test)"
	@echo "make bench       speed benchmarks against the last stored run (fails on a ratio to the same-run"
	@echo "                 baseline grown more than 2x, again on a re-run; medians reported, not judged;"
	@echo "                 stores a passing run) + study wall times (.benchmarks/study_times.csv)"
	@echo "make bench-save  store a benchmark run as the reference without comparing"
	@echo "make bench-studies   only the study wall times (no cache, results/ untouched)"
	@echo "make westwick2012[-fig2|-fig3|-fig4|-fig5|-fig6|-table1|-fig7|-fig8]"
	@echo "make xu1998[-fig2|-fig3|-calibration]"
	@echo "make vanderuit2018-table1"
	@echo "make vanderuit2018-table2   Table II (single trial vs ensembles) on simulated subjects"
	@echo "make apparatus   servo stiffness and gravity on the MuJoCo backend (results/apparatus/)"
	@echo "make matrix      every estimator on every scenario of the three papers, paper and tuned settings (results/matrix/;"
	@echo "                 a comparison grid: full table, ranks, paired comparisons, figures, matrix_comparison.html)"
	@echo "RUN_ARGS=...     more options for jointbench run, e.g. RUN_ARGS='--set table1.seeds=3 --executor dask'"
	@echo "make reproduce-mujoco   every paper study on MuJoCo too (results/<study>/backend-mujoco/), then"
	@echo "                 the analytic reports again, with the MuJoCo value beside every check"
	@echo "BACKEND=mujoco   (on any study target) simulate every part on MuJoCo"
	@echo "make nightly     every paper study against the published values and the previous nightly:"
	@echo "                 results/nightly/index.html; exit 1 on a regression (NIGHTLY_ARGS=... for options)"
	@echo "make example-ankle   README worked example on ../shared/data (developers only)"
	@echo "make catalogue   the catalogue of bad inputs (tools/catalogue/, not part of make test): every case as a"
	@echo "                 process with a timeout, classified; .catalogue/summary.md (CATALOGUE_ARGS='--kind grid')"
	@echo "make reflex      every stiffness estimator against an unmodelled stretch reflex, and the parallel"
	@echo "                 cascade's separation of it (results/reflex/; a comparison study)"
	@echo "make lpv         K(theta) from one trial with a slow movement: pv_irf against FSEWLS mapped"
	@echo "                 through theta (results/lpv/; a comparison study)"
	@echo "make example-reflex  the parallel cascade on the REKLAB ankle recordings (docs/reflex_example.md; developers only)"
	@echo "make parity-reklab   parity with REKLAB's PC_stiffnessID on those recordings (docs/reklab_parity.md; developers only)"

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[all,test]'
	@touch $(STAMP)

venv: $(STAMP)

# The tests on TEST_WORKERS processes (pytest-xdist; each test module stays on one worker, so its shared
# fixtures are made once: tests/conftest.py); TEST_WORKERS=0 runs them in this process, one after another.
# Bytecode is cached (__pycache__, ignored by git) even where PYTHONDONTWRITEBYTECODE is set: without it each
# worker rewrites the asserts of every test module again (pytest: 5.5 CPU-s of a 7.8 s collection, 2.3 s
# with the cache) and each of the tests' CLI subprocesses compiles the package's sources again.
# Headless Chromium (the browser tests: `make chromium`) is installed first, on a machine without it, so that
# its apt-get is not inside the tests' time; failing soft: the tests then skip and say why (their fixture asks
# `make chromium` again for the reason). JOINTBENCH_NO_BROWSER=1 skips both.
TEST_WORKERS ?= 2
test: $(STAMP)
	@[ -n "$$JOINTBENCH_NO_BROWSER" ] || .ci/install-chromium >/dev/null 2>&1 || \
	    echo "make test: no headless Chromium could be installed (the browser tests will skip and say why)"
	PYTHONDONTWRITEBYTECODE= $(BIN)/python -m pytest -q $(if $(filter 0,$(TEST_WORKERS)),,-n $(TEST_WORKERS) --dist loadgroup)

# Lint (ruff, installed with the test extra; the rules are pyproject.toml's [tool.ruff]): .ci/run calls it.
lint: $(STAMP)
	$(BIN)/ruff check .

# Long tests (pytest marker `slow`, not part of `make test`): exact values of the full studies, kbr on 50 s
# at 2.5 kHz, interval coverage on 30 s records.
test-slow: $(STAMP)
	$(BIN)/python -m pytest -q --slow -m slow

# The conformance kit's full version (jointbench.testing.check_estimator(quick=False)) on every registered estimator:
# 20 seeds of interval coverage, 30 seeds of the narrow-band record at every lag/window setting of its grid.
conformance: $(STAMP)
	$(BIN)/python -m pytest -q --slow -m slow tests/test_conformance.py

# Benchmarks: pytest-benchmark runs stored in .benchmarks/<machine>/ (not committed); see tests/benchmarks/bench.py.
bench: $(STAMP)
	$(BIN)/python -m tests.benchmarks.bench
bench-save: $(STAMP)
	$(BIN)/python -m tests.benchmarks.bench --save-only
bench-studies: $(STAMP)
	$(BIN)/python -m tests.benchmarks.bench --studies-only

# The studies, side by side (each one's last cases, figures and report overlap the others' computing, so
# both cores stay busy; quiet: four progress bars would garble each other), then the README's status
# tables from their checks.csv files (never typed by hand; --write-readme: by the same command, which
# has pandas loaded already). The four studies are the parallelism: one
# command runs them (--jobs 4), each in a forked process (each prints its summary whole when it is done). With fewer than
# 8 cores each study runs its cases in its own process (--serial: four processes on 2 cores, where four
# pools of workers on top of them made 12 processes and cost 15 % more CPU on the same numbers, issue 22);
# with 8 or more cores each study gets a pool of cores/4 workers. A RUN_ARGS that says where cases run
# (--serial, --workers, --executor) is used as given.
REPRODUCE_STUDIES := westwick2012 xu1998 vanderuit2018_table1 vanderuit2018_table2
REPRODUCE_CORES   := $(shell nproc 2>/dev/null || echo 2)
REPRODUCE_WHERE   := $(if $(findstring --serial,$(RUN_ARGS))$(findstring --workers,$(RUN_ARGS))$(findstring \
                       --executor,$(RUN_ARGS)),,$(shell n=$(REPRODUCE_CORES); \
                       if [ "$$n" -ge 8 ] 2>/dev/null; then echo "--workers $$((n / 4))"; else echo --serial; fi))
reproduce: $(STAMP)
	@echo "running $(REPRODUCE_STUDIES) side by side ($(or $(REPRODUCE_WHERE),$(RUN_ARGS))); each prints its summary when it is done"
	@$(RUN) --quiet --jobs 4 $(REPRODUCE_WHERE) --write-readme $(REPRODUCE_STUDIES)

# Where make reproduce runs each study's cases on this machine (make bench times the studies the same way).
reproduce-where:
	@echo $(REPRODUCE_WHERE)

westwick2012: $(STAMP)
	$(RUN) westwick2012
westwick2012-fig2: $(STAMP)
	$(RUN) westwick2012 --parts fig2
westwick2012-fig3: $(STAMP)
	$(RUN) westwick2012 --parts fig3
westwick2012-fig4: $(STAMP)
	$(RUN) westwick2012 --parts fig4
westwick2012-fig5: $(STAMP)
	$(RUN) westwick2012 --parts fig5
westwick2012-fig6: $(STAMP)
	$(RUN) westwick2012 --parts fig6
westwick2012-table1 westwick2012-fig7: $(STAMP)
	$(RUN) westwick2012 --parts table1
westwick2012-fig8: $(STAMP)
	$(RUN) westwick2012 --parts fig8

xu1998: $(STAMP)
	$(RUN) xu1998
xu1998-fig2: $(STAMP)
	$(RUN) xu1998 --parts fig2 traces readings
xu1998-fig3: $(STAMP)
	$(RUN) xu1998 --parts fig3 fig3_angle_noise
xu1998-calibration: $(STAMP)
	$(RUN) xu1998 --parts calibration

vanderuit2018-table1: $(STAMP)
	$(RUN) vanderuit2018_table1

vanderuit2018-table2: $(STAMP)
	$(RUN) vanderuit2018_table2

# The comparison matrix (benchmarks/studies/matrix/study.yaml): every estimator on every scenario of the three papers.
matrix: $(STAMP)
	$(RUN) matrix

# Apparatus effects only a physics backend simulates (its parts say backend: mujoco).
apparatus: $(STAMP)
	$(RUN) apparatus

# Every paper study on MuJoCo, then the analytic run (served from its cache when it is current) and the
# MuJoCo reports once more (all cached): each report then shows the other backend's value beside every
# check ("Checks by backend").
reproduce-mujoco: $(STAMP)
	@for s in $(PAPER_STUDIES); do $(BIN)/jointbench run $$s --backend mujoco || exit 1; done
	@for s in $(PAPER_STUDIES); do $(BIN)/jointbench run $$s || exit 1; done
	@for s in $(PAPER_STUDIES); do $(BIN)/jointbench run $$s --backend mujoco --quiet > /dev/null || exit 1; done

# Nightly regression report (jointbench nightly --help); configs/nightly.yaml says what counts as a change.
NIGHTLY_ARGS ?=
nightly: $(STAMP)
	$(BIN)/jointbench nightly $(NIGHTLY_ARGS)

# Headless Chromium from Debian's packages, for the test that opens the nightly report (tests/test_nightly.py).
chromium:
	@.ci/install-chromium

# The README's worked example on real ankle recordings (needs ../shared beside the checkout).
example-ankle: $(STAMP)
	@test -f $(SHARED)/data/reklab-ankle/ankle_stationary.npz || \
	    { echo "$(SHARED)/data/reklab-ankle not found (developers' checkout only)"; exit 2; }
	$(BIN)/python docs/ankle_example.py $(SHARED)/data/reklab-ankle/ankle_stationary.npz docs

clean-results:
	rm -rf results/*/

# The catalogue of bad inputs (issue 20), kept apart from the tests so that it stays an independent measure:
# careless, hostile and unlucky uses by kind (grids, --set, profiles, history, disks, executors, ...), each
# run as a subprocess with a timeout and classified clean / unclear / traceback / hang / silent wrong /
# outputs lost; writes .catalogue/summary.md and cases.csv. Some kinds need unshare -m (full and read-only
# disks) or Dask. CATALOGUE_ARGS='--kind grid --jobs 1', or '--python OTHER/bin/python' to measure another install.
CATALOGUE_ARGS ?=
.PHONY: catalogue realdata
catalogue: $(STAMP)
	$(BIN)/python -m tools.catalogue --out .catalogue $(CATALOGUE_ARGS)
# Reflexes and position-dependent stiffness (issue 21): comparison studies (no published values).
reflex: $(STAMP)
	$(RUN) reflex
lpv: $(STAMP)
	$(RUN) lpv
# The real-data track (issue 37): every estimator on REKLAB's five ankle recordings, cross-validated output VAF.
# Its data: `jointbench data fetch reklab` (pinned commit, SHA-256), or the checkout's ../shared copy here.
REALDATA_DATA ?= $(wildcard ../shared/data/reklab-ankle/ankle_stationary.npz)
realdata: $(STAMP)
	$(RUN) realdata $(if $(REALDATA_DATA),--out results --set trials.params.data=$(abspath $(REALDATA_DATA)))

# Parity with REKLAB's PC_stiffnessID on the real ankle recordings (needs ../shared beside the checkout; the
# reference numbers: tools/reklab/, made by python -m tools.reklab.reference with GNU Octave).
parity-reklab: $(STAMP)
	@test -f $(SHARED)/data/reklab-ankle/ankle_stationary.npz || \
	    { echo "$(SHARED)/data/reklab-ankle not found (developers' checkout only)"; exit 2; }
	$(BIN)/python docs/reklab_parity.py $(SHARED)/data/reklab-ankle/ankle_stationary.npz docs

# The parallel cascade on the real ankle recordings (needs ../shared beside the checkout).
example-reflex: $(STAMP)
	@test -f $(SHARED)/data/reklab-ankle/ankle_stationary.npz || \
	    { echo "$(SHARED)/data/reklab-ankle not found (developers' checkout only)"; exit 2; }
	$(BIN)/python docs/reflex_example.py $(SHARED)/data/reklab-ankle/ankle_stationary.npz docs
