"""The checkpoint description of a trained model: :func:`checkpoint_meta_for` a data set."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from wovenskin.errors import DataError
from wovenskin.io import plain_dict, to_jsonable
from wovenskin.recognition.checkpoint_meta import CheckpointMeta


def _as_mapping(meta: Mapping[str, Any] | Any) -> dict[str, Any]:
    return plain_dict(meta, "data set meta")


def _first(mapping: Mapping[str, Any], *keys: str) -> Any:
    for key in keys:
        if mapping.get(key) is not None:
            return mapping[key]
    return None


def checkpoint_meta_for(
    model_name: str,
    hparams: Mapping[str, Any],
    class_names: Sequence[str],
    input_shape: tuple[int, int, int],
    data_meta: Mapping[str, Any] | Any,
    training: Mapping[str, Any] | None = None,
) -> CheckpointMeta:
    """The :class:`CheckpointMeta` of a model trained on a data set described by ``data_meta``.

    ``data_meta`` must give ``sample_rate_hz`` and ``conditioning`` (the settings the frames
    were conditioned with). Windows of labelled captures (``conditioning`` None) record
    ``{"capture_normalisation": data_meta["normalisation"]}`` instead, or ``{}`` when there
    is none: consumers pass the same dict to ``check_input``. Grid rows/cols, window length
    and class names are cross-checked against the arrays when present (top level or under ``grid`` /
    ``layout``), pitches are taken from there. Everything else becomes the training-data
    description, with ``training`` (the training settings) added.
    """
    window, rows, cols = input_shape
    meta = _as_mapping(data_meta)
    grid = _as_mapping(_first(meta, "grid", "layout") or meta)
    rate = _first(meta, "sample_rate_hz", "rate_hz")
    if rate is None:
        raise DataError("data set meta lacks sample_rate_hz")
    if "conditioning" not in meta:
        raise DataError("data set meta lacks conditioning (the settings its frames went through)")
    meta_rows, meta_cols = grid.get("rows"), grid.get("cols")
    grid_given = meta_rows is not None and meta_cols is not None
    if grid_given and (int(meta_rows), int(meta_cols)) != (rows, cols):
        raise DataError(
            f"data set meta says {meta_rows}x{meta_cols} frames, windows are {rows}x{cols}"
        )
    meta_window = _first(meta, "window", "window_frames", "window_length")
    if meta_window is not None and int(meta_window) != window:
        raise DataError(f"data set meta says {meta_window}-frame windows, windows hold {window}")
    meta_classes = meta.get("class_names")
    if meta_classes is not None and [str(c) for c in meta_classes] != list(class_names):
        raise DataError("data set meta lists other class names than the ones given")
    conditioning = meta["conditioning"]
    if conditioning is not None:
        conditioning = to_jsonable(_as_mapping(conditioning))
    elif meta.get("normalisation") is not None:  # labelled captures: normalised, not conditioned
        conditioning = {"capture_normalisation": to_jsonable(_as_mapping(meta["normalisation"]))}
    else:
        conditioning = {}
    description = {k: v for k, v in meta.items() if k not in ("conditioning", "class_names")}
    if training is not None:
        description["training"] = dict(training)
    row_pitch = grid.get("row_pitch_mm")
    col_pitch = grid.get("col_pitch_mm")
    return CheckpointMeta(
        model_name=model_name,
        hparams=to_jsonable(dict(hparams)),
        class_names=tuple(class_names),
        rows=rows,
        cols=cols,
        window=window,
        sample_rate_hz=float(rate),
        conditioning=conditioning,
        row_pitch_mm=None if row_pitch is None else float(row_pitch),
        col_pitch_mm=None if col_pitch is None else float(col_pitch),
        training_data=to_jsonable(description),
    )
