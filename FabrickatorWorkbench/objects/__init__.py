"""Document objects of Fabrickator: FeaturePython proxies and the objects they own.

The proxy classes' module paths are written into saved ``.FCStd`` files:
:mod:`.fabrication` (``Fabrication``), :mod:`.printed_part`
(``PrintedPart``), :mod:`.high_res_region` (``HighResRegion``) and
:mod:`.prototype` (``Prototype``) keep their names.  :mod:`.fabricate` runs
the core for a Fabrication and :mod:`.tree` keeps its tree of brick objects
in step with the result.
"""
