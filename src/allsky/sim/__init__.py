"""The simulation: the compiled frame loop, the mission state and driver, telemetry."""
