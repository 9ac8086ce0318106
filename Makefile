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

MAPS := ../shared/maps/maze_a.yaml ../shared/maps/maze_b.yaml ../shared/maps/intel.yaml cave:1:60x60

# The README's team tables: 5 robots, the four maps, every strategy, two seeds, and Greedy and
# MinPos again on the EU 10 % band (about 1 h on 2 cores). The tables go into README.md.
sweep-readme: $(STAMP)
	$(BIN)/lorascout sweep --maps $(MAPS) --robots 5 --seeds 2 --also-radio eu868-g3 --out docs/sweep --resume
	$(BIN)/python -m host_tools.readme_sync docs/sweep/tables.md README.md

# Issue 4's acceptance grid: every strategy, 10 seeds, on the ideal link (hours on 2 cores; the
# cost of the EU band is measured on sweep-readme's two seeds). Its tables go into README.md too.
sweep: $(STAMP)
	$(BIN)/lorascout sweep --maps $(MAPS) --robots 5 --seeds 10 --out out/sweep --resume
	$(BIN)/python -m host_tools.readme_sync --block sweep10-tables out/sweep/tables.md README.md

clean:
	rm -rf $(VENV) build *.egg-info
