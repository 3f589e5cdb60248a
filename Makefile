# Fabrickator: `make demo` and `make test` do all the set-up on a fresh
# Debian 12 machine (apt packages, then a virtual environment built from
# FreeCAD's interpreter /usr/bin/python3 with the pinned requirements).

SYSPY   := /usr/bin/python3
VENV    := .venv
PY      := $(VENV)/bin/python
APT_PKGS := freecad python3-venv python3-pip xvfb prusa-slicer chromium chromium-driver leocad
# Blender only to test the Blender add-on headless (tools/blender/), without its recommends
APT_LEAN := blender
SUDO    := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
DEMO_OUT := demo-out
# the demo's high-res regions: the two lens mounts of examples/hmd.py (model mm)
DEMO_HIGH_RES := --high-res=-54,25,25.5,-9,36,70.5 --high-res=9,25,25.5,54,36,70.5

.PHONY: all setup demo test bench bench-check clean

all: demo

# apt packages, installed once when any is missing
.apt.stamp:
	@if ! dpkg -s $(APT_PKGS) $(APT_LEAN) >/dev/null 2>&1; then \
	  echo "== installing apt packages: $(APT_PKGS) $(APT_LEAN)"; \
	  $(SUDO) apt-get update -q && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -q $(APT_PKGS) && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -q --no-install-recommends $(APT_LEAN); \
	fi
	@touch $@

# built afresh whenever requirements.txt changes: upgrading cadquery/OCP in place leaves
# a broken VTK behind (cadquery 2.5 -> 2.6 did)
$(VENV)/.installed: requirements.txt requirements-dev.txt .apt.stamp
	@echo "== building $(VENV) from $(SYSPY) with requirements-dev.txt (requirements.txt and the test tools)"
	rm -rf $(VENV)
	$(SYSPY) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check -r requirements-dev.txt
	@touch $@

setup: $(VENV)/.installed

examples/build/hmd.step: examples/hmd.py $(VENV)/.installed
	$(PY) examples/hmd.py examples/build

demo: examples/build/hmd.step
	$(PY) -m core fabricate examples/build/hmd.step $(DEMO_HIGH_RES) --out $(DEMO_OUT)
	@echo "== demo written to $(DEMO_OUT)/: report.json, layout.json, layout.png, parts/ (P1, P2: the printed lens mounts, STL + STEP, plate-1.3mf), instructions.html, assembly.mpd, bom.csv, bricklink.xml"

# the core's pytest suite, then the workbench in freecadcmd and in the FreeCAD GUI (xvfb),
# on this machine's FreeCAD (0.20 on Debian 12), then on FreeCAD 1.x (Python 3.13) the quick
# core tests and both workbench suites, which run the pipeline end to end there.
# The FreeCAD 1.x root (mostly downloads and unpacking) is built meanwhile, in the
# background, where no password can be asked (as root, or with sudo that needs none).
test: $(VENV)/.installed
	@if [ "$$(id -u)" = 0 ] || sudo -n true 2>/dev/null; then \
	  echo "== building the FreeCAD 1.x root in the background, log: $(FREECAD1_LOG)"; \
	  $(MAKE) --no-print-directory freecad1-root >$(FREECAD1_LOG) 2>&1 & root=$$!; \
	else root=; fi; \
	$(MAKE) --no-print-directory test-core && $(MAKE) --no-print-directory test-workbench; s=$$?; \
	if [ -n "$$root" ]; then wait $$root || { s=1; echo "== the FreeCAD 1.x root failed:"; }; \
	  cat $(FREECAD1_LOG); fi; \
	[ $$s = 0 ] && $(MAKE) --no-print-directory test-freecad1

# the test files are shared between the cores (a file's tests stay together: they share
# their module fixtures)
test-core: $(VENV)/.installed
	$(PY) -m pytest tests/core -q -n auto --dist loadfile --durations=15

# the inner loop: the core tests that need neither FreeCAD, PrusaSlicer, the shared models
# nor a whole pipeline run (those are marked slow), spread over the cores test by test
test-quick: $(VENV)/.installed
	$(PY) -m pytest tests/core -q -n auto -m "not slow" --durations=10

# --- FreeCAD 1.x: a Debian 13 (trixie) root made with debootstrap, beside the host's apt
# sources (which stay Debian 12); built once into FREECAD1_ROOT, the suites run on a copy
# of this tree with a Python 3.13 venv of the root's own
FREECAD1_ROOT ?= /var/tmp/fabrickator-trixie
FREECAD1_LOG  := $(FREECAD1_ROOT).build.log
FREECAD1_MAKE := make --no-print-directory -o .apt.stamp VENV=/root/venv

.PHONY: test-core test-quick test-freecad1 freecad1-root

freecad1-root:
	$(SUDO) sh tools/freecad1/root.sh $(FREECAD1_ROOT)

