"""The simulator: world, physics, sensors, the lockstep server and the fleet."""

import mavlink_bridge.contract.jit_cache  # noqa: F401 (first: numba's cache directory, before any kernel)
