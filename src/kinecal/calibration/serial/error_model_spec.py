"""The choices of ``--error-model`` (`kinecal.calibration.serial.error_model`): their names,
default harmonic orders and folds, the methods that fit joint-error terms, the parsing of a
choice into joint-error families (`kinecal.kinematics.serial.joint_errors`) and the candidates
``auto`` scores. Re-exported by `kinecal.calibration.serial.error_model`; here so that option
checks can read them without importing the calibration itself.
"""

from __future__ import annotations

from kinecal.errors import InputError
from kinecal.kinematics.serial.joint_errors import FAMILIES

__all__ = ["AUTO_HARMONICS", "DEFAULT_FOLDS", "DEFAULT_HARMONICS", "ERROR_MODELS", "LSQ_METHODS",
           "MAX_HARMONICS", "candidates", "parse_error_model"]

#: the choices of ``--error-model`` (``+``-joined family lists are accepted as well)
ERROR_MODELS = ("geometric", "compliance", "harmonic", "scale", "full", "auto", "model")
#: default harmonic order of the fixed choices, and the largest order ``auto`` tries
DEFAULT_HARMONICS = 2
AUTO_HARMONICS = 4
MAX_HARMONICS = 12
#: default number of cross-validation folds
DEFAULT_FOLDS = 10
#: the methods that fit joint-error terms (the metaheuristics search a box of geometric
#: tolerances, which has no meaning for compliance coefficients)
LSQ_METHODS = ("lm", "householder")


def parse_error_model(spec: str) -> tuple[str, ...] | None:
    """Families of an ``--error-model`` value; None for ``auto`` and ``model``.

    ``geometric`` -> (), ``full`` -> all families, ``compliance+harmonic`` -> both.
    """
    if spec in ("auto", "model"):
        return None
    if spec == "geometric":
        return ()
    if spec == "full":
        return FAMILIES
    parts = [p.strip() for p in spec.split("+") if p.strip()]
    bad = [p for p in parts if p not in FAMILIES]
    if not parts or bad:
        raise InputError(f"unknown error model {spec!r}; expected one of "
                         f"{', '.join(ERROR_MODELS)} or families joined by '+' "
                         f"({', '.join(FAMILIES)})", option="--error-model")
    return tuple(f for f in FAMILIES if f in parts)


def candidates(max_harmonics: int) -> list[tuple[str, tuple[str, ...], int]]:
    """``auto``'s candidates ``(label, families, harmonic order)``, smallest first."""
    out: list[tuple[str, tuple[str, ...], int]] = []
    orders = [0, *range(1, max_harmonics + 1)]
    for h in orders:
        for comp in (False, True):
            for scale in (False, True):
                fam = (("compliance",) if comp else ()) + (("harmonic",) if h else ()) \
                    + (("scale",) if scale else ())
                label = "+".join(
                    (["compliance"] if comp else []) + ([f"harmonic{h}"] if h else [])
                    + (["scale"] if scale else [])) or "geometric"
                out.append((label, fam, h))
    return out
