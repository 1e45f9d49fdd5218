"""Robot backends: one folder per arm (``sim``, ``techman``, ``ur``) behind one interface.

:mod:`wovenskin.robots.base` defines the interface and its types; every backend
implements :class:`~wovenskin.robots.base.Robot`. Commands reach a backend only through
:class:`wovenskin.control.safety.SafetyLayer`.
"""
