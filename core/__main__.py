"""``python -m core``: the headless command line."""

import os
import sys
import threading

try:
    from core.cli import main
except KeyboardInterrupt:
    sys.stderr.write("stopped by Ctrl-C while starting\n")
    sys.exit(130)

status = main()
if status > 128 and threading.active_count() > 1:
    # stopped by a signal while worker threads still wait on a slicer: do not wait for
    # them (the slicer dies with this process, core.print_time.dying_with_us)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)
sys.exit(status)
