"""Command-line tools that compose sim and autopilot: ground station, tuner, benchmarks, plots."""
