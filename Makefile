# Fabrickator: `make demo` and `make test` do all the set-up on a fresh
# Debian 12 machine (apt packages, then a virtual environment built from
# FreeCAD's interpreter /usr/bin/python3 with the pinned requirements).

SYSPY   := /usr/bin/python3
VENV    := .venv
PY      := $(VENV)/bin/python
APT_PKGS := freecad python3-venv python3-pip xvfb prusa-slicer
SUDO    := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
DEMO_OUT := demo-out

.PHONY: all setup demo test bench clean

all: demo

# apt packages, installed once when any is missing
.apt.stamp:
	@if ! dpkg -s $(APT_PKGS) >/dev/null 2>&1; then \
	  echo "== installing apt packages: $(APT_PKGS)"; \
	  $(SUDO) apt-get update -q && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -q $(APT_PKGS); \
	fi
	@touch $@

$(VENV)/.installed: requirements.txt .apt.stamp
	@echo "== building $(VENV) from $(SYSPY) with requirements.txt"
	@[ -x $(PY) ] || $(SYSPY) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check -r requirements.txt
	@touch $@

setup: $(VENV)/.installed

examples/build/hmd.step: examples/hmd.py $(VENV)/.installed
	$(PY) examples/hmd.py examples/build

demo: examples/build/hmd.step
	$(PY) -m core fabricate examples/build/hmd.step --out $(DEMO_OUT)
	@echo "== demo written to $(DEMO_OUT)/ (report.json, layout.json, layout.png)"

test: $(VENV)/.installed
	$(PY) -m pytest tests/core -q

bench: examples/build/hmd.step
	$(PY) bench/bench.py
	$(PY) bench/bench_printed.py

clean:
	rm -rf $(DEMO_OUT) examples/build bench/out .pytest_cache
