# ACV: `make run` sets everything up and serves the product; `make test` sets up and runs the tests.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup system-deps test-deps run test test-fast lint clean

# Debian packages needed at run time: EGL and OSMesa for off-screen MuJoCo rendering.
APT_PACKAGES := libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6
# Debian packages the tests need: PostgreSQL (the app tests start a throwaway server on
# 127.0.0.1 with initdb/pg_ctl, so that every API test also runs on PostgreSQL) and Chromium
# (Playwright drives it; no browser is ever downloaded).
TEST_APT_PACKAGES := postgresql chromium

# $(call apt_install,packages): install the missing ones when we are root on Debian.
define apt_install
	@if command -v apt-get >/dev/null && [ "$$(id -u)" = 0 ]; then \
	  missing=""; for p in $(1); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	  if [ -n "$$missing" ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing; fi; \
	fi
endef

system-deps:
	$(call apt_install,$(APT_PACKAGES))

test-deps:
	$(call apt_install,$(TEST_APT_PACKAGES))

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	# torch==2.13.0 resolves to a local CPU wheel here; a bare `torch` would pull a CUDA build.
	$(BIN)/pip install -q torch==2.13.0
	$(BIN)/pip install -q -e '.[dev]'
	touch $(STAMP)

setup: system-deps $(STAMP)

# Serves the web app on http://127.0.0.1:8000 (migrations applied, a demo study prepared)
# and prints the researcher login URL. Data in ./data (ACV_DATA_DIR).
run: setup
	$(BIN)/acv serve --demo

# --dist loadscope: a module's tests share one worker, so its module fixtures (a database, a
# served app, a trained run) are built once, not once per worker.
test: lint test-deps
	$(BIN)/pytest -n 2 --dist loadscope -m "not slow" -q --durations=15

# The unit tiers only: no browser, PostgreSQL, training, Ray or fresh processes (seconds, for
# the edit-test loop; `make test` runs everything CI runs).
test-fast: setup
	$(BIN)/pytest -n 2 --dist loadscope -q -m "not slow and not browser and not postgres and not training and not ray and not process"

# Style, formatting and types (mypy: strict on engine/, check_untyped_defs on app/; see
# [tool.mypy] in pyproject.toml).
lint: setup
	$(BIN)/ruff check app engine tests benchmarks migrations
	$(BIN)/ruff format --check app engine tests benchmarks migrations
	$(BIN)/mypy engine app

clean:
	rm -rf $(VENV) .pytest_cache
