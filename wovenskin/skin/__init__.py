"""Skin I/O: the layout of the grid, the frame types, the wire protocol and the sources.

Everything that reaches the rest of wovenskin from a skin (real or simulated) passes
through here and comes out as ``[row, col]`` frames on a stream clock.
"""

from wovenskin.skin.frames import Frame, SkinInfo, SourceEvent, SourceStats
from wovenskin.skin.layout import ChannelOrder, SkinLayout
from wovenskin.skin.source import SkinSource

__all__ = [
    "ChannelOrder",
    "Frame",
    "SkinInfo",
    "SkinLayout",
    "SkinSource",
    "SourceEvent",
    "SourceStats",
]
