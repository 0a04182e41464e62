"""Studies built on missions: the calibration comparison, Monte Carlo campaigns, loop analysis."""
