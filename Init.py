# Fabrickator: application start-up.  Kept tiny on purpose: FreeCAD runs this
# file with exec() for every start, GUI or not; the work lives in
# FabrickatorWorkbench/ and core/, imported lazily.  Before any module imports
# numpy, the module folder's .venv (numpy 2, cadquery, ...) goes first on
# sys.path, so FreeCAD's own modules and Fabrickator share one set of packages;
# a missing .venv is one line in the Report view naming the fix.
import os
import sys

import FreeCAD

from FabrickatorWorkbench import deps as _fabrickator_deps

_fabrickator_deps.bootstrap()

from FabrickatorWorkbench import llvm as _fabrickator_llvm  # noqa: E402
from FabrickatorWorkbench import undo as _fabrickator_undo  # noqa: E402

_fabrickator_llvm.isolate()

_fabrickator_undo.install()

_fabrickator_tests = os.path.join(_fabrickator_deps.ROOT, "tests", "app")
if os.path.isdir(_fabrickator_tests):
    if _fabrickator_tests not in sys.path:
        sys.path.append(_fabrickator_tests)
    FreeCAD.__unit_test__ += ["TestFabrickatorApp"]
