"""Reproduction of Li, Xiao, Lai and Hu (2024): ``kinecal reproduce li2024``.

Synthetic eye-in-hand set-up in millimetres; the paper's experiments are on a real robot
whose noise it does not state, so kinecal simulates one (`NOISE_MODEL`) and compares the
relative changes the paper reports:

- experiment 1 (sec. 5.1, Table 1): 19 random poses vs 19 poses of the star-polygon
  scheme (``|Pc|`` = 380 mm, r = 60 mm), analytic Tsai, Park, Horaud, Daniilidis on
  consecutive station pairs (paper eq. (2)); paper: rotation error -74 %, translation
  error -92 % with the scheme;
- experiments 2-4 (figs. 4-6): sweeps of N, r and ``|Pc|`` with the scheme;
- refinement (sec. 5.2, fig. 7): the Tsai solution of experiment 1's scheme refined by
  IGWO and DLH-GWO-DE (`kinecal.optimize.minimize`) and by kinecal's LM; paper:
  DLH-GWO-DE converges faster and lower than IGWO, error a further ~19 % lower.

Random poses: positions uniform in the same disc (radius r, height ``|Pc|``), camera
looking at the target centre with no roll ("the arm end moved to random positions"); a
variant with a random roll of +-180 deg is reported beside it.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from kinecal.calibration.handeye import calibrate_handeye, solve
from kinecal.calibration.handeye.errors import pose_error
from kinecal.calibration.handeye.poses import random_poses, star_polygon_poses
from kinecal.calibration.handeye.refine_meta import metaheuristic
from kinecal.spatial import (
    invert_transform,
    matrix_from_axis_angle,
    matrix_from_rpy,
    transform_from,
)

__all__ = ["NOISE_MODEL", "assemble", "experiment1", "refinement", "render", "run", "sweeps"]

PAPER = "li2024"
SOURCE = "Li, Xiao, Lai and Hu (2024)"
NOISE_MODEL = (
    "target2cam perturbed by a rotation vector with N(0, 0.1 deg) per component and a "
    "translation with N(0, 0.5 mm) per component (target frame); flange2base by N(0, 0.02 "
    "deg) and N(0, 0.1 mm) (flange frame); independent per station"
)
METHODS = ("tsai", "park", "horaud", "daniilidis")
X_TRUE = transform_from(matrix_from_rpy([0.02, -0.03, np.pi / 2]), [0.0, 60.0, 90.0])
Y_TRUE = transform_from(matrix_from_rpy([0.0, 0.0, 0.2]), [650.0, 50.0, 0.0])


def _measure(cam2target: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Noisy (flange2base, target2cam) for planned camera poses (see `NOISE_MODEL`)."""
    n = len(cam2target)
    C = invert_transform(cam2target)
    G = Y_TRUE @ cam2target @ invert_transform(X_TRUE)
    C = C @ transform_from(matrix_from_axis_angle(rng.normal(size=(n, 3)) * np.radians(0.1)),
                           rng.normal(size=(n, 3)) * 0.5)
    G = G @ transform_from(matrix_from_axis_angle(rng.normal(size=(n, 3)) * np.radians(0.02)),
                           rng.normal(size=(n, 3)) * 0.1)
    return G, C


def _errors(G: np.ndarray, C: np.ndarray) -> dict[str, tuple[float, float]]:
    out = {}
    for m in METHODS:
        out[m] = pose_error(solve(G, C, m, "consecutive")[0], X_TRUE)
    return out


def _mean_errors(make_poses, trials: int, rng: np.random.Generator) -> dict[str, list[float]]:
    acc = {m: [] for m in METHODS}
    for _ in range(trials):
        G, C = _measure(make_poses(), rng)
        for m, e in _errors(G, C).items():
            acc[m].append(e)
    return {m: np.mean(v, axis=0).tolist() for m, v in acc.items()}


