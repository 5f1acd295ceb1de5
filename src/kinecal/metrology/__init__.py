"""Metrology: figures of merit a metrologist quotes, independent of any machine kind.

`stats`: error statistics of distance errors (mean, rms, std, max, percentiles) and per-axis
summaries, shared by results and reports.
"""
