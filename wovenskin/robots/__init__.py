"""Robot backends: one folder per arm (``sim``, ``techman``, ``ur``) behind one interface.

:mod:`wovenskin.robots.base` defines the interface and its types; every backend
implements :class:`~wovenskin.robots.base.Robot` and declares its robot spec in its
folder's ``config.py``; :mod:`wovenskin.robots.registry` lists the backends, one line
each. Commands reach a backend only through :class:`wovenskin.control.safety.SafetyLayer`.
"""
