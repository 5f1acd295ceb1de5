"""Reports of kinecal results: matplotlib figures (Agg) and self-contained HTML.

`kinecal.report.figures.plot_calibration` draws one figure of a `CalibrationResult`
(behind `CalibrationResult.plot`); `kinecal.report.html` writes the HTML reports of
calibrations (`calibration_report`, behind `CalibrationResult.report`), hand-eye results
(`handeye_report`) and paper reproductions (`reproduce_report`). Both modules import
matplotlib lazily through this package, so importing `kinecal` stays light.
"""

from __future__ import annotations

__all__ = ["calibration_report", "handeye_report", "plot_calibration", "reproduce_report"]


def __getattr__(name: str):  # lazy: matplotlib loads only when a report is made
    if name == "plot_calibration":
        from kinecal.report.figures import plot_calibration

        return plot_calibration
    if name in ("calibration_report", "handeye_report", "reproduce_report"):
        from kinecal.report import html

        return getattr(html, name)
    raise AttributeError(f"module 'kinecal.report' has no attribute {name!r}")
