"""The land detector (PX4's ``MulticopterLandDetector`` in spirit): has the vehicle touched down?

Reads the estimate's velocity, the last collective thrust (fraction of hover) and the LNDMC_* parameters;
says "landed" once the vehicle has been slow and at low thrust for LNDMC_TRIG_TIME of sim time. A landing
without horizontal position (``blind``, the GPS-loss descent) ignores the dead-reckoned horizontal speed.
"""

from __future__ import annotations

import math

from autopilot.estimation import VehicleState
from autopilot.parameters.store import ParamStore


class LandDetector:
    """Touchdown: vertical speed < LNDMC_Z_VEL_MAX, horizontal < LNDMC_XY_VEL_MAX, thrust < LNDMC_LOW_T_THR of
    hover, all for LNDMC_TRIG_TIME (sim time)."""

    def __init__(self, params: ParamStore) -> None:
        self.params = params
        self._version = -1
        self._limits = (0.0, 0.0, 0.0, 0.0)
        self._quiet_since_us: int | None = None

    def _current_limits(self) -> tuple[float, float, float, float]:
        """LNDMC_Z_VEL_MAX, LNDMC_XY_VEL_MAX, LNDMC_LOW_T_THR, LNDMC_TRIG_TIME (µs), cached per parameter version."""
        version = self.params.version
        if version != self._version:
            p = self.params.get
            self._version = version
            self._limits = (
                p("LNDMC_Z_VEL_MAX"),
                p("LNDMC_XY_VEL_MAX"),
                p("LNDMC_LOW_T_THR"),
                p("LNDMC_TRIG_TIME") * 1e6,
            )
        return self._limits

    @property
    def quiet_since_us(self) -> int | None:
        """Sim time since when the vehicle has been quiet (None: it is not)."""
        return self._quiet_since_us

    def reset(self) -> None:
        """Forget the quiet time so far (takeoff, arming)."""
        self._quiet_since_us = None

    def landed(self, state: VehicleState, thrust_ratio: float, blind: bool = False) -> bool:
        """True once the vehicle has been quiet for LNDMC_TRIG_TIME."""
        z_vel_max, xy_vel_max, low_thrust, trig_us = self._current_limits()
        vn, ve, vd = state.vel_ned_m_s
        xy_quiet = blind or math.hypot(vn, ve) < xy_vel_max  # blind: the xy velocity is dead reckoned
        if not (abs(vd) < z_vel_max and xy_quiet and thrust_ratio < low_thrust):
            self._quiet_since_us = None
            return False
        if self._quiet_since_us is None:
            self._quiet_since_us = state.time_us
        return state.time_us - self._quiet_since_us >= trig_us
