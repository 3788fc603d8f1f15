"""MAVLink 2 framing shared by the lockstep encoder and decoder: ids, message layouts, CRC, headers.

Layouts (ids, CRC extras, field order, struct formats) come from pymavlink's ``ardupilotmega``
dialect; the CRC is ``fastcrc``'s (C speed). The ``_``-prefixed names are internal to
``mavlink_bridge`` (the codec, its decoder and ``frame_writer``).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from fastcrc import crc16 as _crc16
from pymavlink.dialects.v20 import ardupilotmega as _dialect

from mavlink_bridge.contract.wire import (
    GRIPPER_CHANNEL,
    ActuatorCommand,
    GpsSample,
    GroundTruth,
    ObstacleDetection,
    SensorSample,
)

#: HIL_SENSOR.fields_updated for a full sample: accel, gyro, mag (bits 0-8), abs pressure (9),
#: pressure alt (11), temperature (12); no differential pressure (10).
HIL_SENSOR_FIELDS_ALL = 0x1BFF
MAV_FRAME_BODY_FRD = _dialect.MAV_FRAME_BODY_FRD
MAV_TYPE_QUADROTOR = _dialect.MAV_TYPE_QUADROTOR
MAV_AUTOPILOT_PX4 = _dialect.MAV_AUTOPILOT_PX4
#: The system and component ids the simulator sends with (the autopilot is 1/1, SPEC §3).
SIM_SYSTEM_ID = 1
SIM_COMPONENT_ID = _dialect.MAV_COMP_ID_SYSTEM_CONTROL
AUTOPILOT_SYSTEM_ID = 1
AUTOPILOT_COMPONENT_ID = _dialect.MAV_COMP_ID_AUTOPILOT1

_HIL_CONTROLS_COUNT = 16
#: HIL_ACTUATOR_CONTROLS payload (time_usec, flags, controls[16], mode) with only the channels we send as
#: arguments: the motors (0-3) and the gripper; pad bytes are the zero floats of the unused channels.
_ACTUATORS_PAYLOAD = struct.Struct(
    f"<QQ4f{4 * (GRIPPER_CHANNEL - 4)}xf{4 * (_HIL_CONTROLS_COUNT - GRIPPER_CHANNEL - 1)}xB"
)
_UINT16_UNKNOWN = 0xFFFF


@dataclass(frozen=True, slots=True)
class Heartbeat:
    """A HEARTBEAT (the autopilot sends one to start the lockstep, SPEC §4)."""

    mav_type: int = MAV_TYPE_QUADROTOR
    autopilot: int = MAV_AUTOPILOT_PX4
    base_mode: int = 0
    custom_mode: int = 0
    system_status: int = _dialect.MAV_STATE_STANDBY


WireMessage = SensorSample | GpsSample | GroundTruth | ObstacleDetection | ActuatorCommand | Heartbeat


# --- CRC-16/MCRF4XX (X.25, the MAVLink checksum) at C speed -----------------------------------
# checksum = crc(crc_extra byte, crc(header without magic + payload)): two C calls per frame
_crc_mcrf4xx = _crc16.mcrf4xx  # (data, initial=0xFFFF) -> int


# --- message layouts from pymavlink ------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class _Layout:
    msg_id: int
    crc_extra: bytes  # one byte
    payload: struct.Struct  # full MAVLink 2 payload, wire order
    id_lo16: int
    id_hi8: int


def _layout(cls: type) -> _Layout:
    return _Layout(cls.id, bytes((cls.crc_extra,)), cls.unpacker, cls.id & 0xFFFF, cls.id >> 16)


_HEARTBEAT = _layout(_dialect.MAVLink_heartbeat_message)
_HIL_SENSOR = _layout(_dialect.MAVLink_hil_sensor_message)
_HIL_GPS = _layout(_dialect.MAVLink_hil_gps_message)
_HIL_STATE_Q = _layout(_dialect.MAVLink_hil_state_quaternion_message)
_OBSTACLE_3D = _layout(_dialect.MAVLink_obstacle_distance_3d_message)
_HIL_ACTUATORS = _layout(_dialect.MAVLink_hil_actuator_controls_message)
#: crc_extra and full payload length of every message the dialect knows (CRC checks).
_KNOWN: dict[int, tuple[bytes, int]] = {
    msg_id: (bytes((cls.crc_extra,)), cls.unpacker.size) for msg_id, cls in _dialect.mavlink_map.items()
}
#: zero padding that restores a payload MAVLink 2 truncated by k trailing zero bytes: ``_PAD[k]``.
_PAD = tuple(bytes(k) for k in range(256))

_V2_HEADER = struct.Struct("<BBBBBBBHB")  # magic, len, incompat, compat, seq, sys, comp, id lo16, id hi8
_V2_HEADER_LEN = _V2_HEADER.size  # 10
_V2_HEADER_IN = struct.Struct("<xBBxxBBHB")  # what decoding reads: len, incompat, sys, comp, id lo16, id hi8
_V1_HEADER = struct.Struct("<BBBBBB")  # magic, len, seq, sys, comp, id
_V1_HEADER_LEN = _V1_HEADER.size  # 6
_CRC = struct.Struct("<H")
_V2_MAGIC = 0xFD
_V1_MAGIC = 0xFE
_IFLAG_SIGNED = 0x01
_SIGNATURE_LEN = 13
