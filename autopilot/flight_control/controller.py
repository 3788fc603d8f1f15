"""Flight control: the commander's target -> reference -> motor commands (PX4's mc_pos_control + mc_att_control).

- Reads: the vehicle state (about the estimator origin), the commander's :class:`NavTarget`, the controller and
  setpoint parameters, the payload state, an optional avoidance :class:`ReferenceOverride`.
- Owns: the :class:`SetpointGenerator` (speed, acceleration and jerk limits), the NLVG-PID
  :class:`CascadeController` (paper eq. 11) with its gains and limits, the mass it flies, the last thrust.
- Emits: the :class:`Reference` of the step and the motor commands (cascade output kept for bookkeeping).
"""

from __future__ import annotations

import math

from autopilot.control.airframe import Airframe
from autopilot.control.cascade import GRAVITY_M_S2, CascadeController, SingleStep
from autopilot.control.param_decls import gains_from_params, limits_from_params
from autopilot.estimation import VehicleState
from autopilot.flight_tasks.setpoints import NavTarget, Reference, SetpointGenerator, SetpointLimits, TargetKind
from autopilot.navigation import ReferenceOverride
from autopilot.parameters.store import ParamStore

#: The parameters the setpoint generator reads.
SETPOINT_PARAMS = ("MPC_ACC_HOR", "MPC_ACC_UP_AUTO", "MPC_ACC_DN_AUTO", "MPC_JERK_AUTO", "MPC_YAWRAUTO_MAX")

Motors = tuple[float, float, float, float]


