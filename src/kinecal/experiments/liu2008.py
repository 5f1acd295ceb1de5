"""``kinecal reproduce liu2008``: Liu, Liu and Wei (2008), parallel-link CMM.

Reproduces Table 3 (probe pose from the legs 0.750 ... 0.850 m of the Table 2 machine)
with the exact Newton solver and with the paper's PSO (Table 1 settings, several seeds:
success rate within the paper's 0.5 um, generations, time; the paper reports about 55
generations and 3 s), then what the paper does not: every real assembly mode of those
legs, the IK -> FK round trip over random workspace poses, and a 42-parameter geometry
calibration on simulated data.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from kinecal.kinematics.stewart.platform import (
    StewartPlatform,
    degrees_to_radians,
    radians_to_degrees,
)

__all__ = ["PAPER", "render", "run"]

#: Liu, Liu and Wei (2008), Table 3 and sec. 4
PAPER = {
    "legs": [0.750, 0.780, 0.800, 0.900, 0.870, 0.850],
    "pose": [0.039860, 0.095930, 0.925235, -12.697325, 6.403095, 15.133206],
    "iterations": 55,
    "seconds": 3.0,
    "precision_m": 0.5e-6,
}
NAMES = ("x_s [m]", "y_s [m]", "z_s [m]", "alpha [deg]", "beta [deg]", "gamma [deg]")


def _pso_study(geom: StewartPlatform, legs: np.ndarray, exact: np.ndarray, seeds: list[int]):
    errs, its, secs, rot = [], [], [], []
    first = None
    for s in seeds:
        res = geom.forward(legs, method="pso", rng=s, on_failure="flag")
        if first is None:
            first = res
        errs.append(float(np.linalg.norm(res.poses[0, :3] - exact[:3])))
        rot.append(float(np.rad2deg(np.abs(res.poses[0, 3:] - exact[3:]).max())))
        its.append(int(res.iterations[0]))
        secs.append(res.elapsed)
    errs_a = np.array(errs)
    hits = errs_a <= PAPER["precision_m"]
    return first, {
        "seeds": len(seeds),
        "success": int(hits.sum()),
        "success_rate": float(hits.mean()),
        "iterations_median": float(np.median(its)),
        "iterations_mean": float(np.mean(its)),
        "iterations_min": int(np.min(its)),
        "iterations_max": int(np.max(its)),
        "iterations_successful_mean": float(np.mean(np.array(its)[hits])) if hits.any() else None,
        "seconds_mean": float(np.mean(secs)),
        "position_error_median_m": float(np.median(errs_a)),
        "position_error_max_m": float(errs_a.max()),
        "angle_error_median_deg": float(np.median(rot)),
    }


def _calibration_study(geom: StewartPlatform, seed: int, n_val: int) -> dict:
    from kinecal.calibration.stewart.calibrate import calibrate_stewart
    from kinecal.calibration.stewart.data import perturb_geometry, simulate_stewart
    from kinecal.calibration.stewart.result import pose_prediction_errors

    rng = np.random.default_rng(seed)
    true = perturb_geometry(geom, 1e-3, rng)
    cal = simulate_stewart(true, 60, rng=rng)
    val = simulate_stewart(true, n_val, rng=rng)
    res = calibrate_stewart(geom, cal, validate=val)
    pred = res.geometry.inverse(val.true_poses) - val.true_legs
    before = pose_prediction_errors(geom, val.true_legs, val.true_poses)
    after = pose_prediction_errors(res.geometry, val.true_legs, val.true_poses)
    return {
        "poses": 60,
        "validation_poses": n_val,
        "errors": "U(-1, 1) mm on all 42 parameters",
        "noise": "1 um tip position, 1 arcsec orientation, 1 um legs",
        "rank": res.rank,
        "condition_number": res.condition_number,
        "leg_rms_before_m": res.validation["before"]["rms"],
        "leg_rms_after_m": res.validation["after"]["rms"],
        "leg_prediction_rms_m": float(np.sqrt(np.mean(pred**2))),
        "position_rms_before_m": before["position"]["rms"],
        "position_rms_after_m": after["position"]["rms"],
        "rotation_rms_before_arcsec": before["rotation_arcsec"]["rms"],
        "rotation_rms_after_arcsec": after["rotation_arcsec"]["rms"],
        "parameter_error_max_m": float(np.abs(res.geometry.parameters - true.parameters).max()),
        "iterations": res.iterations,
    }


def run(
    quick: bool = False, seed: int = 0, out_dir: str | Path | None = None, quiet: bool = True
) -> dict:
    """Run the Liu, Liu and Wei (2008) experiment (quick: 10 PSO seeds, 200 round-trip poses).

    Returns
    -------
    dict
        ``paper``, ``rows`` (Table 3: paper, newton, pso per quantity; lengths in m, angles
        in deg), ``pso`` statistics, ``newton`` timing, ``modes``, ``round_trip`` and
        ``calibration`` summaries.
    """
    from kinecal.cli._common import progress

    geom = StewartPlatform.liu2008()
    legs = np.array(PAPER["legs"])
    n_seeds = 10 if quick else 30
    n_trip = 200 if quick else 1000
    with progress("liu2008", 4, quiet) as update:
        newton = geom.forward(legs)
        t0 = time.perf_counter()
        for _ in range(20):  # single-solve latency, after the first (import) call
            geom.forward(legs)
        t_newton = (time.perf_counter() - t0) / 20
        exact = newton.poses[0]
        seeds = [seed + k for k in range(n_seeds)]
        first, pso = _pso_study(geom, legs, exact, seeds)
        update()
        modes = geom.forward_all(legs, rng=seed)
        update()
        poses = geom.random_poses(n_trip, rng=seed)
        t0 = time.perf_counter()
        back = geom.forward(geom.inverse(poses), on_failure="flag")
        t_trip = time.perf_counter() - t0
        update()
        calib = _calibration_study(geom, seed, 100 if quick else 500)
        update()
    nd, pd = radians_to_degrees(exact), radians_to_degrees(first.poses[0])
    rows = [
        {"quantity": NAMES[k], "paper": PAPER["pose"][k], "newton": float(nd[k]),
         "pso": float(pd[k]), "newton_minus_paper": float(nd[k] - PAPER["pose"][k])}
        for k in range(6)
    ]  # fmt: skip
    printed = degrees_to_radians(PAPER["pose"])
    result = {
        "paper": "liu2008",
        "source": "Liu, Liu and Wei (2008), Table 3",
        "units": "m and deg",
        "legs": PAPER["legs"],
        "rows": rows,
        "printed_pose_legs_error_m": float(np.abs(geom.inverse(printed) - legs).max()),
        "newton": {
            "iterations": int(newton.iterations[0]),
            "residual_m": float(newton.residual[0]),
            "seconds": t_newton,
        },
        "pso": {
            **pso,
            "seed_shown": seed,
            "paper_iterations": 55,
            "paper_seconds": 3.0,
            "history_first_seed": first.history[0].tolist(),
        },
        "modes": {
            "total": len(modes),
            "above_base": int(modes.above.sum()),
            "below_base": int((~modes.above).sum()),
            "starts": modes.n_starts,
            "poses_deg": radians_to_degrees(modes.poses).tolist(),
            "above": modes.above.tolist(),
            "max_residual_m": float(modes.residual.max()),
        },
        "round_trip": {
            "poses": n_trip,
            "converged": int(back.converged.sum()),
            "max_position_error_m": float(np.abs(back.poses[:, :3] - poses[:, :3]).max()),
            "max_angle_error_deg": float(
                np.rad2deg(np.abs(back.poses[:, 3:] - poses[:, 3:]).max())
            ),
            "seconds": t_trip,
        },
        "calibration": calib,
    }
    if out_dir is not None:
        _figure(result, Path(out_dir))
    return result


def _figure(result: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from kinecal._files import atomic_open

    out.mkdir(parents=True, exist_ok=True)
    h = np.maximum(np.array(result["pso"]["history_first_seed"]), 1e-16)
    fig, ax = plt.subplots(figsize=(5, 3.2))
    ax.semilogy(np.arange(h.size), h * 1e6)
    ax.axhline(0.5, ls="--", color="gray", label="0.5 um (Liu, Liu and Wei 2008)")
    ax.set_xlabel("generation")
    ax.set_ylabel("eq. 6: sum |l_i - l'_i| [um]")
    ax.set_title("PSO on the Table 3 legs (cf. Liu, Liu and Wei (2008), Fig. 4b)")
    ax.legend()
    fig.tight_layout()
    with atomic_open(out / "liu2008_pso.png", "wb", encoding=None) as fh:
        fig.savefig(fh, format="png", dpi=120)
    plt.close(fig)


def _ms(seconds: float | None, digits: int) -> str:
    """A time in milliseconds; ``-`` when left out (``SOURCE_DATE_EPOCH``: no times)."""
    return "- ms" if seconds is None else f"{seconds * 1e3:.{digits}f} ms"


def render(result: dict) -> str:
    """Table 3 beside kinecal's newton and PSO, then the PSO statistics and the extras."""
    lines = [
        "Liu, Liu and Wei (2008), Table 3: legs "
        + ", ".join(f"{v:.3f}" for v in result["legs"]) + " m",
        f"{'':12s} {'paper':>14s} {'newton':>16s} {'pso (seed)':>16s} {'newton-paper':>13s}",
    ]
    for r in result["rows"]:
        lines.append(
            f"{r['quantity']:12s} {r['paper']:14.6f} {r['newton']:16.9f} {r['pso']:16.9f} "
            f"{r['newton_minus_paper']:13.2e}"
        )
    nw, ps = result["newton"], result["pso"]
    lines += [
        f"newton: {nw['iterations']} iterations, residual {nw['residual_m']:.1e} m, "
        f"{_ms(nw['seconds'], 2)}",
        f"pso ({ps['seeds']} seeds, 80 particles, w 0.5->0.1, c1=c2=1.8): "
        f"{ps['success']}/{ps['seeds']} within 0.5 um (median tip error "
        f"{ps['position_error_median_m'] * 1e6:.2f} um, angles {ps['angle_error_median_deg']:.1e} "
        f"deg); generations median "
        f"{ps['iterations_median']:.0f} (min {ps['iterations_min']}, max {ps['iterations_max']}; "
        f"paper ~55); {_ms(ps['seconds_mean'], 1)} per solve (paper ~3 s, Java on a P4)",
    ]
    m = result["modes"]
    lines.append(
        f"assembly modes: {m['total']} real ({m['above_base']} above the base, "
        f"{m['below_base']} mirror images below), {m['starts']} Newton starts"
    )
    for k, (p, a) in enumerate(zip(m["poses_deg"], m["above"], strict=True)):
        if a:
            lines.append(
                f"  mode {k + 1}: " + " ".join(f"{v:10.5f}" for v in p)
                + ("   <- Table 3" if k == 0 else "")
            )  # fmt: skip
    rt = result["round_trip"]
    lines.append(
        f"IK -> FK round trip: {rt['converged']}/{rt['poses']} poses, max error "
        f"{rt['max_position_error_m']:.1e} m, {rt['max_angle_error_deg']:.1e} deg"
    )
    c = result["calibration"]
    lines.append(
        f"calibration (42 parameters, {c['errors']}; {c['noise']}): rank {c['rank']}, "
        f"validation legs rms {c['leg_rms_before_m'] * 1e6:.1f} -> "
        f"{c['leg_rms_after_m'] * 1e6:.2f} um (vs noise-free legs "
        f"{c['leg_prediction_rms_m'] * 1e6:.2f} um); tip position rms "
        f"{c['position_rms_before_m'] * 1e6:.0f} -> "
        f"{c['position_rms_after_m'] * 1e6:.2f} um"
    )
    return "\n".join(lines)
