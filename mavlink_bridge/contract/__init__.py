"""The contract shared by ``sim``, ``autopilot`` and the rest of ``mavlink_bridge`` (SPEC §2).

Plain Python only: it imports neither pymavlink nor any other part of the bridge, so the simulator and
the autopilot depend on it and on nothing else of the bridge (except at their I/O edges).

- ``frames``: conventions and conversions (NED/FRD, Hamilton quaternions w-first, ``Vec3``/``Quat``,
  gravity, the WGS-84 ``LocalNedFrame`` about a geodetic origin).
- ``wire``: the lockstep messages (HIL_SENSOR, HIL_GPS, HIL_STATE_QUATERNION, OBSTACLE_DISTANCE_3D,
  HIL_ACTUATOR_CONTROLS) as frozen dataclasses in SI units.
- ``vehicle_api``: what a ground station can ask of and see from the vehicle (modes, commands, missions,
  setpoints, telemetry snapshot, ``VehicleInterface``).
- ``mav_enums``: MAV_CMD, MAV_FRAME and friends as plain ``IntEnum`` with the common-dialect numbers.
"""
