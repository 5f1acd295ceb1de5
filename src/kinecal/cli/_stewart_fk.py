"""The body of ``kinecal stewart fk``, free of typer: `kinecal.cli._direct` runs it
without building the typer command (its options: `kinecal.cli.stewart.fk`)."""

from __future__ import annotations

import sys

import numpy as np

from kinecal.cli._common import echo_json, resolve_data_path, warnings_scope, with_warnings
from kinecal.cli._csv_out import format_rows, write_columns, write_csv
from kinecal.cli._stewart_io import LEG_COLUMNS, POSE_COLUMNS, load_geometry_arg, read_columns
from kinecal.diagnostics import expect
from kinecal.errors import InputError

__all__ = ["FK_BLOCK", "run_fk"]

#: rows per block of ``stewart fk``: one block solves while the one before is formatted
FK_BLOCK = 16384


def run_fk(geometry: str, legs: str, method: str, all_modes: bool, seed: int, json_out: bool,
           strict: bool) -> None:
    """``kinecal stewart fk`` (the options as in `kinecal.cli.stewart.fk`)."""
    if method not in ("newton", "pso"):
        raise InputError(f"unknown method {method!r}; expected newton or pso", option="--method")
    if all_modes and method != "newton":
        raise InputError("--all finds every assembly mode by multi-start Newton; it does not "
                         f"take --method {method}", option="--method")
    geom = load_geometry_arg(geometry)
    path = str(resolve_data_path(legs, "LEGS"))
    L = read_columns(legs, LEG_COLUMNS, "LEGS")
    with warnings_scope(strict) as found:
        L = geom.check_legs(L, file=path)
        with expect("leg-range"):  # judged once above, not again per solve
            if all_modes:
                _fk_all(geom, L, path, seed, json_out, found)
            else:
                _fk_solve(geom, L, path, method, seed, json_out, found)


def _fk_solve(geom, L: np.ndarray, path: str, method: str, seed: int, json_out: bool,
              found: list) -> None:
    """`stewart fk` after its checks: Newton in blocks (CSV) or one call (PSO, JSON)."""
    from kinecal.kinematics.stewart.platform import radians_to_degrees

    if method == "newton" and not json_out:
        _fk_blocks(geom, L, path)
        return
    # a row without any real solution is an input error, whatever the method
    newton = geom.forward(L, on_failure="flag")
    if not newton.converged.all():
        i = int(np.argmin(newton.converged))
        raise InputError(
            f"leg lengths {np.array2string(L[i], precision=6)} have no real assembly "
            f"(closest residual {newton.residual[i]:.3g})",
            file=path,
            row=i + 1,
        )
    res = newton if method == "newton" else geom.forward(L, "pso", rng=seed, on_failure="flag")
    deg = radians_to_degrees(res.poses)
    if json_out:
        rows = [
            {**dict(zip(POSE_COLUMNS, d, strict=True)), "converged": bool(c), "residual": float(r),
             "iterations": int(k)}
            for d, c, r, k in zip(deg, res.converged, res.residual, res.iterations, strict=True)
        ]  # fmt: skip
        echo_json(with_warnings({"method": method, "elapsed": res.elapsed, "poses": rows},
                                found))
        return
    write_columns([*POSE_COLUMNS, "converged", "residual"],
                   [*deg.T, np.where(res.converged, "true", "false").tolist(), res.residual])


def _fk_blocks(geom, L: np.ndarray, path: str) -> None:
    """Newton forward kinematics as CSV, a block of `FK_BLOCK` rows at a time: a worker
    thread solves the next block while this one formats the last (the solver's numpy work
    runs without the GIL, the float formatting needs it), so that the command's throughput
    approaches the API's. The whole CSV is written only once every row has converged (a
    row without a real solution is an input error; nothing is half-written). The tolerance
    is the one a single call takes over all rows."""
    import contextvars
    from concurrent.futures import ThreadPoolExecutor

    from kinecal.kinematics.stewart.forward import default_tol
    from kinecal.kinematics.stewart.platform import radians_to_degrees

    tol = default_tol(L + geom.leg_offsets)
    blocks = [slice(s, min(s + FK_BLOCK, len(L))) for s in range(0, len(L), FK_BLOCK)]

    def solve(b: slice):
        return geom.forward(L[b], on_failure="flag", options={"tol": tol})

    text = []
    ctx = contextvars.copy_context()  # the worker sees the command's diagnostics scope
    with ThreadPoolExecutor(max_workers=1) as pool:
        pending = pool.submit(ctx.run, solve, blocks[0]) if blocks else None
        for k, b in enumerate(blocks):
            res = pending.result()
            pending = (pool.submit(ctx.run, solve, blocks[k + 1]) if k + 1 < len(blocks)
                       else None)
            if not res.converged.all():
                i = int(np.argmin(res.converged))
                if pending is not None:
                    pending.cancel()
                raise InputError(
                    f"leg lengths {np.array2string(L[b][i], precision=6)} have no real "
                    f"assembly (closest residual {res.residual[i]:.3g})",
                    file=path, row=b.start + i + 1)
            deg = radians_to_degrees(res.poses)
            text.append(format_rows([*deg.T, ["true"] * len(deg), res.residual]))
    sys.stdout.write(",".join([*POSE_COLUMNS, "converged", "residual"]) + "\n")
    sys.stdout.write("".join(text))


def _fk_all(geom, L: np.ndarray, path: str, seed: int, json_out: bool, found: list) -> None:
    from kinecal.kinematics.stewart.platform import radians_to_degrees

    out = []
    for i in range(L.shape[0]):  # one multi-start batch per reading
        modes = geom.forward_all(L[i], rng=seed)
        if len(modes) == 0:
            raise InputError(
                f"leg lengths {np.array2string(L[i], precision=6)} have no real assembly",
                file=path,
                row=i + 1,
            )
        out.append(modes)
    if json_out:
        echo_json(with_warnings(
            {
                "method": "newton-multistart",
                "rows": [
                    {
                        "row": i + 1,
                        "modes": [
                            {**dict(zip(POSE_COLUMNS, d, strict=True)), "above": bool(a),
                             "residual": float(r), "converged": True}
                            for d, a, r in zip(radians_to_degrees(m.poses), m.above, m.residual,
                                               strict=True)
                        ],
                    }
                    for i, m in enumerate(out)
                ],
            },
            found))  # fmt: skip
        return
    header = ["row", "mode", *POSE_COLUMNS, "above", "converged", "residual"]
    rows = []
    for i, m in enumerate(out):
        for k, (d, a, r) in enumerate(
            zip(radians_to_degrees(m.poses), m.above, m.residual, strict=True)
        ):
            rows.append([str(i + 1), str(k + 1), *d.tolist(), str(bool(a)).lower(), "true", r])
    write_csv(header, rows)
