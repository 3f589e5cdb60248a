#!/bin/sh
# make test's suites after the host's core tests, in two lanes at once, so that neither of
# the two cores waits while the other finishes a suite:
#   lane 1: the GUI suite on this machine's FreeCAD, then on FreeCAD 1.x;
#   lane 2: the app suite on this machine's FreeCAD, then on FreeCAD 1.x the quick core
#           tests (one worker) and the app suite.
# Each lane's output is shown when both are done; exits 1 when any suite failed.
#   usage: tools/test_lanes.sh MAKE FREECAD1_ROOT|""   (no root: this machine's suites only)
MAKE=${1:?usage: test_lanes.sh MAKE FREECAD1_ROOT}
ROOT=${2:-}
HERE=$(cd "$(dirname "$0")" && pwd)
SUDO=$([ "$(id -u)" = 0 ] || echo sudo)
in_root() {  # in_root COPY TARGET...: make each TARGET in turn inside the root, on the copy /root/COPY
  copy=$1; shift
  FREECAD1_COPY=$copy FREECAD1_KEEP_MOUNTS=1 $SUDO sh "$HERE/freecad1/run.sh" "$ROOT" sh -c \
    'touch -d @0 .apt.stamp; s=0; for t in "$@"; do
       make --no-print-directory -o .apt.stamp VENV=/root/venv QUICK_WORKERS=1 "$t" || s=1; done; exit $s' \
    lane "$@"
}
lane1=$(mktemp); lane2=$(mktemp)
[ -n "$ROOT" ] && FREECAD1_KEEP_MOUNTS=1 $SUDO sh "$HERE/freecad1/run.sh" "$ROOT" true
{ $MAKE --no-print-directory test-gui; s=$?
  if [ -n "$ROOT" ]; then echo "== FreeCAD 1.x: the GUI suite"; in_root fab test-gui || s=1; fi
  exit $s; } >"$lane1" 2>&1 & one=$!
{ $MAKE --no-print-directory test-app; s=$?
  if [ -n "$ROOT" ]; then echo "== FreeCAD 1.x: the quick core tests, then the app suite"
    in_root app test-quick test-app || s=1; fi
  exit $s; } >"$lane2" 2>&1 & two=$!
wait $one; a=$?; wait $two; b=$?
[ -n "$ROOT" ] && $SUDO sh "$HERE/freecad1/release.sh" "$ROOT"
echo "== lane 1 (GUI suites):"; cat "$lane1"
echo "== lane 2 (app suites, FreeCAD 1.x quick core tests):"; cat "$lane2"
rm -f "$lane1" "$lane2"
echo "== lane 1: exit $a, lane 2: exit $b"
[ $a = 0 ] && [ $b = 0 ]
