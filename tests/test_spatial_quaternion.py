"""`quaternion_from_matrix` (branch-free) gives the bits of the per-branch formulation it
replaced: the largest of trace and diagonal chooses the branch, the other components come
from off-diagonal sums or differences, near 0, near pi and at the axis-aligned half turns."""

import numpy as np

from kinecal.spatial import matrix_from_axis_angle, matrix_from_quaternion, quaternion_from_matrix


def _reference(M):
    """The per-branch computation (boolean masks per branch), as it was written before."""
    M = M.reshape(-1, 3, 3)
    tr = np.trace(M, axis1=1, axis2=2)
    k = np.argmax(np.stack([tr, M[:, 0, 0], M[:, 1, 1], M[:, 2, 2]], axis=1), axis=1)
    q = np.empty((M.shape[0], 4))
    for b in range(4):
        i = k == b
        m = M[i]
        if b == 0:
            s = 2.0 * np.sqrt(np.maximum(1.0 + tr[i], 0.0))
            qb = [0.25 * s, (m[:, 2, 1] - m[:, 1, 2]) / s, (m[:, 0, 2] - m[:, 2, 0]) / s,
                  (m[:, 1, 0] - m[:, 0, 1]) / s]
        elif b == 1:
            s = 2.0 * np.sqrt(np.maximum(1.0 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2], 0.0))
            qb = [(m[:, 2, 1] - m[:, 1, 2]) / s, 0.25 * s, (m[:, 0, 1] + m[:, 1, 0]) / s,
                  (m[:, 0, 2] + m[:, 2, 0]) / s]
        elif b == 2:
            s = 2.0 * np.sqrt(np.maximum(1.0 + m[:, 1, 1] - m[:, 0, 0] - m[:, 2, 2], 0.0))
            qb = [(m[:, 0, 2] - m[:, 2, 0]) / s, (m[:, 0, 1] + m[:, 1, 0]) / s, 0.25 * s,
                  (m[:, 1, 2] + m[:, 2, 1]) / s]
        else:
            s = 2.0 * np.sqrt(np.maximum(1.0 + m[:, 2, 2] - m[:, 0, 0] - m[:, 1, 1], 0.0))
            qb = [(m[:, 1, 0] - m[:, 0, 1]) / s, (m[:, 0, 2] + m[:, 2, 0]) / s,
                  (m[:, 1, 2] + m[:, 2, 1]) / s, 0.25 * s]
        q[i] = np.stack(qb, axis=1)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0] *= -1.0
    return q


def test_branch_free_quaternions_have_the_reference_bits():
    rng = np.random.default_rng(0)
    ax = rng.normal(size=(3000, 3))
    ax /= np.linalg.norm(ax, axis=1, keepdims=True)
    R = np.concatenate([
        matrix_from_quaternion(rng.normal(size=(20000, 4))),
        matrix_from_axis_angle(ax * (np.pi - rng.uniform(0, 1e-7, (3000, 1)))),
        matrix_from_axis_angle(ax * rng.uniform(0, 1e-9, (3000, 1))),
        np.eye(3)[None], np.diag([1.0, -1, -1])[None], np.diag([-1.0, 1, -1])[None],
        np.diag([-1.0, -1, 1])[None]])
    assert np.array_equal(quaternion_from_matrix(R), _reference(R))
    assert quaternion_from_matrix(R[:7].reshape(7, 1, 3, 3)).shape == (7, 1, 4)
