"""Command plumbing for several measurement files of any kinds (docs/measurement-kinds.md):
``calibrate MODEL A.csv B.csv ...``, ``identifiability MODEL --data A.csv --data B.csv``,
``simulate MODEL --kind ballbar|pair|point|plane ...``, known fixtures (``--fixture``). No
command is registered here: `kinecal.cli.calibrate` and `kinecal.cli.simulate` call these
functions, so that their own modules stay small.

``--sigma`` takes, for each file, the stated 1-sigma noise in the model's length unit:
``--sigma A.csv=0.002`` (repeatable, by file name), ``--sigma 0.002,0.01`` (in file order,
empty for none: ``0.002,,0.005``) or one number for every file. A file without a stated
noise uses its ``sigma`` column, else its noise is estimated from the fit (and said so).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import typer

from kinecal._limits import check_finite
from kinecal.cli._common import (
    check_paths,
    echo_json,
    report_record,
    resolve_data_path,
    warnings_scope,
    with_warnings,
)
from kinecal.cli._options import load_model_arg
from kinecal.cli._outputs import write_outputs
from kinecal.errors import InputError

__all__ = ["calibrate_files", "check_fixtures_used", "file_kind", "identifiability_files",
           "parse_sigma", "read_fixtures", "select_kind_file", "simulate_gauge",
           "simulate_kind_file"]


def file_kind(spec: str, option: str = "DATA") -> str:
    """The measurement kind of a CSV argument (`kinecal.io.kinds.kind_of_columns`)."""
    from kinecal.io.kinds import kind_of_columns
    from kinecal.io.measurements import csv_header

    path = resolve_data_path(spec, option)
    return kind_of_columns(csv_header(path), path)


def _number(text: str) -> float | None:
    if not text.strip():
        return None
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{text!r} is not a number: expected FILE=SIGMA, SIGMA or SIGMA,"
                         "SIGMA,... in file order (length unit)", option="--sigma") from None
    check_finite(value, "--sigma", positive=True)
    return value


def parse_sigma(values: list[str] | None, files: list[str]) -> list[float | None]:
    """Stated noise per file from the ``--sigma`` values (module docstring)."""
    out: list[float | None] = [None] * len(files)
    for value in values or []:
        if "=" in value:
            name, _, number = value.rpartition("=")
            hits = [i for i, f in enumerate(files) if f == name or Path(f).name == name]
            if len(hits) != 1:
                what = "is none of" if not hits else "names several of"
                raise InputError(f"{name!r} {what} the files ({', '.join(files)}): expected "
                                 "FILE=SIGMA with FILE one of them", option="--sigma")
            out[hits[0]] = _number(number)
        elif "," in value:
            parts = value.split(",")
            if len(parts) != len(files):
                raise InputError(f"{len(parts)} values for {len(files)} files: expected one "
                                 "per file in file order (empty for none)", option="--sigma")
            out = [_number(p) for p in parts]
        else:
            out = [_number(value)] * len(files)
    return out


def _read_all(m, files: list[str], option: str, fixtures: list | None = None,
              angle_unit: str | None = None, tracker: dict | None = None) -> list:
    """The data sets of `files` (joint columns in `angle_unit`), point and plane sets with
    the known geometry of the `fixtures` (`kinecal.io.fixtures.Fixture`) added by id;
    `tracker`: the tracker options of `kinecal.cli.tracker_options`."""
    from kinecal.cli.tracker_options import per_file_station
    from kinecal.io.fixtures import with_fixture
    from kinecal.io.kinds import read_kind

    tracker = tracker or {}
    sets = [read_kind(resolve_data_path(f, option), m, tracker.get("orientation"),
                      angle_unit=angle_unit) for f in files]
    if fixtures:
        sets = [with_fixture(d, fixtures) if getattr(d, "kind", None) in ("point", "plane")
                else d for d in sets]
    if tracker.get("station_per_file"):
        sets = [per_file_station(d, f) for d, f in zip(sets, files, strict=True)]
    return sets


def read_fixtures(paths: list[Path] | None) -> list:
    """The ``--fixture`` files (`kinecal.io.fixtures.read_fixture`)."""
    from kinecal.io.fixtures import read_fixture

    for p in paths or []:
        if not Path(p).is_file():
            raise InputError(f"{p}: no such file", option="--fixture")
    return [read_fixture(p) for p in paths or []]


def check_fixtures_used(fixtures: list, sets: list) -> None:
    """Refuse a fixture none of whose ids a point or plane file of its kind touches."""
    for f in fixtures:
        ids = {n for d in sets if getattr(d, "kind", None) == f.kind for n in d.group_names}
        if not ids & set(f.values):
            raise InputError(f"{Path(f.source).name}: none of its {f.kind}s "
                             f"({', '.join(list(f.values)[:6])}) is touched by a {f.kind} "
                             "file of the calibration (ids must match)", option="--fixture")


def calibrate_files(model: str, files: list[str], *, base_link, tip_link, validate: list[str],
                    method: str, free, seed: int, loss: str, maxiter, target,
                    out: Path | None, model_out: Path | None, report: Path | None,
                    json_out: bool, quiet: bool, strict: bool, rotation_weight,
                    sigma: list[str] | None, extra_options: dict[str, Any],
                    record: tuple = (None, None, None), unit: str | None = None,
                    fixture: list[Path] | None = None, angle_unit: str | None = None,
                    tracker: dict | None = None, priors: dict | None = None) -> None:
    """``kinecal calibrate MODEL A.csv B.csv ...`` (several files or another kind);
    `record`: ``--instrument``, ``--operator``, ``--note`` of the report; `unit`: the
    summary's length unit (None: the model's); `fixture`: ``--fixture`` files; `tracker`:
    ``--orientation-format``, ``--station-per-file``, ``--validate-register``
    (`kinecal.cli.tracker_options`); `priors`: ``prior`` and ``prior_from`` of
    `kinecal.calibrate`."""
    tracker = tracker or {}
    from kinecal.calibration.diagnostics.noise import check_stated_sigma
    from kinecal.calibration.method_options import check_method_options
    from kinecal.calibration.serial.api import calibrate

    given = [k for k, v in extra_options.items() if v is not None]
    if given:
        raise InputError("applies to one tracker file (x,y,z columns) only, not to "
                         f"{len(files)} files or other kinds", option=given[0])
    inputs = {"MODEL": model, **{f"DATA {f}": f for f in files},
              **{f"--validate {v}": v for v in validate},
              **{f"--fixture {f}": str(f) for f in fixture or []}}
    from kinecal.calibration.serial.prior import prior_file

    priors = priors or {}
    check_paths({**inputs, "--prior-from": priors.get("prior_from"),
                 "--prior": prior_file(priors.get("prior"))},
                {"--out": out, "--model-out": model_out, "--report": report})
    provenance = report_record(report, inputs, *record)
    if model_out is not None:
        from kinecal.io.models import check_model_file_name

        check_model_file_name(model_out, "--model-out")
    check_method_options(method, loss=loss, maxiter=maxiter, target=target)
    check_finite(rotation_weight, "--rotation-weight", positive=True)
    stated = parse_sigma(sigma, files)
    with warnings_scope(strict) as found:
        m = load_model_arg(model, base_link, tip_link)
        for s in stated:
            check_stated_sigma(m, s)
        fixtures = read_fixtures(fixture)
        sets = _read_all(m, files, "DATA", fixtures, angle_unit, tracker)
        check_fixtures_used(fixtures, sets)
        vsets = _read_all(m, validate, "--validate", fixtures, angle_unit, tracker) or None
        if rotation_weight is not None and not any(getattr(d, "rotations", None) is not None
                                                   for d in sets):
            raise InputError("applies to measured orientations (qw..qz columns) only",
                             option="--rotation-weight")
        res = calibrate(m, sets, method, free=free, validate=vsets, rng=seed, loss=loss,
                        maxiter=maxiter, target=target, rotation_weight=rotation_weight,
                        sigma=stated, validate_register=tracker.get("register"), **priors)
        res.warnings = list(found)
        result = with_warnings(res.to_dict(), found)
        write_outputs(out=out, result=result, model_out=model_out, save_model=res.save_model,
                      report=report, write_report=lambda path: _report(res, path, provenance),
                      quiet=quiet or json_out)
    if json_out:
        echo_json(result)
    elif not quiet:
        typer.echo(res.summary(unit))


def _report(res, path: Path, provenance) -> None:
    from kinecal.report.html import calibration_report

    calibration_report(res, path, provenance=provenance)


def identifiability_files(model: str, files: list[str], *, base_link, tip_link, free,
                          json_out: bool, quiet: bool, strict: bool,
                          sigma: list[str] | None = None,
                          fixture: list[Path] | None = None,
                          angle_unit: str | None = None) -> None:
    """``kinecal identifiability MODEL --data A.csv --data B.csv``: what a mix identifies
    (what `calibrate` would free from it), with ``--fixture`` files."""
    from kinecal.calibration.blocks.plan import analyse_kinds

    stated = parse_sigma(sigma, files)
    with warnings_scope(strict) as found:
        m = load_model_arg(model, base_link, tip_link)
        fixtures = read_fixtures(fixture)
        sets = _read_all(m, files, "--data", fixtures, angle_unit)
        check_fixtures_used(fixtures, sets)
        ana, kinds = analyse_kinds(m, sets, free, sigma=stated)
    out = ana.report.to_dict()
    out["not_seen"] = list(ana.unseen)
    out["fixtures_show"] = list(ana.shown_by_fixtures)
    out["kinds"] = kinds
    if json_out:
        echo_json(with_warnings(out, found))
        return
    if quiet:
        return
    from kinecal.calibration.blocks.motions import fixture_words, unseen_words

    typer.echo(ana.report.explain())
    typer.echo("identifiable: " + ", ".join(ana.report.identifiable))
    typer.echo("observability: " + ", ".join(f"{k}={v:.4g}"
                                             for k, v in ana.report.observability.items()))
    for k in kinds:
        typer.echo(f"{k['kind']} ({Path(k['file']).name}): {k['observations']} observations,"
                   f" {k['unknowns']} unknowns of its own"
                   + (f", {k['known']} known" if k.get("known") else ""))
    if ana.unseen:
        typer.echo(f"not seen by this mix: {unseen_words(ana.unseen)}")
    if ana.shown_by_fixtures:
        typer.echo(f"known fixtures make visible: {fixture_words(ana.shown_by_fixtures)}")


def _vectors(values: list[str] | None, size: int, option: str) -> np.ndarray | None:
    if not values:
        return None
    rows = []
    for v in values:
        try:
            row = [float(c) for c in v.split(",")]
        except ValueError:
            row = []
        if len(row) != size or not np.isfinite(row).all():
            raise InputError(f"{v!r}: expected {size} comma-separated numbers", option=option)
        rows.append(row)
    return np.array(rows)


def simulate_gauge(m, kind: str, errors, *, poses: int, noise: float, seed: int, out: Path,
                   truth_out: Path | None, quiet: bool, gauge: dict[str, Any],
                   orientation: bool) -> None:
    """``kinecal simulate MODEL --kind K ...`` after the model and ``--errors`` are read:
    `errors` is ``zero``, ``random`` (drawn from `seed`; to measure one arm with several
    kinds, write ``--truth-out`` once and pass it as ``--errors`` to the others) or the
    deviations of a truth file."""
    from kinecal.calibration.serial.simulate import random_errors, write_truth
    from kinecal.data import GAUGE_KINDS

    if kind not in GAUGE_KINDS:
        raise InputError(f"unknown kind {kind!r}; expected one of tracker, "
                         f"{', '.join(GAUGE_KINDS)}", option="--kind")
    if orientation:
        raise InputError(f"applies to --kind tracker only, not {kind}", option="--orientation")
    if isinstance(errors, str):
        true_params = m.nominal + (0.0 if errors == "zero" else
                                   random_errors(m, np.random.default_rng(seed)))
    else:
        true_params = m.nominal + errors
    n = simulate_kind_file(m, kind, poses=poses, noise=noise, true_params=true_params,
                           seed=seed, out=out, **gauge)
    if truth_out is not None:
        write_truth(truth_out, m, true_params)
    if not quiet:
        typer.echo(f"wrote {n} {kind} rows to {out}"
                   + (f", truth to {truth_out}" if truth_out else ""), err=True)


def simulate_kind_file(m, kind: str, *, poses: int, noise: float, true_params, seed: int,
                       out: Path, pivot: list[str] | None, point: list[str] | None,
                       plane: list[str] | None, length: float | None, radius: float | None,
                       groups: int | None, sigma_column: bool) -> int:
    """``kinecal simulate MODEL --kind ...``: write the rows of one gauge kind; returns
    the row count."""
    from kinecal.calibration.blocks.simulate import simulate_kind
    from kinecal.io.kinds import write_gauge

    given = {"--pivot": pivot, "--point": point, "--plane": plane}
    wanted = {"ballbar": "--pivot", "point": "--point", "plane": "--plane"}.get(kind)
    for opt, value in given.items():
        if value and opt != wanted:
            raise InputError(f"applies to --kind {opt[2:] if opt != '--pivot' else 'ballbar'}"
                             f", not {kind}", option=opt)
    if length is not None and kind not in ("ballbar", "pair"):
        raise InputError(f"applies to --kind ballbar or pair, not {kind}", option="--length")
    check_finite(length, "--length", positive=True)
    check_finite(radius, "--radius", positive=True)
    centres = _vectors(pivot or point, 3, wanted or "--pivot")
    planes = _vectors(plane, 6, "--plane")
    sim = simulate_kind(m, kind, poses, true_params=true_params, noise=noise, rng=seed,
                        centres=centres, planes=planes, length=length, radius=radius,
                        groups=groups)
    data = sim.data
    if sigma_column and noise > 0:
        import dataclasses

        data = dataclasses.replace(data, sigma=np.full(len(data), float(noise)))
    write_gauge(out, data, m)
    return len(data)


def select_kind_file(model: str, kind: str, *, count: int, candidates: int | None, seed: int,
                     out: Path, gauge: list[str] | None, length: float | None, base_link,
                     tip_link, angle_unit: str | None = None,
                     program: tuple = (None, 2.0)) -> None:
    """``kinecal select-poses MODEL --kind K --count N --out PLAN.csv``: D-optimal rows of a
    gauge kind (`kinecal.calibration.blocks.plan.select_kind_poses`)."""
    from kinecal.calibration.blocks.plan import select_kind_poses
    from kinecal.data import GAUGE_KINDS
    from kinecal.io.kinds import write_gauge

    if kind not in GAUGE_KINDS:
        raise InputError(f"unknown kind {kind!r}; expected one of tracker, "
                         f"{', '.join(GAUGE_KINDS)}", option="--kind")
    check_paths({"MODEL": model}, {"--out": out, "--program": program[0]})
    check_finite(length, "--length", positive=True)
    from kinecal._limits import check_count

    candidates = 100 if candidates is None else candidates
    check_count(candidates, "--candidates", bytes_per_item=4096, what="candidates")
    geometry: dict[str, Any] = {"length": length}
    if gauge:
        if kind == "pair":
            raise InputError("applies to ballbar, point and plane", option="--gauge")
        size = 6 if kind == "plane" else 3
        geometry["planes" if kind == "plane" else "centres"] = _vectors(gauge, size, "--gauge")
    if length is not None and kind not in ("ballbar", "pair"):
        raise InputError(f"applies to --kind ballbar or pair, not {kind}", option="--length")
    m = load_model_arg(model, base_link, tip_link)
    from kinecal.cli._programs import check_program_for

    check_program_for(program[0], m, program[1])
    plan, info = select_kind_poses(m, kind, count, candidates=candidates, rng=seed, **geometry)
    from kinecal._files import all_or_nothing
    from kinecal.cli._programs import write_program_for

    with all_or_nothing():  # the rows and their program both, or neither
        write_gauge(out, plan, m, angle_unit=angle_unit)
        if program[0] is not None:  # a robot program visiting the rows in order
            write_program_for(program[0], m, plan.q, program[1], f"kinecal select-poses "
                              f"{m.name} --kind {kind}: calibration poses")
    typer.echo(f"wrote {len(plan)} {kind} rows to {out}; O1 = {info['O1']:.4g}, O2 = "
               f"{info['O2']:.4g} ({info['rank']} identifiable parameters"
               + (f"; not seen: {', '.join(info['not_seen'])}" if info["not_seen"] else "")
               + ")", err=True)
