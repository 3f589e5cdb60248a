"""``python -m core``: the headless command line."""

import contextlib
import os
import sys
import threading

from core.errors import address_space_shortage

# before any library is loaded: below its limit OpenBLAS hangs while it loads, LLVM aborts
shortage = address_space_shortage(sys.argv[1] if len(sys.argv) > 1 else "")
if shortage is not None:
    with contextlib.suppress(AttributeError, OSError, ValueError):   # no stderr: the status tells
        sys.stderr.write(shortage + "\n")
    sys.exit(2)
try:
    from core.cli import main
except KeyboardInterrupt:
    with contextlib.suppress(AttributeError, OSError, ValueError):
        sys.stderr.write("stopped by Ctrl-C while starting\n")
    sys.exit(130)

status = main()
if threading.active_count() > 1:
    # stopped (Ctrl-C, SIGTERM; watch ends so too) while worker threads still wait on a
    # slicer: do not wait for them (the slicer dies with this process,
    # core.printing.print_time.dying_with_us); after a run that ended normally none is left
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(status)
sys.exit(status)