def experiment1(trials: int, rng: np.random.Generator) -> dict[str, Any]:
    """Random vs scheme poses (N = 19, |Pc| = 380 mm, r = 60 mm), mean errors per method."""
    star = star_polygon_poses(380.0, 60.0, 19)
    res = {
        "random": _mean_errors(lambda: random_poses(380.0, 60.0, 19, rng, roll=0.0), trials, rng),
        "random_roll": _mean_errors(lambda: random_poses(380.0, 60.0, 19, rng), trials, rng),
        "scheme": _mean_errors(lambda: star, trials, rng),
    }
    for ref in ("random", "random_roll"):
        rot = [1 - res["scheme"][m][0] / res[ref][m][0] for m in METHODS]
        tr = [1 - res["scheme"][m][1] / res[ref][m][1] for m in METHODS]
        res[f"reduction_vs_{ref}"] = {"rotation_percent": 100 * float(np.mean(rot)),
                                      "translation_percent": 100 * float(np.mean(tr))}
    return res


def sweeps(trials: int, rng: np.random.Generator, quick: bool) -> dict[str, Any]:
    """Experiments 2-4: mean Tsai/Park/Horaud/Daniilidis errors along N, r and |Pc|."""
    grid = {
        "N": [5, 9, 13, 19] if quick else [5, 7, 9, 11, 13, 15, 17, 19, 21, 25],
        "r": [30.0, 60.0, 120.0] if quick else [20.0, 40.0, 60.0, 80.0, 100.0, 120.0, 150.0],
        "Pc": [250.0, 380.0, 600.0] if quick else [200.0, 300.0, 380.0, 500.0, 600.0, 800.0],
    }
    out: dict[str, Any] = {}
    for var, values in grid.items():
        rows = []
        for v in values:
            n = int(v) if var == "N" else 19
            r = float(v) if var == "r" else 60.0
            d = float(v) if var == "Pc" else 380.0
            star = star_polygon_poses(d, r, n)
            errs = _mean_errors(lambda star=star: star, trials, rng)
            rows.append({"value": v, **{m: errs[m] for m in METHODS}})
        out[var] = rows
    return out


def refinement(trials: int, rng: np.random.Generator, maxiter: int) -> dict[str, Any]:
    """Sec. 5.2: Tsai (scheme, experiment 1) refined by IGWO, DLH-GWO-DE and LM."""
    star = star_polygon_poses(380.0, 60.0, 19)
    names = ("tsai", "igwo", "dlh-gwo-de", "lm")
    err = {k: [] for k in names}
    fit = {k: [] for k in ("tsai", "igwo", "dlh-gwo-de")}
    hist: dict[str, list[float]] = {}
    nfev: dict[str, int] = {}
    conv: dict[str, list[int]] = {"igwo": [], "dlh-gwo-de": []}
    for k in range(trials):
        G, C = _measure(star, rng)
        X0, _ = solve(G, C, "tsai", "consecutive")
        err["tsai"].append(pose_error(X0, X_TRUE))
        fit["tsai"].append(_fitness(G, C, X0))
        runs = {}
        for method in ("igwo", "dlh-gwo-de"):
            seed = int(rng.integers(2**31))
            r = metaheuristic(G, C, X0, method, rng=seed, pairs="consecutive", maxiter=maxiter)
            err[method].append(pose_error(r.X, X_TRUE))
            fit[method].append(r.fun)
            runs[method] = r.history
            if k == 0:
                hist[method] = r.history
                nfev[method] = r.nfev
        # iterations to reach 99 % of the improvement the better of the two achieved
        best = min(h[-1] for h in runs.values())
        for method, h in runs.items():
            goal = best + 0.01 * (h[0] - best)
            conv[method].append(int(np.argmax(np.asarray(h) <= goal)) if h[-1] <= goal
                                else len(h))
        lm = calibrate_handeye(G, C, method="tsai", refine="lm", pairs="consecutive")
        err["lm"].append(pose_error(lm.X, X_TRUE))
    mean_err = {k: np.mean(v, axis=0).tolist() for k, v in err.items()}
    mean_fit = {k: float(np.mean(v)) for k, v in fit.items()}
    change = {k: {"rotation_percent": 100 * (mean_err[k][0] / mean_err["tsai"][0] - 1),
                  "translation_percent": 100 * (mean_err[k][1] / mean_err["tsai"][1] - 1)}
              for k in ("igwo", "dlh-gwo-de", "lm")}
    return {"errors": mean_err, "fitness": mean_fit, "change_vs_tsai": change,
            "iterations_to_99_percent": {m: float(np.median(v)) for m, v in conv.items()},
            "history": hist, "nfev_first_trial": nfev, "maxiter": maxiter}


