# Two entry points for a fresh machine: `make demo` and `make test`.
# Both create (or reuse) a local virtual environment in .venv.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench sweep venv clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test,ray]'
	touch $(STAMP)

venv: $(STAMP)

# The main job on a built-in default: a team of five on the built-in cave over the EU band.
demo: $(STAMP)
	$(BIN)/lorascout run --map cave:1:60x60 --robots 5 --strategy minpos --radio eu868-g3 --out out/demo

# Two test processes (xdist) for everything but the few tests that time the wall clock, which
# then run alone so that the other process's load cannot make them miss their deadlines.
test: $(STAMP)
	$(BIN)/python -m pytest -n 2 -m "not realtime"
	$(BIN)/python -m pytest -m realtime

bench: $(STAMP)
	$(BIN)/lorascout bench

MAPS := ../shared/maps/maze_a.yaml ../shared/maps/maze_b.yaml ../shared/maps/intel.yaml cave:1:60x60

# Issue 4's acceptance grid and the README's team tables: 5 robots on the four maps, every
# strategy with 10 seeds on the ideal link, and Greedy and MinPos again on the EU 10 % band
# (about 3.2 hours on 2 cores; it resumes, keeping the trials that ran the same code).
# out/sweep keeps every trial with its paths; what the README shows is copied to docs/sweep.
SWEEP_OUT := out/sweep
sweep: $(STAMP)
	$(BIN)/lorascout sweep --maps $(MAPS) --robots 5 --seeds 10 --also-radio eu868-g3 --out $(SWEEP_OUT) --resume
	rm -rf docs/sweep && mkdir -p docs/sweep
	cp $(SWEEP_OUT)/tables.md $(SWEEP_OUT)/tables.json $(SWEEP_OUT)/trials.csv $(SWEEP_OUT)/trials.jsonl \
		$(SWEEP_OUT)/*.png docs/sweep/
	$(BIN)/python -m host_tools.readme_sync docs/sweep/tables.md README.md

clean:
	rm -rf $(VENV) build *.egg-info
