"""From active gesture commands to robot motion: action mapping, motion profiles, safety.

The arbiter's active command becomes a tool- or base-frame twist or a named pose
(:mod:`~wovenskin.control.mapping`), is shaped by acceleration and jerk limits
(:mod:`~wovenskin.control.motion`) and goes through the one safety layer
(:mod:`~wovenskin.control.safety`) to a robot backend.
:mod:`~wovenskin.control.session` runs that loop on a live or replayed skin and
:mod:`~wovenskin.control.trace` writes its per-tick JSONL trace.
"""
