"""The only code that knows MAVLink, by role: ``lockstep`` (the sim <-> autopilot link), ``gcs_server`` (the vehicle
side of the GCS/API links), ``gcs_client`` (the ground station), ``wire`` (codec, links, signing) and ``contract``.

``contract`` imports no pymavlink and may be used by sim and autopilot freely.
"""

import mavlink_bridge.contract.jit_cache  # noqa: F401 (first: numba's cache directory, before any kernel)
