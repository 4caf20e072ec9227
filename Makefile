# Two entry points for a new user: `make demo` and `make test`.
# Both create .venv from pyproject.toml when it is missing or older than pyproject.toml.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin

.PHONY: demo test bench fuzz clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test,ble]'
	touch $@

demo: $(VENV)/.installed
	$(BIN)/rescuemesh run follow --out out/follow

test: $(VENV)/.installed
	$(BIN)/python -m pytest -q

bench: $(VENV)/.installed
	$(BIN)/rescuemesh bench --out out/bench.json

fuzz: $(VENV)/.installed
	$(BIN)/python -m rescuemesh.fuzz --frames 1000000

clean:
	rm -rf $(VENV) out .pytest_cache
