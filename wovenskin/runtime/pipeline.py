"""Opening the live chain: skin source -> conditioning (LiveSkin) -> recogniser -> arbiter.

The one place that wires these stages for a live skin.  :func:`open_live_skin` opens the
source named by a spec and its :class:`~wovenskin.signal.live_skin.LiveSkin` (views, the
guided recorder); :func:`open_live_pipeline` adds the recogniser and the
:class:`~wovenskin.recognition.pipeline.LivePipeline` with the model's own conditioning
and execution rules (robot sessions).  :meth:`LiveChain.record` records every raw frame
to a ``.wsrec`` file.  Nothing is started: the caller starts the skin (or the session
built on it).

A skin whose spec leaves its grid unset (``sim``, ``serial:PORT``, ``none``) takes the
model's grid (:data:`GRID_OPTION_KINDS`): the simulated skin is drawn with it, and a serial
device is assumed to have it until its INFO says otherwise (``docs/skins.md``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from wovenskin.recognition.pipeline import (
    LivePipeline,
    PipelineSettings,
    conditioning_for_model,
    load_recognizer,
    pipeline_settings_for_model,
)
from wovenskin.recording.writer import RecordingWriter
from wovenskin.runtime.sources import open_source, skin_spec
from wovenskin.signal.config import ConditioningConfig
from wovenskin.signal.live_skin import LiveSkin
from wovenskin.skin.frames import SkinInfo
from wovenskin.skin.source import SkinSource
from wovenskin.specs import Spec

OBJECT_SOURCE_SPEC = "none:speed=0"
GRID_OPTION_KINDS = ("sim", "serial", "none")
"""The skin sources whose grid is a ``rows``/``cols`` option (the others bring their own)."""
"""The spec a chain built on a source object reports: read as fast as it delivers."""

Provenance = Mapping[str, Any] | Callable[[SkinInfo], Mapping[str, Any]]
"""A recording's provenance, or a function of the skin's info that gives it."""


@dataclass
class LiveChain:
    """The opened (not started) stages of the live chain; ``recognizer`` and ``pipeline``
    are None for a skin opened without a model, ``recorder`` without a recording."""

    spec: Spec  # the skin spec with the options the source was opened with
    source: SkinSource
    live_skin: LiveSkin
    recorder: RecordingWriter | None = None
    recognizer: Any = None
    pipeline: LivePipeline | None = None

    def record(
        self,
        path: str | Path,
        *,
        overwrite: bool = False,
        provenance: Provenance | None = None,
        settings: Mapping[str, Any] | None = None,
    ) -> RecordingWriter:
        """Record every raw frame from now on to ``path`` (``.wsrec``).

        The recording's settings are the conditioning in use, then ``settings``; its
        provenance is ``provenance`` (default: the skin spec as given)."""
        info = self.source.info
        if callable(provenance):
            provenance = provenance(info)
        header = dict(provenance) if provenance is not None else {"skin_source": self.spec.text}
        recorded = {"conditioning": self.live_skin.config.to_dict(), **(settings or {})}
        self.recorder = RecordingWriter(path, info, header, recorded, overwrite=overwrite)
        self.live_skin.recorder = self.recorder
        return self.recorder

    def close(self) -> None:
        """Close the skin, then the recording (every frame so far is on disk)."""
        try:
            self.live_skin.close()
        finally:
            if self.recorder is not None:
                self.recorder.close()


def open_live_skin(
    skin: str | Spec | SkinSource = "sim",
    *,
    conditioning: ConditioningConfig | None = None,
    record: str | Path | None = None,
    overwrite: bool = False,
    provenance: Provenance | None = None,
    recorded: Mapping[str, Any] | None = None,
    on_message: Callable[[str], None] | None = None,
    defaults: Mapping[str, Any] | None = None,
) -> LiveChain:
    """Open the skin named by ``skin`` and condition its frames.

    ``conditioning`` defaults to the default settings at the source's rate; ``defaults``
    are spec options used where the spec does not set them; ``record`` starts a recording
    (see :meth:`LiveChain.record`, which ``provenance`` and ``recorded`` go to).  A bad
    spec or option is one :class:`~wovenskin.errors.ConfigError` line."""
    if isinstance(skin, str | Spec):
        spec = skin_spec(skin)
        unset = {key: value for key, value in (defaults or {}).items() if key not in spec.options}
        spec = skin_spec(spec, **unset)
        source = open_source(spec)
    else:  # a source object (a simulated operator's skin): read as fast as it delivers
        source, spec = skin, skin_spec(OBJECT_SOURCE_SPEC)
    chain = LiveChain(spec, source, LiveSkin(source, conditioning, on_message=on_message))
    if record is not None:
        chain.record(record, overwrite=overwrite, provenance=provenance, settings=recorded)
    return chain


def open_live_pipeline(
    skin: str | Spec | SkinSource = "sim",
    *,
    model: str | Path | None = None,
    recognizer: Any = None,
    settings: PipelineSettings | None = None,
    on_message: Callable[[str], None] | None = None,
    defaults: Mapping[str, Any] | None = None,
) -> LiveChain:
    """Open the skin named by ``skin`` and wire it to a recogniser and an arbiter.

    ``recognizer`` (default: the one of checkpoint directory ``model``, or the shipped
    model) sets the conditioning; ``settings`` default to the model's recommended execution
    rules; ``on_message`` and ``defaults`` as for :func:`open_live_skin` (a skin that leaves
    its grid unset takes the model's: module docstring).  Record with
    :meth:`LiveChain.record` once everything the recording is for has been built."""
    recognizer = recognizer if recognizer is not None else load_recognizer(model)
    chain = open_live_skin(
        skin,
        conditioning=conditioning_for_model(recognizer),
        on_message=on_message,
        defaults={**_model_grid(skin, recognizer), **(defaults or {})},
    )
    chain.recognizer = recognizer
    settings = settings if settings is not None else pipeline_settings_for_model(recognizer)
    chain.pipeline = LivePipeline.for_live_skin(chain.live_skin, recognizer, settings)
    return chain


def _model_grid(skin: str | Spec | SkinSource, recognizer: Any) -> dict[str, int]:
    """``rows``/``cols`` spec options of the model's grid for a skin that takes them."""
    meta = getattr(recognizer, "meta", None)
    rows, cols = getattr(meta, "rows", None), getattr(meta, "cols", None)
    if not isinstance(skin, str | Spec) or rows is None or cols is None:
        return {}
    if skin_spec(skin).kind not in GRID_OPTION_KINDS:
        return {}
    return {"rows": int(rows), "cols": int(cols)}
