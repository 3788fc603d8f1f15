"""The typed wire contract between simulator and autopilot (SPEC §4).

These frozen dataclasses are what ``sim`` and ``autopilot`` see; only the codec in
``mavlink_bridge`` turns them into MAVLink messages. Fields are SI with the frame in
the name (``_ned``, ``_frd``); non-SI values carry their unit (``_us``, ``_deg``, ``_hpa``).

Message mapping (PX4 simulator_mavlink compatible):

============================  ==========================  ==================
dataclass                     MAVLink message             direction
============================  ==========================  ==================
``SensorSample``              HIL_SENSOR                  sim → autopilot
``GpsSample``                 HIL_GPS                     sim → autopilot
``GroundTruth``               HIL_STATE_QUATERNION        sim → autopilot
``ObstacleDetection``         OBSTACLE_DISTANCE_3D        sim → autopilot
``ActuatorCommand``           HIL_ACTUATOR_CONTROLS       autopilot → sim
============================  ==========================  ==================
"""

from __future__ import annotations

from dataclasses import MISSING, dataclass, fields
from enum import IntEnum
from typing import TypeVar

from mavlink_bridge.contract.frames import Quat, Vec3

_T = TypeVar("_T")


def fast_frozen_init(cls: type[_T]) -> type[_T]:
    """Give a ``@dataclass(frozen=True, slots=True)`` a cheaper ``__init__`` with the same signature.

    The generated frozen ``__init__`` calls ``object.__setattr__(self, name, value)`` per field; this one
    calls each slot's member descriptor directly (about half the cost), so the per-step messages stay
    cheap; ``tests/mavlink_bridge/contract/test_wire_fast_init.py`` checks the contract is kept.
    Frozen semantics (``FrozenInstanceError`` on assignment), ``eq``, ``hash``, ``repr`` and
    ``dataclasses.replace`` are unchanged. Only for classes without ``__post_init__`` or default factories.
    """
    if "__post_init__" in cls.__dict__ or not cls.__dataclass_params__.frozen:  # type: ignore[attr-defined]
        raise TypeError(f"{cls.__name__}: fast_frozen_init needs a frozen dataclass without __post_init__")
    params, body = [], []
    env: dict[str, object] = {}
    for i, f in enumerate(fields(cls)):  # type: ignore[arg-type]
        if f.default_factory is not MISSING:
            raise TypeError(f"{cls.__name__}.{f.name}: fast_frozen_init does not support default factories")
        if f.default is MISSING:
            params.append(f.name)
        else:
            env[f"_d{i}"] = f.default
            params.append(f"{f.name}=_d{i}")
        env[f"_s{i}"] = cls.__dict__[f.name].__set__  # the slot's member descriptor
        body.append(f"    _s{i}(self, {f.name})")
    source = f"def __init__(self, {', '.join(params)}):\n" + "\n".join(body or ["    pass"]) + "\n"
    namespace: dict[str, object] = {}
    exec(source, env, namespace)
    init = namespace["__init__"]
    init.__qualname__ = f"{cls.__qualname__}.__init__"  # type: ignore[attr-defined]
    init.__doc__ = cls.__init__.__doc__
    cls.__init__ = init  # type: ignore[misc]
    return cls


#: HIL_ACTUATOR_CONTROLS channels 0..3 are the motors in PX4 quad-x order:
#: 1 front-right (CCW), 2 rear-left (CCW), 3 front-left (CW), 4 rear-right (CW).
MOTOR_CHANNELS = (0, 1, 2, 3)
#: HIL_ACTUATOR_CONTROLS channel that commands the payload gripper:
#: value >= 0.5 means "release" (the sim drops the payload mass), below means "hold".
GRIPPER_CHANNEL = 8
#: HIL_ACTUATOR_CONTROLS.flags bit 0: the sender runs in lockstep (PX4 convention).
ACTUATOR_FLAG_LOCKSTEP = 1
#: HIL_ACTUATOR_CONTROLS.mode bit that means "armed" (MAV_MODE_FLAG_SAFETY_ARMED).
ACTUATOR_MODE_ARMED = 128


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class SensorSample:
    """IMU, magnetometer and barometer at one control step (HIL_SENSOR)."""

    time_us: int
    accel_frd_m_s2: Vec3  # specific force, body FRD
    gyro_frd_rad_s: Vec3  # angular rate, body FRD
    mag_frd_gauss: Vec3  # magnetic field, body FRD
    abs_pressure_hpa: float
    pressure_alt_m: float
    temperature_degc: float


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class GpsSample:
    """A GNSS fix (HIL_GPS, 10 Hz). The codec carries lat/lon as degE7 on the wire."""

    time_us: int
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    vel_ned_m_s: Vec3
    eph_m: float
    epv_m: float
    fix_type: int  # 3 = 3D fix
    satellites_visible: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class GroundTruth:
    """The true vehicle state (HIL_STATE_QUATERNION): logging and the "truth" estimator."""

    time_us: int
    q_ned_frd: Quat  # Hamilton, w first, body FRD → NED
    rate_frd_rad_s: Vec3
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    vel_ned_m_s: Vec3
    accel_frd_m_s2: Vec3  # specific force, body FRD


class ObstacleShape(IntEnum):
    """What kind of obstacle a detection reports (carried in OBSTACLE_DISTANCE_3D.type)."""

    UNKNOWN = 0
    SPHERE = 1
    CYLINDER = 2
    BOX = 3


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class ObstacleDetection:
    """One sensed obstacle (OBSTACLE_DISTANCE_3D): its nearest surface point.

    ``pos_frd_m`` is the nearest sensed surface point relative to the vehicle in body FRD;
    ``radius_m`` is the sensed extent about that point (0 when unknown).
    """

    time_us: int
    obstacle_id: int
    pos_frd_m: Vec3
    radius_m: float
    shape: ObstacleShape = ObstacleShape.UNKNOWN


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class ActuatorCommand:
    """The autopilot's answer to one SensorSample (HIL_ACTUATOR_CONTROLS).

    ``motor_cmd`` is in [0, 1] per motor (PX4 quad-x order); the simulator maps it
    linearly to commanded rotor speed ``omega_cmd = motor_cmd · omega_max``.
    ``time_us`` echoes the SensorSample it answers (the lockstep frame id).
    """

    time_us: int
    motor_cmd: tuple[float, float, float, float]
    armed: bool
    gripper_release: bool = False
    lockstep: bool = True