# the root's packages are root.sh's; the copy's .apt.stamp (dated 1970: older than the venv) says
# so to test-workbench's sub-makes too (-o does not reach them): none of them runs apt
test-freecad1: freecad1-root
	$(SUDO) sh tools/freecad1/run.sh $(FREECAD1_ROOT) sh -c 'touch -d @0 .apt.stamp; s=0; \
	  $(FREECAD1_MAKE) test-quick || s=1; $(FREECAD1_MAKE) test-workbench || s=1; exit $$s'

# the quick benchmark rows against their targets (bench/targets.py), about 3 minutes;
# prints each row over its target with the stage that grew
bench-check: examples/build/hmd.step
	$(PY) bench/check.py

# every benchmark script in turn (bench/run_all.py lists them), each printing its tables
# as it goes, then docs/benchmarks.md written from them
bench: examples/build/hmd.step
	$(PY) bench/run_all.py --freecadcmd "$(FREECADCMD)"

clean:
	rm -rf $(DEMO_OUT) examples/build bench/out .pytest_cache

# --- the FreeCAD workbench ---------------------------------------------------
FREECADCMD := freecadcmd
FREECAD    := freecad
# FreeCAD's user Mod folder, asked from FreeCAD itself (it differs between versions)
FC_MOD = $(shell $(FREECADCMD) -c "import FreeCAD,sys; sys.stdout.write('MODDIR=' + FreeCAD.getUserAppDataDir() + 'Mod\n')" 2>/dev/null | sed -n 's/^MODDIR=//p')
# the GUI as root needs the web engine's sandbox off; tests run on a virtual screen
FC_GUI_ENV := QTWEBENGINE_DISABLE_SANDBOX=1
XVFB       := xvfb-run -a -s "-screen 0 1280x1024x24"

.PHONY: install gui test-app test-gui test-workbench bench-freecad

install: $(VENV)/.installed
	@mod="$(FC_MOD)"; \
	if [ -z "$$mod" ]; then echo "== cannot ask FreeCAD for its Mod folder: is freecadcmd installed?"; exit 2; fi; \
	if [ -e "$$mod/Fabrickator" ] && [ ! -L "$$mod/Fabrickator" ]; then \
	  echo "== $$mod/Fabrickator exists and is not our link (an Addon Manager copy?): remove it first"; exit 2; fi; \
	mkdir -p "$$mod" && ln -sfn "$(CURDIR)" "$$mod/Fabrickator" && \
	echo "== Fabrickator linked into $$mod/Fabrickator: start FreeCAD and pick the Fabrickator workbench"

gui: install examples/build/hmd.step
	$(FC_GUI_ENV) $(FREECAD) FabrickatorWorkbench/example.py

# the workbench tests run with a throw-away FreeCAD user configuration (-u), so they
# neither read nor change the user's preferences
test-app: $(VENV)/.installed
	@cfg=$$(mktemp -d); $(FREECADCMD) -u $$cfg/user.cfg -t TestFabrickatorApp --module-path=$(CURDIR); \
	status=$$?; rm -rf $$cfg; exit $$status

test-gui: $(VENV)/.installed
	@cfg=$$(mktemp -d); $(FC_GUI_ENV) $(XVFB) $(FREECAD) -u $$cfg/user.cfg tests/gui/run_gui_tests.py \
	  --module-path=$(CURDIR); status=$$?; rm -rf $$cfg; exit $$status

# both workbench suites at once, each with its own user configuration: the GUI suite from
# the start, the app suite and then a second GUI runner beside it, the two runners sharing
# the GUI tests (FABRICKATOR_GUI_CLAIMS), so both cores stay busy to the end; the app suite's
# and the second runner's output is shown when all are done
test-workbench: $(VENV)/.installed
	@claims=$$(mktemp -d); log=$$(mktemp); \
	{ $(MAKE) --no-print-directory test-app >$$log 2>&1; echo $$? >$$claims.app; \
	  FABRICKATOR_GUI_CLAIMS=$$claims $(MAKE) --no-print-directory test-gui >$$log.gui 2>&1; } & lane=$$!; \
	FABRICKATOR_GUI_CLAIMS=$$claims $(MAKE) --no-print-directory test-gui; gui=$$?; wait $$lane; g2=$$?; \
	a=$$(cat $$claims.app); echo "== the app suite (freecadcmd):"; cat $$log; \
	echo "== the second GUI runner:"; cat $$log.gui; rm -rf $$log $$log.gui $$claims $$claims.app; \
	echo "== app suite: exit $$a, GUI runners: exit $$gui and $$g2"; [ $$a = 0 ] && [ $$gui = 0 ] && [ $$g2 = 0 ]

bench-freecad: examples/build/hmd.step
	$(FREECADCMD) bench/bench_freecad.py
