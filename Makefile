# Two entry points for a fresh machine: `make demo` and `make test`.
# Both create (or reuse) a local virtual environment in .venv.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench sweep sweep-readme venv clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test,ray]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(BIN)/lorascout run

test: $(STAMP)
	$(BIN)/python -m pytest

bench: $(STAMP)
	$(BIN)/lorascout bench

# The README's team table (5 robots, maze_a, every strategy, 2 seeds; about 40 min on 1 core).
sweep-readme: $(STAMP)
	$(BIN)/lorascout sweep --maps ../shared/maps/maze_a.yaml --robots 5 --seeds 2 --jobs 1 --out docs/sweep_maze_a

# Issue 4's acceptance grid: 4 maps x 5 strategies x 10 seeds, 5 robots (hours on 2 cores).
sweep: $(STAMP)
	$(BIN)/lorascout sweep --maps ../shared/maps/maze_a.yaml ../shared/maps/maze_b.yaml \
		../shared/maps/intel.yaml cave:1 --robots 5 --seeds 10 --out out/sweep

clean:
	rm -rf $(VENV) build *.egg-info
