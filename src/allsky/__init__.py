"""allsky: an emulator of the 1970s all-sky pointing attitude control system.

The system is the one of US patent 4,012,018 (a sun sensor, a Canopus star
tracker, three strapped-down rate gyros, cold-gas jets, hard-wired electronics
and a small special-purpose computer). A dither scale-factor method is flown
beside it for comparison.
"""

__version__ = "0.1.0"
