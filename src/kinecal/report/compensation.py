"""Report section: what the calibration changes in a robot program (compensation).

The calibration's held-out validation poses (else up to `MAX_ROWS` calibration poses) are
treated as a joint program and compensated with `kinecal.compensation.api`: the
section shows how far each pose's command moves (joint and Cartesian corrections), whether
the calibrated arm reaches every nominal pose, and the command that does the same for any
program.
"""

from __future__ import annotations

import html
from typing import Any

import numpy as np

from kinecal.errors import InputError

__all__ = ["MAX_ROWS", "compensation_section"]

#: poses compensated for the report (the first ones) and rows shown one by one
MAX_ROWS = 200
SHOWN_ROWS = 20


def compensation_section(result: Any) -> str:
    """The ``compensation`` section of a calibration report (HTML).

    Parameters
    ----------
    result : CalibrationResult
        A serial-arm calibration with its joint values (validation or calibration poses).
    """
    from kinecal.compensation.api import compensate
    from kinecal.report.markup import section, table

    nom = result.nominal_model
    q, which = result.q_validation, "held-out validation"
    if q is None or not len(q):
        q, which = result.q_calibration, "calibration"
    if q is None or not len(q):
        return section("compensation", "Compensation",
                       "<p>No joint values in this result: nothing to compensate.</p>")
    q = np.asarray(q)[:MAX_ROWS]
    try:
        res = compensate(result, joints=q, diagnose=False)
    except InputError as exc:  # e.g. a model with several markers
        return section("compensation", "Compensation",
                       f"<p>Not computed: {html.escape(exc.message)}</p>")
    unit = nom.length_unit
    dq = np.degrees(res.joint_motion()[0])  # revolute joints (prismatic: a length)
    ok = res.converged
    rows = [
        ("poses compensated", f"{len(res)} ({which} poses, as a joint program)"),
        ("compensated", "position and orientation" if res.outputs == "pose" else "position"),
        ("converged", f"{int(ok.sum())} of {len(res)}"),
        (f"correction mean / max [{unit}]", f"{res.correction.mean():.4g} / "
                                            f"{res.correction.max():.4g}"),
    ]
    if res.outputs == "pose":
        a = np.degrees(res.correction_rotation)
        rows.append(("correction angle mean / max [deg]", f"{a.mean():.4g} / {a.max():.4g}"))
    rows.append(("largest joint correction [deg]", f"{dq.max():.4g}"))
    if ok.any():
        rows.append((f"residual of the calibrated model, max [{unit}]",
                     f"{res.residual[ok].max():.2g}"))
    others = {s: k for s, k in res.ik.counts().items() if k and s != "converged"}
    if others:
        rows.append(("other rows", ", ".join(f"{k} {s}" for s, k in others.items())))
    head = ["pose", "max |dq| [deg]", f"correction [{unit}]"]
    if res.outputs == "pose":
        head.append("angle [deg]")
    per = []
    for k in range(min(len(res), SHOWN_ROWS)):
        row = [k + 1, float(dq[k]), float(res.correction[k])]
        if res.outputs == "pose":
            row.append(float(np.degrees(res.correction_rotation[k])))
        per.append([*row, str(res.status[k])])
    body = (
        "<p>Compensation puts the calibration to work: for every pose of a joint program the "
        "controller commands joints that make the <em>calibrated</em> arm reach the pose the "
        "<em>nominal</em> model meant. The correction is how far each command moves, to "
        "first order the error the uncompensated program has on the real arm.</p>"
        + table(None, rows)
        + table([*head, "status"], per, left=0)
        + ("<p>Any program: <code>kinecal compensate CALIBRATED.yaml PROGRAM.csv --out "
           "COMPENSATED.csv</code> (joints <code>q1..qn</code>, or targets <code>x,y,z"
           "[,qw,qx,qy,qz]</code> with filtered targets for a controller that keeps its "
           "nominal model).</p>")
    )
    return section("compensation", "Compensation", body)
