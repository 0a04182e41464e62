"""Studies: the calibration comparison, Monte Carlo campaigns, loop analysis.

Each is built on missions.
"""
