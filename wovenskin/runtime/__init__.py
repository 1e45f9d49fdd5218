"""The composition root: the only package that opens sources, robots, recognisers and
sessions from their specs and wires the pipeline's stages together.  Every other package
imports only the stages below it."""

from wovenskin.runtime.pipeline import LiveChain, open_live_pipeline, open_live_skin
from wovenskin.runtime.session import open_session
from wovenskin.runtime.sources import open_source

__all__ = ["LiveChain", "open_live_pipeline", "open_live_skin", "open_session", "open_source"]
