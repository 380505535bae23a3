# Two user-facing targets: `make demo` and `make test`. Both bootstrap .venv idempotently:
# a second run finds the stamp newer than pyproject.toml and installs nothing. Both also build the
# hand-landmark model file inside .venv from the mediapipe 0.10.21 wheel on the package registry (once: the
# file is its own stamp; `make hand-model` builds only it; docs/camera_pose.md).
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
BASE_STAMP := $(VENV)/.installed-base
DEV_STAMP := $(VENV)/.installed-dev
HAND_MODEL := $(VENV)/share/touchanything/hand_landmarker.task
PYTEST_ARGS ?=

.PHONY: demo test hand-model

demo: $(BASE_STAMP) $(HAND_MODEL)
	$(VENV)/bin/touchanything demo

# The suite in two runs: everything that neither measures time nor holds a machine resource in $(TEST_WORKERS)
# worker processes, then the `serial` tests (those under tests/timing/ and those that use the X display; marked in
# tests/conftest.py) one by one on an otherwise idle machine.
TEST_WORKERS ?= 2

test: $(DEV_STAMP) $(HAND_MODEL) xvfb
	$(VENV)/bin/ruff check .
	$(PY) -m pytest -n $(TEST_WORKERS) -m "not serial" $(PYTEST_ARGS) || [ $$? -eq 5 ]  # 5: PYTEST_ARGS selected none
	$(PY) -m pytest -m serial $(PYTEST_ARGS) || [ $$? -eq 5 ]

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)

$(BASE_STAMP): pyproject.toml | $(VENV)/bin/python
	$(PY) -m pip install --quiet -e .
	touch $@

$(DEV_STAMP): pyproject.toml $(BASE_STAMP)
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $@

hand-model: $(HAND_MODEL)

$(HAND_MODEL): scripts/build_hand_model.py devices/camera_pose/model_file.py | $(BASE_STAMP)
	$(PY) scripts/build_hand_model.py --out $@

# The dashboard tests need an X virtual framebuffer; install it when missing and running as root.
.PHONY: xvfb
xvfb:
	@command -v Xvfb >/dev/null 2>&1 || { \
	  if [ "$$(id -u)" = 0 ]; then \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq xvfb xauth >/dev/null; \
	  else echo "note: Xvfb is not installed (apt-get install xvfb xauth); dashboard tests will be skipped"; fi; }
