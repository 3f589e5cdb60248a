"""Fabrickator core: everything that does not need FreeCAD.

Stages (one module each), passing plain data from :mod:`core.model`:

``mesh_io`` (load and repair a model) → ``voxelize`` (legofy into a
:class:`~core.model.Grid`) → ``layout`` (merge 1x1 plates into catalog
parts, a :class:`~core.model.Layout`) → ``stability`` (connectivity graph,
components, weak points).  ``pipeline.fabricate`` runs them all; the CLI
(``python -m core``) wraps it.
"""

__version__ = "0.1.0"
