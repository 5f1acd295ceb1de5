"""Image formation: a calibration board rendered through a known camera (OpenCV
distortion model) with illumination, blur and noise; used by `kinecal.vision.render`.

Image formation (`render_board`), per pixel of a ``supersample``-times finer grid: the pixel
is undistorted exactly through the camera's OpenCV distortion model (Newton iterations on
the forward model of `kinecal.calibration.handeye.camera`), its ray is intersected with the
board plane, and the board's printed texture is sampled there (bilinear, texture edges on
texel boundaries, so the rendered edges lie where the geometry puts them); the fine image is
averaged down (box filter = pixel area integration). Then, in this order: illumination
(gain, linear gradient, vignetting, offset) on the board's albedo (black 20, white 235 on
0-255) and the background, Gaussian blur (optics / defocus), Gaussian read noise plus
signal-dependent shot noise, quantisation to 8 bits. A noise-free render places every corner
at the projection of its board point to about 0.01 px (tests).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye.camera import check_camera, project
from kinecal.errors import InputError
from kinecal.vision import require_cv2
from kinecal.vision.boards import Board

Array = NDArray[np.float64]

__all__ = ["ImageConditions", "render_board", "render_boards", "undistort_normalized"]

_BLACK, _WHITE = 20.0, 235.0


@dataclass
class ImageConditions:
    """Imaging conditions of one rendered image (all optional; defaults: ideal image).

    Attributes
    ----------
    blur : float
        Gaussian blur sigma (px) applied after pixel integration.
    noise : float
        Read noise sigma (grey levels).
    shot : float
        Shot noise: extra variance ``shot * intensity`` (grey levels^2 per grey level).
    gain : float
        Illumination gain (1: white paper at 235).
    offset : float
        Added dark level (grey levels).
    gradient : (float, float)
        Relative illumination change across the image width and height (0.3 = +-15 %).
    vignetting : float
        Relative darkening in the image corners.
    background : float
        Albedo of the scene behind the board (grey levels at gain 1).
    """

    blur: float = 0.0
    noise: float = 0.0
    shot: float = 0.0
    gain: float = 1.0
    offset: float = 0.0
    gradient: tuple[float, float] = (0.0, 0.0)
    vignetting: float = 0.0
    background: float = 110.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict of the fields."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}


def undistort_normalized(uv: Array, K: Array, dist8: Array, iterations: int = 30) -> Array:
    """Normalised undistorted coordinates ``(N, 2)`` of pixels ``(N, 2)``: the exact inverse
    of `kinecal.calibration.handeye.camera.project` by Newton iterations on the forward
    model (to < 1e-13 for the distortions of real lenses; points where the model folds back
    are left at their last iterate)."""
    yd = (uv[:, 1] - K[1, 2]) / K[1, 1]
    xd = (uv[:, 0] - K[0, 2] - K[0, 1] * yd) / K[0, 0]
    if not np.any(dist8):
        return np.column_stack([xd, yd])
    k1, k2, p1, p2, k3, k4, k5, k6 = dist8
    x, y = xd.copy(), yd.copy()
    for _ in range(iterations):
        r2 = x * x + y * y
        num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
        f = num / den
        fr = ((k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)) * den
              - num * (k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2))) / (den * den)
        ex = x * f + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) - xd
        ey = y * f + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y - yd
        a = f + 2.0 * x * x * fr + 2.0 * p1 * y + 6.0 * p2 * x
        b = 2.0 * x * y * fr + 2.0 * p1 * x + 2.0 * p2 * y
        d = f + 2.0 * y * y * fr + 6.0 * p1 * y + 2.0 * p2 * x
        det = a * d - b * b
        x -= (d * ex - b * ey) / det
        y -= (a * ey - b * ex) / det
        if max(np.nanmax(np.abs(ex)), np.nanmax(np.abs(ey))) < 1e-14:
            break
    return np.column_stack([x, y])


def render_board(
    board: Board,
    K: Array,
    dist: Array | None,
    target2cam: Array,
    size: tuple[int, int],
    conditions: ImageConditions | None = None,
    *,
    supersample: int = 3,
    rng: int | np.random.Generator | None = None,
) -> NDArray[np.uint8]:
    """One 8-bit grey image of `board` at pose `target2cam` (see the module docstring).

    Parameters
    ----------
    board : Board
        The board (its length unit is the unit of ``target2cam``).
    K : ndarray, shape (3, 3)
        Camera matrix (pixels, OpenCV convention).
    dist : ndarray, shape (4,), (5,) or (8,), optional
        OpenCV distortion coefficients.
    target2cam : ndarray, shape (4, 4)
        Board pose in the camera frame.
    size : (int, int)
        Image ``(width, height)`` in pixels.
    conditions : ImageConditions, optional
        Illumination, blur and noise; default an ideal image.
    supersample : int
        Samples per pixel along each axis (pixel area integration).
    rng : int or Generator, optional
        Seed of the noise.

    Returns
    -------
    ndarray, shape (height, width), uint8
    """
    return render_boards([board], K, dist, [target2cam], size, conditions,
                         supersample=supersample, rng=rng)


def render_boards(
    boards: Sequence[Board],
    K: Array,
    dist: Array | None,
    target2cam: Sequence[Array],
    size: tuple[int, int],
    conditions: ImageConditions | None = None,
    *,
    supersample: int = 3,
    rng: int | np.random.Generator | None = None,
) -> NDArray[np.uint8]:
    """One 8-bit grey image of several boards at their poses `target2cam` (a rig's image:
    two boards on two arms, boards of one cell); where they overlap the nearer one hides
    the other. Parameters as `render_board`, one pose ``(4, 4)`` per board."""
    cv2 = require_cv2()
    K, d8 = check_camera(K, dist)
    cond = conditions or ImageConditions()
    rng = np.random.default_rng(rng)
    W, H = int(size[0]), int(size[1])
    ss = int(supersample)
    if W < 8 or H < 8 or ss < 1:
        raise InputError(f"image size {W}x{H} / supersample {ss}: expected >= 8 px and >= 1")
    if len(boards) != len(target2cam):
        raise InputError(f"{len(boards)} boards but {len(target2cam)} poses")
    fine = np.full((H * ss, W * ss), float(cond.background), np.float32)
    depth = np.full((H * ss, W * ss), np.inf)
    for board, T in zip(boards, target2cam, strict=True):
        _paint(fine, depth, board, K, d8, np.asarray(T, dtype=float), W, H, ss,
               float(cond.background))
    img = cv2.resize(fine, (W, H), interpolation=cv2.INTER_AREA) if ss > 1 else fine
    return _finish(img.astype(np.float64), cond, W, H, rng)


def _paint(fine: NDArray[np.float32], depth: Array, board: Board, K: Array, d8: Array,
           T: Array, W: int, H: int, ss: int, background: float) -> None:
    """Draw `board` at pose `T` into the supersampled image `fine` where it is nearer than
    `depth` (the ray parameter of what is drawn there), updating `depth`."""
    cv2 = require_cv2()
    R, t = T[:3, :3], T[:3, 3]
    # texture resolution: ~1.2 texels per fine pixel at the nearest corner
    z_near = float(np.min((board.object_points @ R.T + t)[:, 2]))
    if z_near <= 0:
        z_near = float(abs(t[2])) or 1.0
    ppu = min(1.2 * ss * K[0, 0] / z_near, 5000.0 / max(np.ptp(board.extent()), 1e-9))
    # texels per pitch, rounded up to a quarter octave (a few cached textures per board)
    per_pitch = round(float(2.0 ** (np.ceil(4.0 * np.log2(max(board.pitch * ppu, 4.0))) / 4.0)))
    albedo_tex, A = _albedo_texture(board, per_pitch)
    win = _board_window(board, A, albedo_tex.shape, K, d8, R, t, W, H)
    if win is None:
        return
    i0, i1, j0, j1 = (w * ss for w in win)
    # fine pixel centres of the window (final image coordinates)
    us = (np.arange(j0, j1) + 0.5) / ss - 0.5
    vs = (np.arange(i0, i1) + 0.5) / ss - 0.5
    x, y = _ray_grid(us, vs, ss, K, d8)
    # the ray (x, y, 1) meets the board plane n . p = n . t at lambda = n.t / n.(x, y, 1);
    # that point's board coordinates are R^T (lambda (x, y, 1) - t)
    n = R[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = (n @ t) / (n[0] * x + n[1] * y + n[2])
    front = np.isfinite(lam) & (lam > 0)
    lam = np.where(front, lam, 0.0)
    bt = R.T @ t
    mx = A[0, 0] * (lam * (R[0, 0] * x + R[1, 0] * y + R[2, 0]) - bt[0]) + A[0, 2]
    my = A[1, 1] * (lam * (R[0, 1] * x + R[1, 1] * y + R[2, 1]) - bt[1]) + A[1, 2]
    h, w = albedo_tex.shape[:2]
    on = front & (mx > -0.5) & (mx < w - 0.5) & (my > -0.5) & (my < h - 0.5)
    mx = np.where(front, mx, -1e6).astype(np.float32)
    my = np.where(front, my, -1e6).astype(np.float32)
    if board.faces * (n @ t) <= 0:  # the printed side faces away: the plain back
        tex = np.full_like(albedo_tex, 200.0)
    else:
        tex = albedo_tex
    drawn = cv2.remap(tex, mx, my, interpolation=cv2.INTER_LINEAR,
                      borderMode=cv2.BORDER_CONSTANT, borderValue=background)
    view = fine[i0:i1, j0:j1]
    near = depth[i0:i1, j0:j1]
    if np.isinf(near).all():  # nothing drawn here yet: the whole window, as one board
        view[...] = drawn
        near[on] = lam[on]
        return
    take = on & (lam < near)
    view[take] = drawn[take]
    near[take] = lam[take]


def _finish(img: Array, cond: ImageConditions, W: int, H: int,
            rng: np.random.Generator) -> NDArray[np.uint8]:
    """Illumination, blur, noise and quantisation of the integrated image (module
    docstring)."""
    cv2 = require_cv2()
    # illumination
    u = (np.arange(W) - 0.5 * (W - 1)) / W
    v = (np.arange(H) - 0.5 * (H - 1)) / H
    gx, gy = cond.gradient
    light = cond.gain * (1.0 + gx * u[None, :] + gy * v[:, None])
    if cond.vignetting:
        r2 = (u[None, :] ** 2 + v[:, None] ** 2) / 0.5
        light = light * (1.0 - cond.vignetting * r2)
    img = img * light + cond.offset
    if cond.blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), sigmaX=float(cond.blur), sigmaY=float(cond.blur),
                               borderType=cv2.BORDER_REFLECT)
    if cond.noise > 0 or cond.shot > 0:
        var = cond.noise**2 + cond.shot * np.clip(img, 0.0, None)
        img = img + rng.standard_normal(img.shape) * np.sqrt(var)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


@functools.lru_cache(maxsize=6)
def _albedo_texture(board: Board, per_pitch: int) -> tuple[NDArray[np.float32], Array]:
    """Albedo image (float32) of the board's texture at `per_pitch` texels per pitch
    (cached: consecutive renders of one board reuse it)."""
    tex, A = board.texture(per_pitch / board.pitch)
    tex = (_BLACK + (_WHITE - _BLACK) * (tex.astype(np.float32) / 255.0)).astype(np.float32)
    tex.setflags(write=False)
    return tex, A


def _board_window(board: Board, A: Array, tex_shape: tuple[int, ...], K: Array, d8: Array,
                  R: Array, t: Array, W: int, H: int) -> tuple[int, int, int, int] | None:
    """Rows ``i0:i1`` and columns ``j0:j1`` of the image that can show the board texture
    (its outline densely projected, 2 px margin); the whole image when part of the texture
    lies behind the camera; None when none of it is in view."""
    h, w = tex_shape[:2]
    s = np.linspace(0.0, 1.0, 65)
    edge = np.concatenate([np.column_stack([s * (w - 1), np.zeros_like(s)]),
                           np.column_stack([s * (w - 1), np.full_like(s, h - 1.0)]),
                           np.column_stack([np.zeros_like(s), s * (h - 1)]),
                           np.column_stack([np.full_like(s, w - 1.0), s * (h - 1)])])
    bx = (edge[:, 0] - A[0, 2]) / A[0, 0]
    by = (edge[:, 1] - A[1, 2]) / A[1, 1]
    P = np.column_stack([bx, by, np.zeros_like(bx)]) @ R.T + t
    if np.any(P[:, 2] <= 1e-9 * np.abs(P).max()):
        return 0, H, 0, W
    uv = project(K, d8, P)
    if not np.all(np.isfinite(uv)):
        return 0, H, 0, W
    j0 = max(int(np.floor(uv[:, 0].min())) - 2, 0)
    j1 = min(int(np.ceil(uv[:, 0].max())) + 3, W)
    i0 = max(int(np.floor(uv[:, 1].min())) - 2, 0)
    i1 = min(int(np.ceil(uv[:, 1].max())) + 3, H)
    if j0 >= j1 or i0 >= i1:
        return None
    return i0, i1, j0, j1


def _ray_grid(us: Array, vs: Array, ss: int, K: Array, d8: Array) -> tuple[Array, Array]:
    """Normalised undistorted ray coordinates ``x, y`` ``(len(vs), len(us))`` of the pixel
    positions ``us`` (columns) and ``vs`` (rows), spaced ``1 / ss`` apart.

    Without distortion the map is linear. With distortion, its smooth correction to the
    linear map is computed exactly (`undistort_normalized`) on knots every 4 samples and
    interpolated bilinearly (float32 ``cv2.resize``; the correction varies slowly: the
    interpolation error is below 1e-4 px for real lenses)."""
    h, w = len(vs), len(us)
    y_lin = ((vs - K[1, 2]) / K[1, 1])[:, None]
    x_lin = (us[None, :] - K[0, 2] - K[0, 1] * y_lin) / K[0, 0]
    y_lin = np.broadcast_to(y_lin, (h, w))
    if not np.any(d8):
        return x_lin, np.array(y_lin)
    cv2 = require_cv2()
    step = 4
    # knots at sample index 4k + 1.5, k = -1 ..: cv2.resize by 4 puts them where they belong
    nh, nw = h // step + 3, w // step + 3
    ki = vs[0] + (step * np.arange(-1, nh - 1) + 1.5) / ss
    kj = us[0] + (step * np.arange(-1, nw - 1) + 1.5) / ss
    ku, kv = np.meshgrid(kj, ki)
    g = np.column_stack([ku.ravel(), kv.ravel()])
    ky = (g[:, 1] - K[1, 2]) / K[1, 1]
    kx = (g[:, 0] - K[0, 2] - K[0, 1] * ky) / K[0, 0]
    corr = undistort_normalized(g, K, d8) - np.column_stack([kx, ky])
    corr = corr.reshape(nh, nw, 2).astype(np.float32)
    fine = cv2.resize(corr, (nw * step, nh * step), interpolation=cv2.INTER_LINEAR)
    fine = fine[step: step + h, step: step + w].astype(np.float64)
    return x_lin + fine[..., 0], y_lin + fine[..., 1]
