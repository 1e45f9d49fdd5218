"""The root of every error wovenskin raises on purpose: bad input, a bad setting, a device.

Library code raises a subclass of :class:`WovenskinError` for anything a user can cause
and fix (a corrupt file, an unknown option, a disconnected skin).  The command line prints
such an error as one line and exits with status 2; any other exception is a bug and keeps
its traceback.  Each subclass also derives from the builtin it refines (``ValueError``,
``OSError``, ...) so that ``except ValueError`` keeps working for callers of the Python API.
"""

from __future__ import annotations


class WovenskinError(Exception):
    """Something a user can cause and fix; ``str(error)`` is the one-line message."""


class ConfigError(WovenskinError, ValueError):
    """A setting, option or spec string that is unknown, of the wrong type or out of range."""


class DataError(WovenskinError, ValueError):
    """Input data that cannot be used: a corrupt or foreign file, wrong shapes, NaN."""


class DeviceError(WovenskinError, ConnectionError):
    """A skin or robot that cannot be reached, stopped answering or broke its protocol."""


class MissingExtraError(WovenskinError, ImportError):
    """An optional part of wovenskin needs a package that is not installed; the message
    names the extra to install (``wovenskin[ros2]``, ``wovenskin[ur]``)."""
