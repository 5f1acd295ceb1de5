"""Plausibility diagnostics of calibrations: serial arms, Stewart platforms, hand-eye.

Each check is a plain function of arrays and models that calls
`kinecal.diagnostics.warn(code, message)` when it finds something implausible (or raises
`kinecal.InputError` when the data cannot give an answer at all). The calibration entry
points run them; `CODES` lists every code with a one-line meaning (docs/diagnostics.md
explains each one with its likely cause, what to do and an example).
"""

from __future__ import annotations

__all__ = ["CODES"]

#: every diagnostic code kinecal's calibrations issue -> what it means
CODES: dict[str, str] = {
    "too-few-poses": "the distinct poses give no more equations than free parameters (error)",
    "few-poses": "fewer than 3 equations per free parameter",
    "duplicate-poses": "rows repeat the joint readings of other rows",
    "joint-limits": "joint readings outside the model's joint limits",
    "joint-units": "joint readings look like the other angle unit",
    "scale-mismatch": "measured lengths in another unit than the model's",
    "mirrored-frame": "measured positions fit the model mirrored (an axis negated)",
    "initial-error": "the data are far from the nominal model: wrong model or frame",
    "validation-overlap": "validation poses repeat calibration poses",
    "rank-deficient": "the poses identify fewer parameters than well-spread poses do",
    "unidentifiable-free": "free parameters that the poses cannot identify",
    "parameter-tolerance": "an identified parameter moved far beyond its tolerance",
    "residual-offset": "the residual holds an offset a free base frame would take",
    "lack-of-fit": "the residual is far above the repeatability of repeated poses",
    "outliers": "poses whose error is far outside the others' spread",
    "leg-range": "Stewart leg readings outside the geometry's leg range",
    "angle-units": "Stewart pose angles that look like radians",
    "handeye-conditioning": "hand-eye motions too close to one rotation axis for the noise",
    "absolute-errors": "simulate(errors=...) got absolute parameter values, not deviations",
}
