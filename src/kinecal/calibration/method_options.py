"""Which calibration options each method uses: the others are refused, never ignored.

A metaheuristic has no robust loss, Levenberg-Marquardt has no iteration budget nor a
target cost: an option the chosen method would silently drop gives a result the user did
not ask for (``--method pso --loss huber`` is still a plain mean-error search). `calibrate`,
the command line and the batch jobs file all check with `check_method_options`.

| option | lm | householder | metaheuristics | hybrid-* |
|---|---|---|---|---|
| loss (other than linear), f_scale | yes | - | - | - |
| maxiter | - | yes | yes | yes |
| target | - | - | yes | yes |
| options | - | - | yes | yes |
"""

from __future__ import annotations

from typing import Any

from kinecal.errors import InputError

__all__ = ["box_option", "check_method_options", "uses"]

#: option -> predicate on the method name: does the method use it?
_USED_BY = {
    "loss": lambda m: m == "lm",
    "f_scale": lambda m: m == "lm",
    "maxiter": lambda m: m != "lm",
    "target": lambda m: m not in ("lm", "householder"),
    "options": lambda m: m not in ("lm", "householder"),
}

#: what to say about each option when refused
_WHO = {
    "loss": "a robust loss applies to method lm only",
    "f_scale": "f_scale applies to method lm with a robust loss only",
    "maxiter": "an iteration budget applies to householder, the metaheuristics and the "
               "hybrids (lm stops on its own tolerances)",
    "target": "a target mean error applies to the metaheuristics and the hybrids only",
    "options": "method options apply to the metaheuristics and the hybrids only",
}


def uses(method: str, option: str) -> bool:
    """True when calibration `method` uses `option` (``loss``, ``maxiter``, ...)."""
    return _USED_BY[option](method)


def check_method_options(method: str, *, loss: str = "linear", f_scale: float | None = None,
                         maxiter: int | None = None, target: float | None = None,
                         options: dict[str, Any] | None = None,
                         names: dict[str, str] | None = None) -> None:
    """Refuse the options that `method` would not use.

    Parameters
    ----------
    method : str
        Calibration method (`kinecal.calibrate`).
    loss, f_scale, maxiter, target, options
        As given to `kinecal.calibrate` (defaults: not given).
    names : dict of str to str, optional
        How the options are called where they were given (default ``--loss``,
        ``--maxiter``, ... as on the command line); named in the error.

    Raises
    ------
    InputError
        An option given that `method` does not use, or `f_scale` without a robust loss.
    """
    given = {"loss": loss != "linear", "f_scale": f_scale is not None,
             "maxiter": maxiter is not None, "target": target is not None,
             "options": bool(options)}
    label = {k: f"--{k.replace('_', '-')}" for k in given} | dict(names or {})
    for option, present in given.items():
        if present and not uses(method, option):
            raise InputError(f"{_WHO[option]}, not to method {method}", option=label[option])
    if f_scale is not None and loss == "linear":
        raise InputError(_WHO["f_scale"], option=label["f_scale"])


def check_error_model_options(error_model: str | None, *, harmonics: int | None = None,
                              folds: int | None = None) -> None:
    """Refuse ``--harmonics`` and ``--folds`` where the error model would not use them.

    ``--harmonics`` sets the order of an explicit harmonic family (``harmonic``, ``full``,
    ``...+harmonic``) or the largest order ``auto`` tries; ``--folds`` the cross-validation
    of ``auto``. Without ``--error-model`` the model file's own terms are used as they are.
    """
    from kinecal.calibration.serial.error_model_spec import parse_error_model

    if folds is not None and error_model != "auto":
        raise InputError("cross-validation folds apply to --error-model auto only",
                         option="--folds")
    if harmonics is not None:
        families = None if error_model is None else parse_error_model(error_model)
        if error_model != "auto" and (families is None or "harmonic" not in families):
            raise InputError("a harmonic order applies to --error-model auto, full or one "
                             "with the harmonic family, not to "
                             f"{error_model or 'the model file default'}",
                             option="--harmonics")


def check_refine_options(refine: str, *, robust: bool = True,
                         rotation_weight: float | None = None,
                         options: dict[str, Any] | None = None) -> None:
    """Refuse hand-eye refinement options the chosen `refine` would not use.

    ``rotation_weight`` belongs to the ``lm`` refinement, ``robust=False`` to ``lm`` and
    ``none`` (no outlier flags), ``options`` (popsize, maxiter, boxes) to the metaheuristic
    refiners ``igwo`` and ``dlh-gwo-de``.
    """
    if refine != "lm" and rotation_weight is not None:
        raise InputError(f"rotation_weight applies to refine lm, not to refine {refine}",
                         option="rotation_weight")
    if refine not in ("lm", "none") and robust is False:
        raise InputError(f"robust applies to refine lm and none, not to refine {refine}",
                         option="robust")
    if options and refine not in ("igwo", "dlh-gwo-de"):
        raise InputError(f"options apply to the metaheuristic refiners (igwo, dlh-gwo-de), "
                         f"not to refine {refine}", option="options")


def box_option(method: str, box: str | None) -> dict[str, str] | None:
    """The method options of ``--box`` (`kinecal.calibration.serial.box`): None when not
    given; refused for ``lm`` and ``householder``, which search no box."""
    if box is None:
        return None
    if method in ("lm", "householder"):
        raise InputError(f"a search box applies to the metaheuristics only, not to method "
                         f"{method}", option="--box")
    return {"box": box}
