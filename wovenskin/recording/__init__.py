"""Keeping skin data: the native recording format, the interchange formats and replay.

- :mod:`wovenskin.recording.untrusted` -- what a file is, bounded JSON, safe ``.npz`` loading;
- :mod:`wovenskin.recording.formats` -- labelled streams and labelled captures (``.npz``,
  ``docs/formats.md``);
- :mod:`wovenskin.recording.native` -- the crash-safe ``.wsrec`` recording and its reader,
  over :mod:`~wovenskin.recording.records`, :mod:`~wovenskin.recording.documents` and
  :mod:`~wovenskin.recording.writer`;
- :mod:`wovenskin.recording.files` -- the one reader that decides what a data file is;
- :mod:`wovenskin.recording.replay` -- a skin source that plays either back;
- :mod:`wovenskin.recording.inspect` -- ``wovenskin info`` and ``wovenskin convert``.
"""
