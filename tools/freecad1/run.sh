#!/bin/sh
# Run a command inside the FreeCAD 1.x root (tools/freecad1/root.sh) on a copy of this
# working tree, with ../shared beside it, the host's /opt package caches read-only and
# a Python 3.13 venv that lives in the root (never the host's .venv).
#   usage: tools/freecad1/run.sh ROOT COMMAND...      (COMMAND runs in the copy, /root/fab)
# The copy is refreshed from the working tree every run (.venv and outputs left out);
# tests/gui/artifacts of the run are copied back to tests/gui/artifacts-freecad1/.
# FREECAD1_COPY=NAME uses /root/NAME for the copy (runs side by side), and
# FREECAD1_KEEP_MOUNTS=1 leaves the mounts for other runs (unmounted at exit otherwise).
set -eu
ROOT=${1:?usage: run.sh ROOT COMMAND...}; shift
REPO=$(cd "$(dirname "$0")/../.." && pwd)
SHARED="$REPO/../shared"
mounts=""
COPY=${FREECAD1_COPY:-fab}
cleanup() {
  [ "${FREECAD1_KEEP_MOUNTS:-}" = 1 ] && return 0
  for m in $mounts; do umount "$m" 2>/dev/null || umount -l "$m" 2>/dev/null || true; done
}
trap cleanup EXIT INT TERM
bind() {  # bind SRC DEST [ro]
  mkdir -p "$2"
  mountpoint -q "$2" && return 0
  mount --bind "$1" "$2"
  [ "${3:-}" = ro ] && mount -o remount,bind,ro "$2"
  mounts="$2 $mounts"
}
mountpoint -q "$ROOT/proc" || { mount -t proc proc "$ROOT/proc"; mounts="$ROOT/proc $mounts"; }
bind /dev "$ROOT/dev"
mountpoint -q "$ROOT/dev/shm" || { mount -t tmpfs shm "$ROOT/dev/shm"; mounts="$ROOT/dev/shm $mounts"; }
[ -d /opt ] && bind /opt "$ROOT/opt" ro
if [ -d "$SHARED" ]; then bind "$SHARED" "$ROOT/root/shared" ro; fi
# the hostile tests run the CLI as user nobody from the copy: /root is 700 in a fresh root
chmod 755 "$ROOT/root"
rm -rf "$ROOT/root/$COPY"
mkdir -p "$ROOT/root/$COPY"
tar -C "$REPO" --exclude=./.venv --exclude=./demo-out --exclude=./bench/out --exclude=./.apt.stamp \
    --exclude='./tests/gui/artifacts*' --exclude=.pytest_cache --exclude=__pycache__ -cf - . \
  | tar -C "$ROOT/root/$COPY" -xf -
status=0
chroot "$ROOT" /usr/bin/env -i HOME=/root PATH=/usr/local/bin:/usr/bin:/bin LANG=C.UTF-8 \
  TERM=dumb FABRICKATOR_VENV=/root/venv sh -c 'cd "/root/$0" && "$@"' "$COPY" "$@" || status=$?
if [ -d "$ROOT/root/$COPY/tests/gui/artifacts" ]; then
  out="$REPO/tests/gui/artifacts-freecad1"
  [ "$COPY" = fab ] || out="$out-$COPY"
  rm -rf "$out"
  cp -r "$ROOT/root/$COPY/tests/gui/artifacts" "$out"
fi
exit $status
