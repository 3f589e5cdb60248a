"""Run the GUI tests inside FreeCAD and end FreeCAD with their status.

    QTWEBENGINE_DISABLE_SANDBOX=1 xvfb-run -a -s "-screen 0 1280x1024x24" \\
        freecad -u TMPDIR/user.cfg tests/gui/run_gui_tests.py --module-path=REPO

FreeCAD runs this file as a macro once its window is up; the tests start
from the event loop, and the process exits with 0 when all pass, 1
otherwise (also when they take longer than $FABRICKATOR_GUI_TIMEOUT
seconds, default 2400: a dialog nobody answers must not hang CI).  A test
name (or part of one) in $FABRICKATOR_GUI_TESTS runs only the matching
tests.  With $FABRICKATOR_GUI_CLAIMS naming a folder, several runners share the
tests: each runs a test only once it has claimed it there (a class with class
fixtures as a whole), so a second runner started later takes what is left.
"""

import os
import sys
import time
import traceback
import unittest

from PySide import QtCore


class _ReportAtOnce(unittest.TextTestResult):
    """A result that prints each failure's traceback when it happens and remembers the running test.

    The watchdog may end FreeCAD before unittest's summary, so a failure must not wait for it.
    """

    running = None
    started = time.monotonic()

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.took = []

    def startTest(self, test):
        type(self).running = (test.id(), time.monotonic())
        super().startTest(test)

    def stopTest(self, test):
        self.took.append((time.monotonic() - type(self).running[1], test.id()))
        super().stopTest(test)

    def slowest(self, count=15):
        """The ``count`` slowest tests' wall times, as pytest's --durations prints them."""
        rows = sorted(self.took, reverse=True)[:count]
        return "".join(f"{seconds:7.2f}s {name}\n" for seconds, name in rows)

    def _at_once(self, kind, test, err):
        self.stream.write(f"\n{kind}: {test.id()}\n{self._exc_info_to_string(err, test)}\n")
        self.stream.flush()

    def addFailure(self, test, err):
        super().addFailure(test, err)
        self._at_once("FAIL", test, err)

    def addError(self, test, err):
        super().addError(test, err)
        self._at_once("ERROR", test, err)

    def printErrors(self):
        if self.failures or self.errors:
            self.stream.write(f"\n{len(self.failures)} failure(s), {len(self.errors)} error(s): "
                              "their tracebacks are printed above, where they happened\n")


class _Claimed(unittest.TestSuite):
    """The tests of ``suite`` that this runner claims in the folder ``claims`` as it reaches
    them (an exclusive file per test, or per class where the class has class fixtures)."""

    _cleanup = False  # the tests are held in ``flat``, not in the suite's own list

    def __init__(self, suite, claims):
        super().__init__()
        self.flat = [t for s in suite for t in (s if isinstance(s, unittest.TestSuite) else [s])]
        self.claims = claims

    @staticmethod
    def _whole(cls) -> bool:
        return "setUpClass" in vars(cls) or "tearDownClass" in vars(cls)

    def _claim(self, test) -> bool:
        cls = type(test)
        name = f"{cls.__module__}.{cls.__qualname__}" if self._whole(cls) else test.id()
        try:
            os.close(os.open(os.path.join(self.claims, name), os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            return True
        except FileExistsError:
            return False

    def __iter__(self):
        held = set()
        for test in self.flat:
            cls = type(test)
            if cls in held or self._claim(test):
                if self._whole(cls):
                    held.add(cls)
                yield test


def _run():
    status = 1
    try:
        import FabrickatorWorkbench

        root = os.path.dirname(os.path.dirname(os.path.abspath(FabrickatorWorkbench.__file__)))
        sys.path.insert(0, os.path.join(root, "tests", "gui"))
        import TestFabrickatorGui

        suite = unittest.defaultTestLoader.loadTestsFromModule(TestFabrickatorGui)
        wanted = os.environ.get("FABRICKATOR_GUI_TESTS")
        if wanted:
            suite = unittest.TestSuite(t for s in suite for t in s if wanted in t.id())
        claims = os.environ.get("FABRICKATOR_GUI_CLAIMS")
        if claims:
            suite = _Claimed(suite, claims)
        result = unittest.TextTestRunner(stream=sys.stderr, verbosity=2, resultclass=_ReportAtOnce).run(suite)
        sys.stderr.write(f"\nslowest {min(15, len(result.took))} tests:\n{result.slowest()}")
        status = 0 if result.wasSuccessful() else 1
    except BaseException:
        traceback.print_exc()
    finally:
        sys.stderr.flush()
        sys.stdout.flush()
        os._exit(status)


def _watchdog():
    now = time.monotonic()
    running = _ReportAtOnce.running
    where = f"in {running[0]}, running for {now - running[1]:.0f} s" if running else "before the first test"
    sys.stderr.write(f"GUI tests took too long ({now - _ReportAtOnce.started:.0f} s): stopped {where}\n")
    sys.stderr.flush()
    os._exit(1)


def _close_stuck_dialogs(seen={}):
    """A modal dialog open for more than 10 s is reported (title and text) and rejected."""
    import time

    from PySide import QtGui

    widget = QtGui.QApplication.activeModalWidget()
    if widget is None:
        seen.clear()
        return
    first = seen.setdefault(id(widget), time.monotonic())
    if time.monotonic() - first > 10:
        text = widget.text() if hasattr(widget, "text") else ""
        sys.stderr.write(f"stuck modal dialog {widget.windowTitle()!r}: {text!r}: rejected\n")
        widget.reject()


_stuck = QtCore.QTimer()
_stuck.timeout.connect(_close_stuck_dialogs)
_stuck.start(500)
_timer = QtCore.QTimer()
_timer.setSingleShot(True)
_timer.timeout.connect(_watchdog)
_timer.start(int(float(os.environ.get("FABRICKATOR_GUI_TIMEOUT", "2400")) * 1000))
QtCore.QTimer.singleShot(1000, _run)
