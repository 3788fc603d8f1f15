"""The per-step row layouts of the Rerun telemetry: scalar columns, the series they make, decimation, batch sizes.

Angles are in rad while buffered, degrees once flushed.
"""

from __future__ import annotations

from autopilot.control.cascade import ControlSample
from autopilot.telemetry import entities as ent

# ---- scalar row layout (angles in rad while buffered, degrees once flushed) ----
C_POS, C_POS_SP, C_POS_ERR, C_ATT = 0, 3, 6, 9
C_MOTOR, C_BAT_PCT, C_BAT_V, C_CLEARANCE, C_SEQ = 12, 16, 17, 18, 19
# the controller block (CascadeDiagnostics, NaN while the controller is off)
C_ATT_ERR, C_ATT_SP = 20, 23
C_KP, C_KI, C_KD = 26, 32, 38  # 6 channels each: x, y, z, roll, pitch, yaw
C_THRUST, C_TORQUE = 44, 45
N_COLS = 48
N_CTRL = N_COLS - C_ATT_ERR  # the ControlSample block
assert N_CTRL == ControlSample.SIZE, "the control columns mirror autopilot.control.cascade.ControlSample"
ANGLE_COLS = (slice(C_ATT, C_ATT + 3), slice(C_ATT_ERR, C_ATT_SP + 3))

#: (entity path, first column, width, series names)
SERIES: tuple[tuple[str, int, int, tuple[str, ...]], ...] = (
    (ent.POS_NED, C_POS, 3, ent.XYZ),
    (ent.POS_SP_NED, C_POS_SP, 3, tuple(f"{n} sp" for n in ent.XYZ)),
    (ent.POS_ERR_NED, C_POS_ERR, 3, ent.XYZ),
    (ent.ATT_ERR, C_ATT_ERR, 3, ent.RPY),
    (ent.ATT, C_ATT, 3, ent.RPY),
    (ent.ATT_SP, C_ATT_SP, 3, tuple(f"{n} sp" for n in ent.RPY)),
    (ent.gain_path("position", "kp"), C_KP, 3, ("k_p x", "k_p y", "k_p z")),
    (ent.gain_path("attitude", "kp"), C_KP + 3, 3, ("k_p roll", "k_p pitch", "k_p yaw")),
    (ent.gain_path("position", "ki"), C_KI, 3, ("k_i x", "k_i y", "k_i z")),
    (ent.gain_path("attitude", "ki"), C_KI + 3, 3, ("k_i roll", "k_i pitch", "k_i yaw")),
    (ent.gain_path("position", "kd"), C_KD, 3, ("k_d x", "k_d y", "k_d z")),
    (ent.gain_path("attitude", "kd"), C_KD + 3, 3, ("k_d roll", "k_d pitch", "k_d yaw")),
    (ent.MOTORS, C_MOTOR, 4, ent.MOTOR_NAMES),
    (ent.THRUST, C_THRUST, 1, ("thrust (N)",)),
    (ent.TORQUE, C_TORQUE, 3, ("roll torque (N·m)", "pitch torque (N·m)", "yaw torque (N·m)")),
    (ent.BATTERY_REMAINING, C_BAT_PCT, 1, ("charge (%)",)),
    (ent.BATTERY_VOLTAGE, C_BAT_V, 1, ("voltage (V)",)),
    (ent.CLEARANCE, C_CLEARANCE, 1, ("clearance (m)",)),
    (ent.MISSION_SEQ, C_SEQ, 1, ("current item",)),
)

#: Series flushed at every N-th control step only (250 Hz / N); the rest at every step.
DECIMATION: dict[str, int] = {
    ent.POS_SP_NED: 5,
    ent.ATT_SP: 5,
    **{ent.gain_path(loop, term): 5 for loop in ("position", "attitude") for term in ("kp", "ki", "kd")},
    ent.THRUST: 5,
    ent.TORQUE: 5,
    ent.CLEARANCE: 10,
    ent.BATTERY_REMAINING: 50,
    ent.BATTERY_VOLTAGE: 50,
    ent.MISSION_SEQ: 50,
}

#: Batch sizes (control steps) and trail segment lengths (3D samples): a file wants few large chunks,
#: a live viewer wants to see the data within seconds.
SAVE_BATCH_ROWS, SAVE_TRAIL_POINTS = 30_000, 3000
LIVE_BATCH_ROWS, LIVE_TRAIL_POINTS = 1000, 125

# ---- 3D row layout ----
D_POS, D_QUAT, D_SP = 0, 3, 7  # quaternion stored x, y, z, w (Rerun order)
N_3D = 10
