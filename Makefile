# Helpers for a fresh machine. `make demo` runs the pipeline on the demo sources,
# `make test` runs the whole test suite. Both create .venv on first use.
#
# DANCE3D_MEDIA / DANCE3D_MODELS point at the real demo media and models; they default
# to the shared folders next to this checkout and can be set to any other location.

PYTHON ?= python3
VENV := .venv
BIN := $(abspath $(VENV))/bin
DANCE3D_MEDIA ?= $(abspath ../shared/media)
DANCE3D_MODELS ?= $(abspath ../shared/models)
DANCE3D_MOCAP ?= $(abspath ../shared/mocap)
export DANCE3D_MEDIA DANCE3D_MODELS DANCE3D_MOCAP

.PHONY: setup demo demo-media test test-fast browser clean-demo

setup: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	# torch first: the CPU wheel, so the `train` extra does not pull CUDA packages.
	$(BIN)/pip install --quiet torch==2.13.0
	$(BIN)/pip install --quiet -e '.[train,dev,ray]'
	touch $@

demo-media:
	@test -d "$(DANCE3D_MEDIA)/videos" || { echo "demo: no demo media at $(DANCE3D_MEDIA): run 'make demo DANCE3D_MEDIA=/path/to/media' with a videos/ folder holding the files named in manifests/sources.csv"; exit 1; }
	@mkdir -p demo
	@ln -sfn "$(DANCE3D_MEDIA)/videos" demo/media

demo: setup demo-media
	PATH="$(BIN):$$PATH" dvc repro

test: setup
	PATH="$(BIN):$$PATH" pytest

test-fast: setup
	PATH="$(BIN):$$PATH" pytest -m "not slow"

# Debian's Chromium and chromedriver, for the review page's browser test (needs root).
browser:
	apt-get update -qq
	DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver

clean-demo:
	rm -rf data demo/media
