"""wovenskin: gesture control of a robot arm through a woven capacitive tactile skin.

Subpackages, one per stage of the pipeline:

- :mod:`wovenskin.skin` -- skin layout, frames, wire protocol and sources (serial, sim, replay);
- :mod:`wovenskin.signal` -- calibration, baseline tracking, filtering, contact detection;
- :mod:`wovenskin.sim` -- the physically motivated simulated skin and simulated people;
- :mod:`wovenskin.recording` -- the native recording format, interchange formats, replay;
- :mod:`wovenskin.ui` -- terminal views and guided sessions;
- :mod:`wovenskin.bench` -- benchmarks behind ``wovenskin bench``.
"""

__version__ = "0.1.0"
