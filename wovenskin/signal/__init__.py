"""Signal conditioning: from raw channel values to clean relative-change frames and contacts.

Owns calibration (baseline and per-channel noise), drift tracking, the causal moving
average, contact detection and blob extraction.  The same code runs frame by frame on a
live stream and on a whole recording at once, with identical results.
"""

from wovenskin.signal.calibration import Calibration, calibrate
from wovenskin.signal.conditioner import (
    ConditionedFrames,
    Conditioner,
    LiveConditioner,
    condition_recording,
)
from wovenskin.signal.config import ConditioningConfig
from wovenskin.signal.contacts import (
    Contact,
    ContactDetector,
    DetectorSettings,
    extract_contacts,
)

__all__ = [
    "Calibration",
    "ConditionedFrames",
    "Conditioner",
    "ConditioningConfig",
    "Contact",
    "ContactDetector",
    "DetectorSettings",
    "LiveConditioner",
    "calibrate",
    "condition_recording",
    "extract_contacts",
]
