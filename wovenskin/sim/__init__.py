"""The simulated skin: capacitive physics, simulated people performing gestures, streams.

The default source of wovenskin when no hardware is attached.
"""
