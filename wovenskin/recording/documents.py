"""The documents inside ``.wsrec`` records: JSON with numeric arrays kept as raw bytes."""

from __future__ import annotations

import json
import math
import re
import struct
from typing import Any

import numpy as np

from wovenskin.io import to_jsonable
from wovenskin.recording.untrusted import loads_json

_DOC_HEAD = struct.Struct("<I")  # JSON length
_ARRAY_REF = "__wsrec_array__"
_ARRAY_DTYPE = re.compile(r"[<>|=]?[biuf][1-9][0-9]?")  # plain numeric or boolean dtypes


def encode_document(document: Any) -> bytes:
    """JSON with numeric numpy arrays (anywhere inside) stored as raw little-endian bytes.

    Layout: ``u32 json_length``, the UTF-8 JSON ``{"arrays": [{"dtype", "shape"}...],
    "doc": ...}`` in which each array is replaced by ``{"__wsrec_array__": index}``, then
    the arrays' bytes in index order.
    """
    arrays: list[np.ndarray] = []

    def to_json(value: Any) -> Any:
        if isinstance(value, np.ndarray):
            if value.dtype.kind not in "biuf":
                raise TypeError(f"cannot record an array of dtype {value.dtype}")
            arrays.append(np.ascontiguousarray(value, dtype=value.dtype.newbyteorder("<")))
            return {_ARRAY_REF: len(arrays) - 1}
        plain = to_jsonable(value)  # numpy scalars, paths
        if plain is value:
            raise TypeError(f"cannot record a value of type {type(value).__name__}")
        return plain

    doc_json = json.dumps(document, default=to_json)
    specs = [{"dtype": a.dtype.str, "shape": list(a.shape)} for a in arrays]
    text = ('{"arrays": ' + json.dumps(specs) + ', "doc": ' + doc_json + "}").encode()
    return b"".join((_DOC_HEAD.pack(len(text)), text, *(a.tobytes() for a in arrays)))


def decode_document(payload: bytes | memoryview) -> Any:
    """Inverse of :func:`encode_document`; ``ValueError`` (one line) if the payload is
    malformed: bad JSON, nesting past :data:`~wovenskin.recording.untrusted.MAX_JSON_DEPTH`,
    an envelope or array spec of the wrong type, a dtype that is not plain numeric, a shape
    whose bytes the record does not hold, or a reference to an array that does not exist."""
    payload = memoryview(payload)
    if len(payload) < _DOC_HEAD.size:
        raise ValueError("document shorter than its length field")
    (text_length,) = _DOC_HEAD.unpack_from(payload)
    end = _DOC_HEAD.size + text_length
    if end > len(payload):
        raise ValueError("document JSON runs past the record")
    envelope = loads_json(bytes(payload[_DOC_HEAD.size : end]), "document JSON")
    if not isinstance(envelope, dict) or not isinstance(envelope.get("arrays"), list):
        raise ValueError("document is not an object with an 'arrays' list")
    if "doc" not in envelope:
        raise ValueError("document has no 'doc'")
    arrays = []
    for spec in envelope["arrays"]:
        dtype, shape = array_spec(spec)
        nbytes = dtype.itemsize * math.prod(shape)
        if end + nbytes > len(payload):
            raise ValueError(f"array {dtype} {shape} needs {nbytes} bytes the record does not hold")
        array = np.frombuffer(payload, dtype, math.prod(shape), end).reshape(shape)
        arrays.append(array.astype(dtype.newbyteorder("="), copy=True))
        end += nbytes
    if end != len(payload):
        raise ValueError(f"{len(payload) - end} stray bytes after the document")
    return _resolve_arrays(envelope["doc"], arrays)


def array_spec(spec: Any) -> tuple[np.dtype, tuple[int, ...]]:
    """The dtype and shape of one ``{"dtype", "shape"}`` spec of an untrusted document,
    checked before any use (a ROS 2 bag's documents use it too); else a one-line
    ``ValueError``."""
    if not isinstance(spec, dict):
        raise ValueError("an array spec is not an object")
    text, shape = spec.get("dtype"), spec.get("shape")
    if not isinstance(text, str) or not _ARRAY_DTYPE.fullmatch(text):
        raise ValueError(f"array dtype {str(text)[:40]!r} is not a plain numeric dtype")
    try:
        dtype = np.dtype(text)
    except TypeError:
        raise ValueError(f"array dtype {text!r} is not a plain numeric dtype") from None
    if not isinstance(shape, list) or len(shape) > 32:
        raise ValueError("array shape is not a list of at most 32 sizes")
    if not all(type(n) is int and n >= 0 for n in shape):
        raise ValueError(f"array shape {str(shape)[:60]} is not a list of sizes >= 0")
    return dtype, tuple(shape)


def _resolve_arrays(value: Any, arrays: list[np.ndarray]) -> Any:
    if isinstance(value, dict):
        if len(value) == 1 and _ARRAY_REF in value:
            index = value[_ARRAY_REF]
            if type(index) is not int or not 0 <= index < len(arrays):
                count = len(arrays)
                raise ValueError(f"reference to array {str(index)[:20]}, but there are {count}")
            return arrays[index]
        return {k: _resolve_arrays(v, arrays) for k, v in value.items()}
    if isinstance(value, list):
        return [_resolve_arrays(v, arrays) for v in value]
    return value
