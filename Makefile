# JointBench. Two commands do all the set-up on a fresh machine (each creates .venv when missing):
#   make reproduce   # every implemented paper study -> results/<study>/
#   make test        # the test suite (what .ci/run calls)
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
RUN    := $(BIN)/jointbench run
SHARED ?= ../shared

.PHONY: help venv test test-slow bench reproduce westwick2012 westwick2012-fig2 westwick2012-fig3 \
        westwick2012-fig4 westwick2012-fig5 westwick2012-fig6 westwick2012-table1 westwick2012-fig7 \
        westwick2012-fig8 xu1998 xu1998-fig2 xu1998-fig3 xu1998-calibration vanderuit2018-table1 \
        example-ankle clean-results

help:
	@echo "make reproduce   run every implemented paper study (results/<study>/report.md)"
	@echo "make test        run the tests (creates .venv when missing)"
	@echo "make test-slow   the long versions of some tests"
	@echo "make bench       speed benchmarks (pytest-benchmark), JSON in results/benchmarks.json"
	@echo "make westwick2012[-fig2|-fig3|-fig4|-fig5|-fig6|-table1|-fig7|-fig8]"
	@echo "make xu1998[-fig2|-fig3|-calibration]"
	@echo "make vanderuit2018-table1"
	@echo "make example-ankle   README worked example on ../shared/data (developers only)"

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

venv: $(STAMP)

test: $(STAMP)
	$(BIN)/python -m pytest -q

# the long versions of some tests (e.g. kbr on 50 s at 2.5 kHz, interval coverage on 30 s records)
test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

bench: $(STAMP)
	mkdir -p results
	$(BIN)/python -m pytest -q tests/benchmarks --benchmark-enable --benchmark-sort=mean --benchmark-columns=median,iqr,min,mean,rounds \
	    --benchmark-json=results/benchmarks.json

reproduce: westwick2012 xu1998 vanderuit2018-table1

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

# The README's worked example on real ankle recordings (needs ../shared beside the checkout).
example-ankle: $(STAMP)
	@test -f $(SHARED)/data/reklab-ankle/ankle_stationary.npz || \
	    { echo "$(SHARED)/data/reklab-ankle not found (developers' checkout only)"; exit 2; }
	$(BIN)/python docs/ankle_example.py $(SHARED)/data/reklab-ankle/ankle_stationary.npz docs

clean-results:
	rm -rf results/*/
