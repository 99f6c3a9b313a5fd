# Helpers for a fresh machine. `make demo` runs the pipeline on the demo sources,
# `make test` runs the whole test suite. Both create .venv on first use.
#
# DANCE3D_MEDIA / DANCE3D_MODELS point at the real demo media and models; they default
# to the shared folders next to this checkout and can be set to any other location.

PYTHON ?= python3
VENV := .venv
BIN := $(abspath $(VENV))/bin
# Local copies are used where they exist; without them the demo downloads its clips and
# models from their public sources (checksums verified).
ifneq ($(wildcard ../shared/media),)
DANCE3D_MEDIA ?= $(abspath ../shared/media)
endif
ifneq ($(wildcard ../shared/models),)
DANCE3D_MODELS ?= $(abspath ../shared/models)
endif
ifneq ($(wildcard ../shared/mocap),)
DANCE3D_MOCAP ?= $(abspath ../shared/mocap)
endif
ifneq ($(wildcard ../shared/pose2d_eval),)
DANCE3D_POSE2D_EVAL ?= $(abspath ../shared/pose2d_eval)
endif
ifneq ($(wildcard ../shared/hand_eval),)
DANCE3D_HAND_EVAL ?= $(abspath ../shared/hand_eval)
endif
export DANCE3D_MEDIA DANCE3D_MODELS DANCE3D_MOCAP DANCE3D_POSE2D_EVAL DANCE3D_HAND_EVAL

.PHONY: setup lock demo models test test-fast docs browser clean-demo

setup: $(VENV)/.installed

# Exact versions from requirements.lock (what CI tested); pyproject.toml keeps the ranges.
$(VENV)/.installed: pyproject.toml requirements.lock
	$(PYTHON) -m venv $(VENV)
	# torch first: the CPU wheel, so the `train` extra does not pull CUDA packages.
	$(BIN)/pip install --quiet -c requirements.lock pip torch
	$(BIN)/pip install --quiet -c requirements.lock -e '.[train,dev,ray,docs,openvino]'
	touch $@

# Refresh requirements.lock: resolve pyproject.toml's ranges afresh in a throw-away venv
# and freeze what it installed. Run `make test` on the result before committing it.
LOCK_VENV := $(abspath .lock-venv)
lock:
	rm -rf $(LOCK_VENV)
	$(PYTHON) -m venv $(LOCK_VENV)
	$(LOCK_VENV)/bin/pip install --quiet --upgrade pip
	$(LOCK_VENV)/bin/pip install --quiet torch==2.13.0
	$(LOCK_VENV)/bin/pip install --quiet '.[train,dev,ray,docs,openvino]'
	{ echo "# Exact versions CI tests with (pip constraints). Regenerate with 'make lock'."; \
	  echo "# torch is the CPU build: install it before the project (see the Makefile)."; \
	  $(LOCK_VENV)/bin/pip freeze --all --exclude-editable | grep -v '^dance3d' | sed 's/^torch==\([^+]*\)+cpu/torch==\1/'; \
	} > requirements.lock
	rm -rf $(LOCK_VENV) build *.egg-info

# The default detector and pose model: found in DANCE3D_MODELS or models/, else fetched
# from their sources (MoveNet is converted from Google's TFLite in a throw-away venv).
models: setup
	PATH="$(BIN):$$PATH" dance3d models fetch

demo: setup models
	PATH="$(BIN):$$PATH" dvc repro

test: setup
	PATH="$(BIN):$$PATH" pytest

test-fast: setup
	PATH="$(BIN):$$PATH" pytest -m "not slow"

# The documentation site: the reference pages generated from the code, then MkDocs into site/.
docs: setup
	$(BIN)/python -m pipeline.reference docs/reference
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

# Debian's Chromium and chromedriver, for the review page's browser test (needs root).
browser:
	apt-get update -qq
	DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver

clean-demo:
	rm -rf data
