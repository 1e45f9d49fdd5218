"""Keeping skin data: the native recording format, the interchange formats and replay.

- :mod:`wovenskin.recording.formats` -- labelled streams and labelled captures (``.npz``,
  ``docs/formats.md``);
- :mod:`wovenskin.recording.native` -- the crash-safe ``.wsrec`` recording format;
- :mod:`wovenskin.recording.replay` -- a skin source that plays either back.
"""
