"""The registry: a record per robot serial number, quick checks, drift over time, fleets.

A calibration is used for years. The registry keeps, per robot serial number, every
calibration (result JSON, report, the model it was calibrated from, the SHA-256 of its
inputs, date, operator, instrument, command line), every check, and which calibration is
current; history is append-only (a correction is a new record; a record leaves the
history only through a retraction with its reason). The store is an SQLite file
(``kinecal.db`` in the working folder, ``$KINECAL_DB`` or ``--db PATH``) or a PostgreSQL
database (``--db postgresql://...``), through SQLAlchemy Core, its schema made and
upgraded by the Alembic migrations shipped in `kinecal.registry.migrations`. The page
docs/robot-life.md walks through a robot's life with it.

The check (`check`) compares the current calibration's prediction with a few poses
measured today, of any measurement kind (`kinecal.calibration.blocks`), judged against that
calibration's own uncertainty (its parameter covariance propagated to the poses) and the
instrument's noise: a chi-square test of the whitened residuals and a test of a change
along the directions robots usually suffer (joint offsets, base), after Teunissen's
detection-identification testing of least-squares residuals (Teunissen 2000, *Testing
Theory*) and the variance propagation of the GUM (JCGM 100:2008).

Public entry points
-------------------
`open_registry` (`store`)
    The store at a ``--db`` value: `Registry` with ``add_calibration``, ``add_check``,
    ``set_current``, ``retract``, ``robots``, ``history``, ``current``.
`run_check` (`check`)
    A check of today's measurements against a calibration result.
`plan_check` (`plan`)
    The few poses that best reveal joint offsets, base and bent links.
`drift_summary` (`drift`)
    Drift rates per parameter direction and the projected date of crossing the limit.
`check_fleet` (`fleet`)
    Checks of many robots on a process pool or Dask, one transaction per robot.
"""

from kinecal._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "open_registry": "kinecal.registry.store",
    "Registry": "kinecal.registry.store",
    "run_check": "kinecal.registry.check",
    "CheckResult": "kinecal.registry.check",
    "plan_check": "kinecal.registry.plan",
    "drift_summary": "kinecal.registry.drift",
    "check_fleet": "kinecal.registry.fleet",
})
