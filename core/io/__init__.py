"""Files in and out: model files read as one repaired mesh, a user's ``layout.json``, and the
output folder a run writes.

:mod:`~core.io.meshes` reads every supported model format (STL, OBJ, PLY, 3MF, STEP, BREP,
FCStd) into one repaired mesh in millimetres, or says in one line why it cannot, with the
B-rep formats read and tessellated by :mod:`~core.io.brep` and every mesh repaired by
:mod:`~core.io.repair`; :mod:`~core.io.layout_file` checks a ``layout.json`` field by field;
:mod:`~core.io.output_dir` checks an output folder before a run, writes beside it and
installs the result whole, so that a failed run never leaves half an output behind. Nothing
here decides what to build.
"""
