"""The autopilot: estimator, commander, mission, planner, control cascade, telemetry."""

import mavlink_bridge.contract.jit_cache  # noqa: F401 (first: numba's cache directory, before any kernel)
