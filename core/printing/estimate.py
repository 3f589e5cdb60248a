"""The print time of a plate as a result, and the calibrated estimate that stands in for the slicer.

:class:`PrintEstimate` is the time of one plate with how it was found (the slicer, its
settings and pose, or the estimate and why no slicer ran).  :func:`estimate_seconds` is a
linear model in volume, surface area, layers and part-layers (:func:`estimate_features`,
:func:`plate_features`) whose coefficients (:data:`ESTIMATE_COEFFS`) :func:`fit_estimate`
fitted against real PrusaSlicer runs; it needs no slicer and the same plate always gives the
same number.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

from core.printing.plate import as_meshes


ESTIMATE_METHOD = "estimate (volume/surface/layers model)"

#: Layer height (mm) the estimate counts layers with: the default profile's.
ESTIMATE_LAYER_MM = 0.2

#: Coefficients of :func:`estimate_seconds`, multiplying the plate's
#: (volume mm^3, surface area mm^2, layers, part-layers, 1).  Fitted with
#: :func:`fit_estimate` (least squares on relative error, coefficients >= 0)
#: against prusa-slicer 2.5.0 with FALLBACK_PROFILE (its bundle) on the calibration plates
#: of tests/core/test_print_time.py (boxes, cylinders, a tube, a cup, a
#: sphere, LEGO-like studded parts, multi-part plates and six models of
#: /work/shared/models), 21 plates from 20 min to 5 h, sliced without
#: supports.  Relative error of the fit: rms 10.6 %, max 21 %; leave-one-out
#: rms 14 %, max 31 %.
ESTIMATE_COEFFS = (0.04172, 0.2796, 5.67, 0.5232, 53.98)


@dataclass
class PrintEstimate:
    """Print time of one plate.

    ``method`` names the slicer, version and profile and the settings that
    were added (``"prusa-slicer 2.5.0 (MK3S, 0.20mm QUALITY, PLA; with
    supports)"``), then the pose print_time chose, if it chose one
    (``"; posed on side +y, the fastest of 3 sliced poses"``); or it starts
    with ``"estimate"`` and then says why no slicer was used.
    ``gcode_path`` is the sliced G-code, or None for an estimate.
    ``supports`` says whether the time includes supports, ``pose`` names
    the pose :func:`~core.printing.print_time.print_time` turned the mesh into (several meshes'
    joined by ", "), None when every mesh came in its print pose.
    ``cached`` says the slicer's answer came from :mod:`core.printing.slice_cache`
    (the same plate sliced before; no G-code then).  ``enlarged_bed`` says it
    was sliced on a bed enlarged to fit (:func:`core.printing.printers.reference_time`).
    """

    seconds: float
    method: str
    gcode_path: str | None
    supports: bool = False
    pose: str | None = None
    cached: bool = False
    enlarged_bed: bool = False


def estimate_features(meshes) -> np.ndarray:
    """The estimate's inputs for one plate: (volume, area, layers, part-layers, 1).

    Volume (mm^3, absolute value, so inverted meshes count) and surface
    area (mm^2) are summed over the parts; layers is the tallest part's
    height / ESTIMATE_LAYER_MM (layer changes); part-layers the sum of that
    over all parts (per-layer travel and retraction between parts).
    """
    parts = as_meshes(meshes)
    return plate_features([abs(float(m.volume)) for m in parts], [float(m.area) for m in parts],
                          [float(m.extents[2]) for m in parts])


def plate_features(volumes, areas, heights) -> np.ndarray:
    """The estimate's inputs (as :func:`estimate_features`) of one plate whose parts have
    these volumes (mm^3), surface areas (mm^2) and heights on the bed (mm), one each."""
    layers = np.asarray(heights, dtype=float) / ESTIMATE_LAYER_MM
    return np.array([float(np.sum(volumes)), float(np.sum(areas)), layers.max(), layers.sum(), 1.0])


def estimate_seconds(meshes, coeffs=ESTIMATE_COEFFS) -> float:
    """Estimated print time in seconds of all ``meshes`` on one plate, no slicer needed.

    ``coeffs`` . :func:`estimate_features`; the default coefficients are
    calibrated for FALLBACK_PROFILE (see ESTIMATE_COEFFS).  An empty plate
    takes 0 s.
    """
    if len(meshes) == 0:
        return 0.0
    return float(estimate_features(meshes) @ np.asarray(coeffs, dtype=float))


def fit_estimate(plates: list, seconds) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients for :func:`estimate_seconds` fitted to measured times.

    ``plates`` is a list of mesh lists, ``seconds`` the slicer's time for
    each.  Minimises the squared relative error with coefficients >= 0
    (scipy ``nnls``); returns the coefficients and each plate's relative
    error (estimate / measured - 1).
    """
    measured = np.asarray(seconds, dtype=float)
    features = np.array([estimate_features(plate) for plate in plates])
    coeffs, _ = nnls(features / measured[:, None], np.ones_like(measured))
    return coeffs, features @ coeffs / measured - 1.0
