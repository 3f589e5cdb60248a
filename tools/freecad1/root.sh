#!/bin/sh
# Build (once) a Debian 13 "trixie" root filesystem with FreeCAD 1.x in it, without
# touching this machine's apt sources: debootstrap into ROOT, apt inside the root only.
# The host's CA certificates and pip configuration are copied in, so pip inside the
# root reaches the same package registries as the host.
#   usage: tools/freecad1/root.sh ROOT
# Idempotent: a finished root has ROOT/.fabrickator-root (holding its package list) and is
# left as it is while that list is unchanged; a new package is installed into it.
set -eu
ROOT=${1:?usage: root.sh ROOT}
MIRROR=${DEBIAN_MIRROR:-http://deb.debian.org/debian}
# e2fsprogs: chattr, for the hostile tests of files that cannot be deleted
PKGS="freecad python3-venv python3-pip xvfb xauth ca-certificates prusa-slicer make git e2fsprogs"
STAMP="$ROOT/.fabrickator-root"
[ -e "$STAMP" ] && [ "$(cat "$STAMP")" = "$PKGS" ] && exit 0
[ "$(id -u)" = 0 ] || { echo "root.sh: making a root filesystem needs root (run as root or with sudo)"; exit 2; }
command -v debootstrap >/dev/null || {
  echo "== installing debootstrap (a bookworm package)"
  DEBIAN_FRONTEND=noninteractive apt-get install -y -q debootstrap; }
if [ ! -x "$ROOT/usr/bin/apt-get" ] || [ ! -e "$ROOT/.debootstrap-done" ]; then
  rm -rf "$ROOT"
  echo "== debootstrap trixie into $ROOT"
  debootstrap --variant=minbase trixie "$ROOT" "$MIRROR" >"${ROOT%/}.debootstrap.log" 2>&1 || {
    echo "root.sh: debootstrap failed, see ${ROOT%/}.debootstrap.log"; tail -5 "${ROOT%/}.debootstrap.log"; exit 1; }
  touch "$ROOT/.debootstrap-done"
fi
cp /etc/resolv.conf "$ROOT/etc/resolv.conf"
echo "== apt-get install (inside the root): $PKGS"
chroot "$ROOT" /usr/bin/env DEBIAN_FRONTEND=noninteractive sh -c \
  "apt-get update -q >/dev/null && apt-get install -y -q --no-install-recommends $PKGS >/var/log/fabrickator-apt.log 2>&1" || {
  echo "root.sh: apt-get inside the root failed, see $ROOT/var/log/fabrickator-apt.log"; tail -5 "$ROOT/var/log/fabrickator-apt.log"; exit 1; }
# after apt: the ca-certificates package rewrites the bundle, the host's own CAs go on top
cp /etc/ssl/certs/ca-certificates.crt "$ROOT/etc/ssl/certs/ca-certificates.crt"
if [ -d /usr/local/share/ca-certificates ]; then
  mkdir -p "$ROOT/usr/local/share/ca-certificates"
  cp -r /usr/local/share/ca-certificates/. "$ROOT/usr/local/share/ca-certificates/"
fi
[ -e /etc/pip.conf ] && cp /etc/pip.conf "$ROOT/etc/pip.conf"
if [ -e "$HOME/.config/pip/pip.conf" ]; then
  mkdir -p "$ROOT/root/.config/pip" && cp "$HOME/.config/pip/pip.conf" "$ROOT/root/.config/pip/pip.conf"
fi
chroot "$ROOT" freecadcmd --version 2>/dev/null | head -1 || true
echo "$PKGS" >"$STAMP"
