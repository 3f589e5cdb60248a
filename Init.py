# Fabrickator: application start-up.  Kept tiny on purpose: FreeCAD runs this
# file with exec() for every start, GUI or not; the work lives in
# FabrickatorWorkbench/ and core/, imported lazily.
