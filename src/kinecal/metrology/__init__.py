"""Metrology: figures of merit a metrologist quotes, independent of any machine kind.

- `units`: the length unit a printed summary uses (``--unit mm|um|m``; a model in metres
  shown in millimetres by default).
- `stats`: error statistics of distance errors (mean, rms, std, max, percentiles) and
  per-axis summaries, shared by results and reports.
- `iso9283`: ISO 9283:1998 pose accuracy and repeatability (AP, RP, clauses 7.2.1-7.2.2)
  and distance accuracy and repeatability (AD, RD, clause 7.3) of repeated measurements
  (`iso9283` of a `kinecal.data.RepeatedPoses`). Pure numpy on top of `kinecal.spatial`;
  the CSV reader is `kinecal.io.repeatability`, the command ``kinecal iso9283``, the
  report `kinecal.report.iso9283`.
"""
