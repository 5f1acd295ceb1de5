"""Several data sets, or another kind than tracker points, given to `kinecal.calibrate`:
tracker files alone are merged for the serial fast path (`kinecal.calibration.serial.
merge`), anything else is one stacked problem (`kinecal.calibration.blocks`)."""

from __future__ import annotations

from kinecal.calibration.serial.merge import data_sets, merge_tracker_sets

__all__ = ["several"]


def several(dispatch, model, data, method, *, free, validate, loss, f_scale, rank_tol,
            rotation_weight, sigma, **kw):
    """Several data sets or another kind than tracker points: tracker files alone are
    merged for the fast path (`dispatch`, the serial calibration's), anything else is one
    stacked problem (`kinecal.calibration.blocks.calibrate_blocks`)."""
    sets, sig = data_sets(data, sigma, "data")
    vsets = None if validate is None else data_sets(validate, None, "validation")[0]
    one = merge_tracker_sets(sets, sig)
    vone = None if vsets is None else merge_tracker_sets(vsets, [None] * len(vsets))
    if one is not None and (vsets is None or vone is not None):
        return dispatch(model, one[0], method, free=free, validate=None if vone is None
                        else vone[0], loss=loss, f_scale=f_scale, rank_tol=rank_tol,
                        rotation_weight=rotation_weight, sigma=one[1], **kw)
    from kinecal.calibration.blocks.api import calibrate_blocks

    return calibrate_blocks(model, sets, sigma=sig, validate=vsets, method=method, free=free,
                            loss=loss, f_scale=f_scale, rank_tol=rank_tol,
                            rotation_weight=rotation_weight, prior=kw.get("prior"),
                            prior_from=kw.get("prior_from"))
