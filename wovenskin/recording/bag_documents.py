"""The JSON inside a wovenskin ROS 2 bag: documents with exact arrays, checked on the way in.

A bag (:mod:`wovenskin.recording.bag`) carries a recording's header, calibrations, labels
and annotations as ``std_msgs/msg/String`` messages holding JSON.  :func:`dumps_document`
writes a numeric NumPy array anywhere inside a document as
``{"__ndarray__": {"dtype": "<f4", "shape": [10, 10], "base64": "..."}}`` (dtype and bytes
exact) and keeps ``NaN``/``Infinity`` as Python writes them; :func:`loads_document` is its
inverse for text a stranger may have crafted: nesting, dtypes and sizes are checked before
anything is allocated, and every problem is one ``ValueError`` line.

:func:`label_from_item` and :func:`annotation_from_item` check one label or annotation item
as the ``.wsrec`` reader checks its records; the bag writer runs them too, so wovenskin
never writes a bag it would refuse to read.
"""

from __future__ import annotations

import base64
import binascii
import json
import math
from typing import Any

import numpy as np

from wovenskin.io import to_jsonable
from wovenskin.recording.documents import array_spec
from wovenskin.recording.native import Annotation, RecordedLabel
from wovenskin.recording.untrusted import loads_json

ARRAY_KEY = "__ndarray__"
_RESERVED_EXTRA = frozenset({"self", "label", "start_s", "end_s", "kind"})


def dumps_document(document: Any) -> str:
    """``document`` as JSON text, numeric arrays exact (see the module docstring).

    ``ValueError`` (one line) for a value JSON cannot hold (an array of strings or
    objects, a set, an arbitrary object)."""

    def to_json(value: Any) -> Any:
        if isinstance(value, np.ndarray):
            if value.dtype.kind not in "biuf":
                raise ValueError(f"cannot store an array of dtype {value.dtype} in a bag")
            text = base64.b64encode(value.tobytes()).decode("ascii")  # C order, any ndim
            spec = {"dtype": value.dtype.str, "shape": list(value.shape), "base64": text}
            return {ARRAY_KEY: spec}
        plain = to_jsonable(value)  # numpy scalars, paths, dataclasses
        if plain is value:
            raise ValueError(f"cannot store a value of type {type(value).__name__} in a bag")
        return plain

    try:
        return json.dumps(document, default=to_json)
    except (TypeError, RecursionError) as exc:  # circular or exotic values
        raise ValueError(f"cannot store this document in a bag ({exc})") from None


def loads_document(text: str, what: str) -> Any:
    """Inverse of :func:`dumps_document` for untrusted ``text``; ``ValueError`` naming
    ``what`` for bad JSON, deep nesting or a malformed array."""
    return _resolve(loads_json(text, what), what)


def _resolve(value: Any, what: str) -> Any:
    if isinstance(value, dict):
        if len(value) == 1 and ARRAY_KEY in value:
            return _array(value[ARRAY_KEY], what)
        return {k: _resolve(v, what) for k, v in value.items()}
    if isinstance(value, list):
        return [_resolve(v, what) for v in value]
    return value


def _array(spec: Any, what: str) -> np.ndarray:
    """One ``__ndarray__`` spec as an array; dtype, shape and byte count checked first."""
    try:
        dtype, shape = array_spec(spec)
    except ValueError as exc:
        raise ValueError(f"{what}: {exc}") from None
    dtype_text, text = spec["dtype"], spec.get("base64")
    if not isinstance(text, str):
        raise ValueError(f"{what}: array has no base64 text")
    count = math.prod(shape)
    if count * dtype.itemsize != len(text) // 4 * 3 - text[-2:].count("="):
        raise ValueError(f"{what}: array {dtype_text} {shape} does not match its bytes")
    try:
        raw = base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError):
        raise ValueError(f"{what}: array bytes are not valid base64") from None
    if len(raw) != count * dtype.itemsize:
        raise ValueError(f"{what}: array {dtype_text} {shape} does not match its bytes")
    return np.frombuffer(raw, dtype, count).reshape(shape).copy()


# ----------------------------------------------------------------------------- items


def indexed_items(documents: list[tuple[int, Any]], count: Any, topic: str) -> list[dict]:
    """Items of one topic in their original order: each ``(bag time, decoded JSON)`` must
    be an object with an ``index``, and the indexes must be exactly ``0 .. count - 1``."""
    if type(count) is not int or count < 0:
        raise ValueError(f"the header's count of {topic} items is not a number >= 0")
    by_index: dict[int, dict] = {}
    for _, item in documents:
        index = item.get("index") if isinstance(item, dict) else None
        if type(index) is not int or not 0 <= index < count or index in by_index:
            shown = str(index)[:20]
            raise ValueError(f"{topic}: item index {shown} is missing, repeated or out of range")
        by_index[index] = item
    if len(by_index) != count:
        raise ValueError(f"{topic} holds {len(by_index)} items; the header says {count}")
    return [by_index[i] for i in range(count)]


def label_item(index: int, label: RecordedLabel) -> dict:
    return {
        "index": index,
        "label": label.label,
        "start_s": label.start_s,
        "end_s": label.end_s,
        "kind": label.kind,
        "extra": label.extra,
    }


def label_from_item(item: dict) -> RecordedLabel:
    """The label of one ``/wovenskin/labels`` item; ``ValueError`` if any field is bad."""
    start_s, end_s = _finite(item, "start_s"), _finite(item, "end_s")
    if end_s < start_s:
        raise ValueError(f"label ends at {end_s} before it starts at {start_s}")
    extra = item.get("extra")
    if not isinstance(extra, dict):
        raise ValueError("label 'extra' is not an object")
    reserved = sorted(_RESERVED_EXTRA & set(extra))
    if reserved:  # a .wsrec label could not hold them (RecordingWriter.add_label's keywords)
        raise ValueError(f"label 'extra' uses the reserved key {reserved[0]!r}")
    return RecordedLabel(_text(item, "label"), start_s, end_s, _text(item, "kind"), extra)


def annotation_item(index: int, note: Annotation) -> dict:
    return {"index": index, "stream": note.stream, "t": note.t, "payload": note.payload}


def annotation_from_item(item: dict) -> Annotation:
    """The annotation of one ``/wovenskin/annotations`` item; ``ValueError`` if bad."""
    if "payload" not in item:
        raise ValueError("annotation has no 'payload'")
    return Annotation(_text(item, "stream"), _finite(item, "t"), item["payload"])


def calibration_from_item(item: dict) -> dict:
    """The calibration of one ``/wovenskin/calibrations`` item; ``ValueError`` if bad."""
    calibration = item.get("calibration")
    if not isinstance(calibration, dict):
        raise ValueError("calibration is not an object")
    return calibration


def _text(item: dict, key: str) -> str:
    value = item.get(key)
    if not isinstance(value, str):
        raise ValueError(f"'{key}' is not text")
    return value


def _finite(item: dict, key: str) -> float:
    value = item.get(key)
    if type(value) not in (int, float) or not math.isfinite(value):
        raise ValueError(f"'{key}' is not a finite number")
    return float(value)