class FlightControl:
    """Reference generation and the cascade for one vehicle; pure (no clock or I/O)."""

    def __init__(self, params: ParamStore, airframe: Airframe, dt_s: float = 0.004) -> None:
        self.params = params
        self.airframe = airframe
        self.dt_s = dt_s
        self.setpoints = SetpointGenerator(self._setpoint_limits())
        values = params.values()
        self.gains = gains_from_params(values)
        self.limits = limits_from_params(values)
        self.payload_released = False  # what the cascade's mass currently assumes
        self.hover_thrust_n = airframe.mass_kg * GRAVITY_M_S2
        self.thrust_ratio = 0.0  # last collective thrust / hover thrust
        self.reference = self.setpoints.reference()
        self._last_kind = TargetKind.IDLE
        self.controller = self._warm_up()

    def _warm_up(self) -> CascadeController:
        """Build the cascade and run it once now: its first call JIT-loads the numba kernels (seconds),
        which must not happen inside the lockstep, where the sim would declare the autopilot lost."""
        controller = CascadeController(self.airframe, self.gains, 1, self.dt_s, self.limits)
        zero = (0.0, 0.0, 0.0)
        controller.update_position_single(zero, zero, (1.0, 0.0, 0.0, 0.0), zero, zero, zero, zero, 0.0)
        controller.reset()
        return controller

    # ------------------------------------------------------------------ parameters
    def _setpoint_limits(self) -> SetpointLimits:
        p = self.params.get
        return SetpointLimits(
            acc_xy_m_s2=p("MPC_ACC_HOR"),
            acc_up_m_s2=p("MPC_ACC_UP_AUTO"),
            acc_down_m_s2=p("MPC_ACC_DN_AUTO"),
            jerk_m_s3=p("MPC_JERK_AUTO"),
            yaw_rate_rad_s=math.radians(p("MPC_YAWRAUTO_MAX")),
        )

    def apply_setpoint_params(self) -> None:
        self.setpoints.limits = self._setpoint_limits()

    def apply_controller_params(self) -> str | None:
        """Gains change live (integrators kept); a limit change rebuilds the cascade with its state carried over.

        Inconsistent values (e.g. δ2 <= δ1) leave the gains in force; returns why (None when applied).
        """
        values = self.params.values()
        try:
            gains = gains_from_params(values)
            limits = limits_from_params(values)
        except ValueError as exc:
            return f"Controller parameters not applied: {exc}"
        self.gains = gains
        if limits != self.limits:
            self.limits = limits
            self.controller = self._rebuild(self.controller)
        else:
            self.controller.set_gains(gains)
        return None

    def _rebuild(self, old: CascadeController | None) -> CascadeController:
        """A cascade with the gains, limits and step in force; integrators, held outputs and mass carried over
        from ``old`` so a limit change is bumpless (the state layout does not depend on the limits)."""
        controller = CascadeController(self.airframe, self.gains, 1, self.dt_s, self.limits)
        if old is not None:
            controller.load_state(old.state_array())
        controller.set_mass_kg(self._mass_kg())
        return controller

    def _mass_kg(self) -> float:
        """Nominal mass, minus ``PLD_MASS_KG`` once the payload is released (at least 10 % of nominal)."""
        mass = self.airframe.mass_kg
        if self.payload_released:
            return max(mass - self.params.get("PLD_MASS_KG"), 0.1 * mass)
        return mass

    def set_payload_released(self, released: bool) -> None:
        """Tell the cascade the mass it now carries (gripper release / grab, PLD_MASS_KG changes)."""
        self.payload_released = released
        mass = self._mass_kg()
        self.hover_thrust_n = mass * GRAVITY_M_S2
        self.controller.set_mass_kg(mass)

    @property
    def hover_fraction(self) -> float:
        """Hover thrust as a fraction of the maximum (to turn thrust_ratio into throttle)."""
        return self.hover_thrust_n / (4.0 * self.airframe.max_rotor_thrust_n)

    # ------------------------------------------------------------------ the step
    def idle(self, state: VehicleState, target: NavTarget, armed: bool, dt_s: float) -> Motors:
        """No flight: the reference follows the vehicle; motors at idle when armed, off when not."""
        self.dt_s = dt_s
        self._last_kind = TargetKind.IDLE
        self.reference = self.setpoints.update(target, self.dt_s, state.pos_ned_m)
        self.thrust_ratio = 0.0
        idle = self.params.get("MOT_SPIN_IDLE") if armed else 0.0
        return (idle, idle, idle, idle)

    def reference_for(self, state: VehicleState, target: NavTarget, dt_s: float) -> Reference:
        """The reference of this step (``dt_s`` after the last) toward ``target``, restarted at the vehicle when
        flight begins."""
        self.dt_s = dt_s
        controller = self.controller
        if abs(controller.dt_s - self.dt_s) > 1e-9:
            controller = self.controller = self._rebuild(controller)
        gen = self.setpoints
        if self._last_kind is TargetKind.IDLE:
            gen.reset(state.pos_ned_m, state.vel_ned_m_s, state.yaw_rad)
            controller.reset()
        self._last_kind = target.kind
        self.reference = ref = gen.update(target, self.dt_s, state.pos_ned_m)
        return ref

    def override(self, override: ReferenceOverride) -> Reference:
        """Replace this step's position, velocity and acceleration reference (the avoidance detour)."""
        self.setpoints.set_reference(override.pos_ned_m, override.vel_ned_m_s, override.acc_ned_m_s2)
        ref = self.reference
        self.reference = ref = Reference(override.pos_ned_m, override.vel_ned_m_s, override.acc_ned_m_s2, ref.yaw_rad)
        return ref

    def control(self, state: VehicleState) -> SingleStep:
        """The cascade on this step's reference: motor commands, thrust and errors (:data:`SingleStep`)."""
        ref = self.reference
        out = self.controller.update_single(  # update_position_single without its Python frame
            state.pos_ned_m,
            state.vel_ned_m_s,
            state.q_ned_frd,
            state.rate_frd_rad_s,
            ref.pos_ned_m,
            ref.vel_ned_m_s,
            ref.acc_ned_m_s2,
            ref.yaw_rad,
        )
        self.thrust_ratio = out[4] / self.hover_thrust_n
        return out
