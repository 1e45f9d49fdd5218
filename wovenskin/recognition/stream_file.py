"""A labelled stream for the pipeline: given, or read from a ``.npz`` or ``.wsrec`` file."""

from __future__ import annotations

import os

import numpy as np

from wovenskin.recording.files import read_stream
from wovenskin.recording.formats import LabelledStream
from wovenskin.skin.layout import check_supported


def load_stream(stream: LabelledStream | str | os.PathLike) -> LabelledStream:
    """``stream`` itself, or the labelled stream read from a ``.npz`` or ``.wsrec`` path
    (the kind decided by content: :func:`wovenskin.recording.files.read_stream`); a grid or
    rate the pipeline cannot use is one
    :class:`~wovenskin.skin.layout.UnsupportedSkinError` line naming the file."""
    if isinstance(stream, LabelledStream):
        labelled, where = stream, "the stream"
    elif os.path.isdir(stream):
        raise FileNotFoundError(f"{stream}: is a folder, not a stream file (.npz or .wsrec)")
    elif not os.path.isfile(stream):
        raise FileNotFoundError(f"{stream}: no such file")
    else:
        labelled, where = read_stream(stream, "the pipeline"), str(stream)
    shape = np.shape(labelled.frames)
    if len(shape) == 3:  # run_pipeline names any other shape
        check_supported(shape[1], shape[2], labelled.sample_rate_hz, where)
    return labelled
