"""Calibration: identify a machine's real geometry from measurements, and how sure that is.

By machine kind, each package opening with its papers and entry points:

- `kinecal.calibration.serial`: serial arms (papers 000 and 002): `calibrate`, error models,
  simulation, pose selection, cross-validation.
- `kinecal.calibration.stewart`: the parallel-link CMM of paper 004: `calibrate_stewart`.
- `kinecal.calibration.handeye`: AX = XB / AX = ZB (paper 001): `calibrate_handeye`, its
  refinements, pose planning, reprojection refinement from images.
- `kinecal.calibration.diagnostics`: plausibility checks of every kind, stable codes.

Shared helpers of every kind, at this level: `identifiability` (QR with column pivoting,
SVD, observability indices), `uncertainty` and `covariance` (standard errors on the
identifiable subspace), `method_options` (which options each method uses).
"""
