"""The options of ``kinecal calibrate``, declared once each (the command lists them one line
apiece; `kinecal.cli._options` holds the ones other commands share)."""

from __future__ import annotations

import typer

from kinecal.cli._options import CALIBRATION_METHOD_CHOICES, choices

#: help of --fixture (calibrate, identifiability)
FIXTURE_HELP = ("Known fixtures: CSV of point,px,py,pz or plane,px,py,pz,nx,ny,nz rows (base "
                "frame, length unit) for the point or plane files' ids (repeatable). See "
                "docs/measurement-kinds.md.")
#: --error-model values (and families joined by '+')
ERROR_MODELS = ("geometric", "compliance", "harmonic", "scale", "full", "auto")

DATA = typer.Argument(..., help="Measurement CSV(s) or NAME:PART; several files of any kinds "
                      "make one problem (docs/measurement-kinds.md).")
METHOD = typer.Option("lm", "--method", metavar=choices(*CALIBRATION_METHOD_CHOICES),
                      help="Levenberg-Marquardt, Householder Gauss-Newton, a metaheuristic, or "
                      "least squares then a metaheuristic (hybrid-ga, ...). See "
                      "docs/optimizers.md.")
VALIDATE = typer.Option(None, "--validate", help="Validation CSV or NAME:PART (any kind; "
                        "repeatable).")
FREE = typer.Option("identifiable", "--free", metavar=choices("identifiable", "all", "NAMES"),
                    help="The identifiable parameters, all or comma-separated names.")
LOSS = typer.Option("linear", "--loss", metavar=choices(
    "linear", "huber", "soft_l1", "cauchy", "arctan"), help="Loss of the residuals (robust "
    "losses with lm only).")
MAXITER = typer.Option(None, "--maxiter", help="Iteration budget.")
TARGET = typer.Option(None, "--target", help="Stop at this mean distance error (model length "
                      "unit; metaheuristics).")
BOX = typer.Option(None, "--box", metavar=choices("data", "tolerances"),
                   help="Search box of a metaheuristic: around a Levenberg-Marquardt fit "
                   "(data, the default) or the model file's tolerances around nominal (the "
                   "papers'). See docs/optimizers.md.")
OUT = typer.Option(None, "--out", help="Result JSON to write.")
MODEL_OUT = typer.Option(None, "--model-out", help="Calibrated model YAML.")
JSON = typer.Option(False, "--json", help="Print the result JSON.")
ROTATION_WEIGHT = typer.Option(
    None, "--rotation-weight", help="With measured orientations: length units per rad of "
    "rotation error (default: the workspace's characteristic length).")
ERROR_MODEL = typer.Option(
    None, "--error-model", metavar=choices(*ERROR_MODELS), help="auto: chosen by "
    "cross-validation on the calibration poses, within and beyond their joint ranges; or "
    "families joined by '+' (default: the model file's joint_errors, else geometric). See "
    "docs/error-models.md.")
HARMONICS = typer.Option(None, "--harmonics", help="Harmonic order (default 2; auto tries "
                         "1..4).")
FOLDS = typer.Option(None, "--folds", help="Cross-validation folds (--error-model auto; "
                     "default 10).")
SIGMA = typer.Option(
    None, "--sigma", help="The instrument's stated 1-sigma noise per coordinate (length "
    "unit): the residual is tested against it (chi-square) and the standard errors with "
    "it known are added. Several files: FILE=SIGMA (repeatable) or SIGMA,SIGMA,... in "
    "file order. See docs/diagnostics.md.")
PRIOR = typer.Option(
    None, "--prior", metavar="auto|GROUP=S,...|FILE", help="A prior on the free parameters "
    "(a MAP fit): auto (strength by cross-validation), lengths=S,angles=S (1-sigma in model "
    "units; also NAME=S, tool.*=S) or a CSV name,sigma[,mean]. See docs/priors.md.")
PRIOR_FROM = typer.Option(
    None, "--prior-from", help="Prior values from a previous result JSON instead of the "
    "nominal ones (alone: --prior auto).")
IMAGES = typer.Option(None, "--images", help="Folder of board images: DATA is then "
                      "STATIONS.csv (image,q1..qn). See docs/arm-from-images.md.")
BOARD = typer.Option(None, "--board", help="With --images: the board, e.g. "
                     "chessboard:9x6:25; a rig's NAME:LINK:SPEC (repeatable; docs/rigs.md).")
CAMERA = typer.Option(None, "--camera", help="With --images: a rig's camera "
                      "NAME:LINK[:intrinsics.yaml] (repeatable; LINK world, flange or a "
                      "system's link).")
INTRINSICS = typer.Option(None, "--intrinsics", help="With --images: camera YAML (default: "
                          "from the images).")
SETUP = typer.Option("eye-in-hand", "--setup", help="With --images: eye-in-hand or "
                     "eye-to-hand.")
MIN_CORNERS = typer.Option(None, "--min-corners", help="With --images: fewest corners an image "
                           "must show (ChArUco, seen in part; default 60 % of the board's).")
FIXTURE = typer.Option(None, "--fixture", help=FIXTURE_HELP)
