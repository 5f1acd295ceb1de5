"""Tool-point errors of an arm calibrated from images, against a known true arm.

A camera sees neither the arm's base (its pose is taken up by the board or camera pose)
nor where the flange ends (taken up by X), so a camera-calibrated arm is compared with the
true one after the best rigid alignment at both ends: a base transform ``B`` and a flange
transform ``E`` minimising ``sum |B T_est(q) E p - T_true(q) p|^2`` over the held-out
configurations and a few points ``p`` spread over the tool (the flange origin and points
``reach`` along its axes). The errors reported are those of the tool point after that
alignment, for the nominal arm and the calibrated one alike.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import matrix_from_axis_angle, transform_from

Array = NDArray[np.float64]

__all__ = ["aligned_frame_errors", "aligned_tool_errors"]


def aligned_tool_errors(model: SerialModel, params: Array, true_params: Array, q: Array,
                        tool: Array = (0.0, 0.0, 150.0), reach: float = 100.0) -> Array:
    """Tool-point errors ``(N,)`` of `params` against `true_params` after rigid alignment.

    Parameters
    ----------
    model : SerialModel
    params, true_params : ndarray, shape (n_params,)
        Estimated (nominal or calibrated) and true parameter vectors.
    q : ndarray, shape (N, n_joints)
        Held-out configurations (rad).
    tool : array_like, shape (3,)
        Tool point in the end frame (length unit).
    reach : float
        Distance of the alignment points from the end-frame origin.

    Returns
    -------
    ndarray, shape (N,)
        Distances (length unit).
    """
    return aligned_frame_errors(model.fk(q, params), model.fk(q, true_params), tool, reach)


def aligned_frame_errors(Te: Array, Tt: Array, tool: Array = (0.0, 0.0, 150.0),
                         reach: float = 100.0) -> Array:
    """Tool-point errors ``(N,)`` of estimated end frames `Te` ``(N, 4, 4)`` against true
    ones `Tt` after the rigid alignment at both ends (module docstring): what
    `aligned_tool_errors` computes from a model, for frames of any chain (a robot system's
    tip, `kinecal.kinematics.tree.SystemModel.tip_model`)."""
    pts = np.vstack([np.zeros(3), np.eye(3) * reach, np.asarray(tool, float)])

    def place(T: Array, x: Array) -> tuple[Array, Array, Array]:
        B = transform_from(matrix_from_axis_angle(x[:3]), x[3:6])
        E = transform_from(matrix_from_axis_angle(x[6:9]), x[9:12])
        return B, E, B @ T @ E

    def fun(x: Array) -> Array:
        _, _, A = place(Te, x)
        pe = np.einsum("nij,pj->npi", A[:, :3, :3], pts) + A[:, None, :3, 3]
        pt = np.einsum("nij,pj->npi", Tt[:, :3, :3], pts) + Tt[:, None, :3, 3]
        return (pe - pt).ravel()

    from scipy.optimize import least_squares

    x = least_squares(fun, np.zeros(12), method="lm", xtol=1e-14, ftol=1e-14).x
    _, _, A = place(Te, x)
    tp = np.asarray(tool, float)
    pe = np.einsum("nij,j->ni", A[:, :3, :3], tp) + A[:, :3, 3]
    pt = np.einsum("nij,j->ni", Tt[:, :3, :3], tp) + Tt[:, :3, 3]
    return np.linalg.norm(pe - pt, axis=1)
