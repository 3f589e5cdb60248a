#!/bin/sh
# Unmount what tools/freecad1/run.sh mounted into the FreeCAD 1.x root and left there
# (FREECAD1_KEEP_MOUNTS=1): the shared models, /opt, /dev/shm, /dev and /proc.
#   usage: tools/freecad1/release.sh ROOT
ROOT=${1:?usage: release.sh ROOT}
for m in "$ROOT/root/shared" "$ROOT/opt" "$ROOT/dev/shm" "$ROOT/dev" "$ROOT/proc"; do
  mountpoint -q "$m" && { umount "$m" 2>/dev/null || umount -l "$m"; }
done
exit 0
