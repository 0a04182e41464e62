"""The simulation: compiled frame loop, mission state and driver, telemetry."""