def _fitness(G: np.ndarray, C: np.ndarray, X: np.ndarray) -> float:
    """The paper's fitness (`refine_meta.axxb_fitness`, consecutive pairs) of one X."""
    from kinecal.calibration.handeye._motions import motion_pairs
    from kinecal.calibration.handeye.refine_meta import axxb_fitness
    from kinecal.spatial import quaternion_from_matrix

    A, B = motion_pairs(G, C, "consecutive")
    dist = float(np.sqrt(np.mean(np.sum(C[:, :3, 3] ** 2, axis=1))))
    x = np.concatenate([quaternion_from_matrix(X[:3, :3]), X[:3, 3]])
    return float(axxb_fitness(A, B, dist)(x[None])[0])


def _figures(result: dict[str, Any], out_dir: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from kinecal._files import write_bytes_atomic

    out_dir.mkdir(parents=True, exist_ok=True)
    files = []
    labels = {"N": "number of poses N", "r": "radius r (mm)", "Pc": "|Pc| (mm)"}
    for fig_no, var in zip((4, 5, 6), ("N", "r", "Pc"), strict=True):
        rows = result["sweeps"][var]
        fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
        for m in METHODS:
            x = [row["value"] for row in rows]
            ax[0].plot(x, [row[m][0] for row in rows], marker="o", label=m)
            ax[1].plot(x, [row[m][1] for row in rows], marker="o", label=m)
        ax[0].set_ylabel("rotation error (deg)")
        ax[1].set_ylabel("translation error (mm)")
        for a in ax:
            a.set_xlabel(labels[var])
            a.set_yscale("log")
            a.legend()
        fig.suptitle(f"li2024 experiment {fig_no - 2} (paper fig. {fig_no})")
        fig.tight_layout()
        files.append(_save(fig, out_dir / f"li2024_fig{fig_no}_{var}.png", write_bytes_atomic))
        plt.close(fig)
    fig, ax = plt.subplots(figsize=(5, 3.5))
    for m, h in result["refinement"]["history"].items():
        ax.semilogy(h, label=m)
    ax.set_xlabel("iteration")
    ax.set_ylabel("fitness (best of the pack)")
    ax.set_title("li2024 refinement (paper fig. 7)")
    ax.legend()
    fig.tight_layout()
    files.append(_save(fig, out_dir / "li2024_fig7_convergence.png", write_bytes_atomic))
    plt.close(fig)
    return files


def _save(fig, path: Path, writer) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    writer(path, buf.getvalue())
    return str(path)


def run(quick: bool = False, seed: int = 0, out_dir: str | Path | None = None,
        quiet: bool = True) -> dict[str, Any]:
    """Run experiments 1-4 and the refinement comparison of Li, Xiao, Lai and Hu (2024).

    Parameters
    ----------
    quick : bool
        Fewer trials and sweep points (well under a minute).
    seed : int
        Seed of `numpy.random.default_rng`; the same seed gives the same result.
    out_dir : str or Path, optional
        Where the figures (PNG) go.
    quiet : bool
        Unused (no progress output).

    Returns
    -------
    dict
        JSON-able: ``paper``, ``source``, ``noise_model``, ``units``, ``rows`` (the paper's
        numbers beside kinecal's), ``experiment1``, ``sweeps``, ``refinement``.
    """
    rng = np.random.default_rng(seed)
    trials = 10 if quick else 100
    e1 = experiment1(trials, rng)
    sw = sweeps(4 if quick else 40, rng, quick)
    rf = refinement(2 if quick else 10, rng, 60 if quick else 200)
    result = assemble(e1, sw, rf, trials, seed)
    if out_dir is not None:
        result["figures"] = _figures(result, Path(out_dir))
    return result


def assemble(e1: dict[str, Any], sw: dict[str, Any], rf: dict[str, Any], trials: int,
             seed: int) -> dict[str, Any]:
    """The result dict of `run` from the outputs of `experiment1`, `sweeps`, `refinement`."""
    red = e1["reduction_vs_random"]
    rows = [
        {"experiment": "1 (N=19, |Pc|=380, r=60)", "quantity": "rotation error, scheme vs random",
         "paper": "-74 %", "kinecal": f"{-red['rotation_percent']:+.0f} %"},
        {"experiment": "1", "quantity": "translation error, scheme vs random",
         "paper": "-92 %", "kinecal": f"{-red['translation_percent']:+.0f} %"},
    ]
    for m in ("igwo", "dlh-gwo-de", "lm"):
        c = rf["change_vs_tsai"][m]
        change = f"{c['rotation_percent']:+.0f} % / {c['translation_percent']:+.0f} %"
        rows.append({"experiment": "refinement",
                     "quantity": f"{m} vs Tsai: rotation / translation",
                     "paper": "about -19 % (DLH-GWO-DE)" if m == "dlh-gwo-de" else "-",
                     "kinecal": change})
    it = rf["iterations_to_99_percent"]
    rows.append({"experiment": "refinement",
                 "quantity": "iterations to 99 % of the gain (median), IGWO / DLH-GWO-DE",
                 "paper": "DLH-GWO-DE faster", "kinecal":
                 " / ".join(f"{it[m]:g}" if it[m] <= rf["maxiter"] else f"> {rf['maxiter']}"
                            for m in ("igwo", "dlh-gwo-de"))})
    f = rf["fitness"]
    rows.append({"experiment": "refinement", "quantity": "final fitness DLH-GWO-DE vs IGWO",
                 "paper": "DLH-GWO-DE lower", "kinecal":
                 f"{100 * (f['dlh-gwo-de'] / f['igwo'] - 1):+.2f} %"})
    result = {"paper": PAPER, "source": SOURCE, "noise_model": NOISE_MODEL,
              "units": {"rotation": "deg (geodesic)", "translation": "mm"},
              "trials": trials, "seed": seed, "rows": rows, "experiment1": e1, "sweeps": sw,
              "refinement": rf}
    return result


def render(result: dict[str, Any]) -> str:
    """The paper's numbers beside kinecal's, then the experiment tables, as text."""
    lines = [f"li2024 ({result['source']}): hand-eye pose scheme and DLH-GWO-DE refinement",
             f"noise model: {result['noise_model']}", ""]
    w = max(len(r["quantity"]) for r in result["rows"])
    lines.append(f"{'experiment':<26} {'quantity':<{w}}  {'paper':<26} kinecal")
    for r in result["rows"]:
        lines.append(f"{r['experiment']:<26} {r['quantity']:<{w}}  {r['paper']:<26} "
                     f"{r['kinecal']}")
    e1 = result["experiment1"]
    lines += ["", f"experiment 1: mean errors over {result['trials']} trials "
              "(rotation deg / translation mm), consecutive pairs"]
    lines.append(f"{'method':<12} {'random':>18} {'random + roll':>18} {'scheme':>18}")
    for m in METHODS:
        cells = [f"{e1[k][m][0]:.4f} / {e1[k][m][1]:.3f}" for k in ("random", "random_roll",
                                                                     "scheme")]
        lines.append(f"{m:<12} " + " ".join(f"{c:>18}" for c in cells))
    rr = e1["reduction_vs_random_roll"]
    lines.append(f"(scheme vs random with roll: rotation {-rr['rotation_percent']:+.0f} %, "
                 f"translation {-rr['translation_percent']:+.0f} %)")
    for var, title in (("N", "experiment 2: N"), ("r", "experiment 3: r (mm)"),
                       ("Pc", "experiment 4: |Pc| (mm)")):
        lines += ["", f"{title}, Tsai rotation deg / translation mm (park, horaud, daniilidis "
                  "in the JSON)"]
        lines.append("  ".join(f"{row['value']:g}: {row['tsai'][0]:.4f}/{row['tsai'][1]:.3f}"
                               for row in result["sweeps"][var]))
    rf = result["refinement"]
    lines += ["", f"refinement (mean over trials, {rf['maxiter']} iterations; DLH-GWO-DE "
              f"evaluates 4 x popsize points per iteration, IGWO 2 x; first trial: "
              f"{rf['nfev_first_trial']}): rotation deg / translation mm / fitness"]
    for k in ("tsai", "igwo", "dlh-gwo-de", "lm"):
        e = rf["errors"][k]
        fit = rf["fitness"].get(k)
        lines.append(f"{k:<12} {e[0]:.4f} / {e[1]:.3f}" + (f" / {fit:.4e}" if fit else ""))
    if result.get("figures"):
        lines += ["", "figures: " + ", ".join(result["figures"])]
    return "\n".join(lines)
