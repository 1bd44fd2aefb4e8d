# ACV: `make run` sets everything up and serves the product; `make test` sets up and runs the tests.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup system-deps run test lint bench clean

# Debian packages needed at run time: EGL and OSMesa for off-screen MuJoCo rendering.
APT_PACKAGES := libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6

system-deps:
	@if command -v apt-get >/dev/null && [ "$$(id -u)" = 0 ]; then \
	  missing=""; for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	  if [ -n "$$missing" ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing; fi; \
	fi

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	# torch==2.13.0 resolves to a local CPU wheel here; a bare `torch` would pull a CUDA build.
	$(BIN)/pip install -q torch==2.13.0
	$(BIN)/pip install -q -e '.[dev]'
	touch $(STAMP)

setup: system-deps $(STAMP)

run: setup
	$(BIN)/acv demo

test: setup
	$(BIN)/ruff check app engine tests benchmarks
	$(BIN)/pytest -n 2 -m "not slow" -q

lint: setup
	$(BIN)/ruff check app engine tests benchmarks

clean:
	rm -rf $(VENV) .pytest_cache
