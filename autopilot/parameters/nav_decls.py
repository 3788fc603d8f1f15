"""Parameters of navigation, commander, land detector and failsafes (SPEC §8, PX4 names).

Declared once here; ``autopilot.param_schema`` aggregates them with the controller's and
the mission's. The commander also reads the mission's ``MIS_CRUISE_SPD`` (cruise speed in
every auto mode), ``MIS_ACC_RAD``/``MIS_ALT_ACC_RAD`` (acceptance) and ``MIS_RTL_ALT`` (RTL
altitude), so each of those has one knob. Speeds and accelerations shape the setpoint generator
(:mod:`autopilot.flight_tasks.setpoints`); the ``LNDMC_*`` ones are the land detector of
:mod:`autopilot.commander.state_machine`; ``COM_*``/``NAV_DLL_*``/``BAT_*``/``GF_*`` are the failsafes of
:mod:`autopilot.safety.failsafe`; ``SYS_FAILURE_EN`` gates :mod:`autopilot.safety.failure_injection`. Failsafe action
values are :class:`autopilot.safety.failsafe.FailsafeAction`.
"""

from __future__ import annotations

from autopilot.parameters.store import ParamSpec

_ACTIONS = "0 none, 1 warn, 2 hold, 3 return, 4 land"


def nav_param_specs() -> list[ParamSpec]:
    """Every parameter owned by commander, setpoints and failsafes, in display order."""
    return [
        # -- takeoff, cruise, landing (setpoint generator limits) ------------------------------
        ParamSpec("MIS_TAKEOFF_ALT", 10.0, 0.5, 500.0, "m", "Default takeoff altitude above home"),
        ParamSpec("MPC_TKO_SPEED", 1.5, 0.3, 5.0, "m/s", "Climb speed during takeoff"),
        ParamSpec("MPC_XY_VEL_MAX", 12.0, 0.5, 30.0, "m/s", "Upper bound for any horizontal speed request"),
        ParamSpec("MPC_Z_VEL_MAX_UP", 3.0, 0.5, 8.0, "m/s", "Maximum climb speed in auto modes"),
        ParamSpec("MPC_Z_VEL_MAX_DN", 1.5, 0.5, 4.0, "m/s", "Maximum descent speed in auto modes"),
        ParamSpec("MPC_LAND_SPEED", 0.7, 0.2, 2.0, "m/s", "Final descent speed when landing"),
        ParamSpec("MPC_LAND_ALT2", 5.0, 0.5, 50.0, "m", "Below this height above home, descend at MPC_LAND_SPEED"),
        ParamSpec("MPC_ACC_HOR", 3.0, 0.5, 10.0, "m/s^2", "Horizontal acceleration limit of the setpoint"),
        ParamSpec("MPC_ACC_UP_AUTO", 3.0, 0.5, 10.0, "m/s^2", "Upward acceleration limit of the setpoint"),
        ParamSpec("MPC_ACC_DN_AUTO", 2.0, 0.5, 10.0, "m/s^2", "Downward acceleration limit of the setpoint"),
        ParamSpec("MPC_JERK_AUTO", 8.0, 1.0, 80.0, "m/s^3", "Jerk limit of the setpoint acceleration"),
        ParamSpec("MPC_YAWRAUTO_MAX", 45.0, 5.0, 360.0, "deg/s", "Yaw rate limit of the yaw setpoint"),
        ParamSpec("MPC_YAW_MODE", 0.0, 0.0, 1.0, "", "Yaw in auto modes: 0 face the target, 1 keep heading"),
        # -- position mode from a joystick (MANUAL_CONTROL; autopilot.flight_tasks.position_control) --------------
        ParamSpec("MPC_VEL_MANUAL", 10.0, 0.5, 30.0, "m/s", "POSCTL: horizontal speed at full stick (capped)"),
        ParamSpec("MPC_HOLD_DZ", 0.1, 0.0, 0.5, "", "POSCTL: stick deadzone (fraction of full stick) of every axis"),
        ParamSpec("COM_RC_LOSS_T", 0.5, 0.1, 35.0, "s", "Joystick silence (wall clock) after which POSCTL holds"),
        # -- return to launch -----------------------------------------------------------------
        ParamSpec("RTL_LAND_DELAY", 0.0, 0.0, 300.0, "s", "Hover above home this long before landing"),
        # -- land detector and arming ---------------------------------------------------------
        ParamSpec("LNDMC_Z_VEL_MAX", 0.5, 0.05, 2.0, "m/s", "Landed: vertical speed below this"),
        ParamSpec("LNDMC_XY_VEL_MAX", 1.5, 0.1, 5.0, "m/s", "Landed: horizontal speed below this"),
        ParamSpec("LNDMC_LOW_T_THR", 0.6, 0.05, 0.95, "", "Landed: collective thrust below this fraction of hover"),
        ParamSpec("LNDMC_TRIG_TIME", 1.0, 0.1, 10.0, "s", "Landed conditions must hold this long"),
        ParamSpec("COM_DISARM_LAND", 1.0, -1.0, 20.0, "s", "Auto-disarm this long after landing (-1 never)"),
        ParamSpec("COM_DISARM_PRFLT", -1.0, -1.0, 60.0, "s", "Auto-disarm if armed without takeoff (-1 never)"),
        ParamSpec("COM_ARM_WO_GPS", 0.0, 0.0, 1.0, "", "1: allow arming without a 3D GPS fix"),
        ParamSpec("MOT_SPIN_IDLE", 0.1, 0.0, 0.3, "", "Motor command while armed on the ground"),
        # -- failsafes ------------------------------------------------------------------------
        ParamSpec("NAV_DLL_ACT", 0.0, 0.0, 4.0, "", f"GCS link loss action: {_ACTIONS}"),
        ParamSpec("COM_DL_LOSS_T", 10.0, 1.0, 300.0, "s", "GCS heartbeat silence (wall clock) that is a loss"),
        ParamSpec("COM_OBL_ACT", 2.0, 2.0, 4.0, "", f"Offboard setpoint loss action: {_ACTIONS}"),
        ParamSpec("COM_OF_LOSS_T", 1.0, 0.2, 60.0, "s", "Offboard setpoint silence (wall clock) that is a loss"),
        ParamSpec("COM_LOW_BAT_ACT", 3.0, 0.0, 4.0, "", f"Low battery action: {_ACTIONS}"),
        ParamSpec("BAT_LOW_THR", 0.15, 0.0, 0.5, "", "Battery fraction that is low (warn)"),
        ParamSpec("BAT_CRIT_THR", 0.07, 0.0, 0.5, "", "Battery fraction that triggers COM_LOW_BAT_ACT"),
        ParamSpec("BAT_HOVER_ENDUR", 1200.0, 10.0, 36000.0, "s", "Battery endurance at hover thrust"),
        ParamSpec("GF_ACTION", 1.0, 0.0, 4.0, "", f"Geofence breach action: {_ACTIONS}"),
        ParamSpec("GF_MAX_HOR_DIST", 0.0, 0.0, 100000.0, "m", "Max horizontal distance from home (0 off)"),
        ParamSpec("GF_MAX_VER_DIST", 0.0, 0.0, 10000.0, "m", "Max height above home (0 off)"),
        # -- sensor failures (autopilot.safety.failure_injection) and sensor-loss failsafes -------------
        ParamSpec("SYS_FAILURE_EN", 0.0, 0.0, 1.0, "", "1: accept MAV_CMD_INJECT_FAILURE (sensor/motor failures)"),
        ParamSpec("COM_POS_FS_DELAY", 5.0, 0.0, 120.0, "s", "GPS lost: dead-reckoning time before COM_POS_LOSS_ACT"),
        ParamSpec("COM_POS_LOSS_ACT", 1.0, 0.0, 1.0, "", "Position loss: 0 warn, 1 land (baro height, no xy control)"),
    ]
