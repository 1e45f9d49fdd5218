"""The quantitative ranges of ``docs/gestures.md`` as named constants.

Every performer in :mod:`wovenskin.sim.valid` and :mod:`wovenskin.sim.invalid` draws its
trial parameters inside these ranges, and the simulator's tests check the rendered tracks
against the same constants, so the contract lives in exactly one place in code.  Ranges
are ``(low, high)`` tuples, lengths in millimetres, times in seconds, forces in newtons.
"""

from __future__ import annotations

DWELL_S = 0.1
"""A gesture must be recognised this long before it becomes actionable."""

SWIPE_TRAVEL_MM = (35.0, 90.0)
"""Distance a swipe travels (less where the skin is too small)."""

SWIPE_MEAN_SPEED_MM_S = (70.0, 250.0)
"""Mean speed of a swipe's characteristic motion."""

SWIPE_PEAK_SPEED_MM_S = 480.0
"""Upper bound of a swipe's peak speed ("peaks up to about 450 mm/s")."""

SWIPE_MAX_OFF_AXIS_DEG = 10.0
"""Largest angle between a swipe's chord and its nominal direction."""

SWIPE_FLICK_LIFT_S = (0.01, 0.04)
"""A flicked swipe starts lifting this long before its motion ends, with no rest (issue 22:
a flick lifts as soon as, or just before, the motion ends; the lift ramp then covers the end
of the deceleration)."""

SWIPE_MAX_BOW = 0.06
"""Largest sideways bow of a swipe path, as a fraction of its travel ("slightly curved")."""

PAIR_SPACING_MM = (15.0, 26.0)
"""Distance between the two fingertips of a two-finger swipe."""

CIRCLE_PAIR_SPACING_MM = (13.0, 20.0)
"""Distance between the two fingertips of a circle."""

CIRCLE_RADIUS_MM = (14.0, 26.0)
"""Radius of the circle traced by the centroid of the two fingertips."""

CIRCLE_TURNS = (1.0, 2.5)
CIRCLE_RATE_HZ = (1.0, 2.6)
"""Mean angular rate of a circle, in turns per second."""

PINCH_2F_START_MM = (45.0, 75.0)
PINCH_2F_END_MM = (10.0, 20.0)
"""Fingertip distance at the start and end of ``pinch_in_2f``."""

PINCH_5F_SPREAD_MM = (28.0, 42.0)
PINCH_5F_BUNCHED_MM = (6.0, 12.0)
"""Radius of the five fingertips around their centroid, spread and bunched."""

PUSH_RAMP_S = (0.15, 0.4)
"""Time over which a push's force rises."""

PUSH_SMOOTH_SHARE = 0.35
"""Share of pushes made as one smooth press: no distinct landing, the force rises
continuously from zero over ``PUSH_RAMP_S`` (issue 22: people who press in one motion; 3 of
12 such pushes were taken by a model trained only on pushes that land, then ramp)."""

PUSH_SMOOTH_START = 0.03
"""A smooth press starts at this share of its held force (a fingertip's first touch)."""

PUSH_MAX_MOTION_MM = 3.0
"""A push holds with less motion than this."""

CONTACT_RAMP_S = (0.01, 0.05)
"""Landing and lift-off ramps of a contact."""

FINGERTIP_PATCH_MM = (8.0, 14.0)
"""Width of a fingertip contact patch; it grows with pressure."""

REST_S = (0.0, 1.5)
"""Fingers often rest on the skin this long after the characteristic motion."""

SKIN_MARGIN_MM = 7.0
"""Fingertip centres of valid gestures stay this far inside the sensing area (a patch radius)."""
