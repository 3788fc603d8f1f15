"""Smooth position setpoints toward a navigation target, within speed, acceleration and jerk limits.

The commander says *where* to go (:class:`NavTarget`); :class:`SetpointGenerator` says how
the reference moves there, one control step at a time, as the trajectory the cascade
tracks: ``pos_sp_ned``, ``vel_sp_ned`` and the acceleration feed-forward ``acc_sp_ned``
(paper eq. 11, ``U_x = ẍ_desire + …``).

Per step (horizontal plane and vertical axis shaped separately, as PX4 does):

1. desired velocity toward the target with a braking profile
   ``v_des = min(v_max, −a·T + sqrt((a·T)² + 2·a·d), K_APPROACH·d)`` (``d`` = remaining
   distance, ``T`` = :data:`BRAKE_LAG_S`, the time the jerk-limited reference needs to start
   braking), so the reference stops at the target within the acceleration limit;
2. desired acceleration toward ``v_des`` with its own jerk-aware profile
   ``|a_des| = min(a_max, sqrt(2·j_max·|Δv|), |Δv|/TAU_VEL_S)``, so the velocity does not
   overshoot ``v_des`` (hence never exceeds the speed limit) while the acceleration ramps down;
3. the acceleration moves toward it by at most ``j_max·dt`` (jerk limit);
4. ``v_sp`` and ``pos_sp`` integrate it (semi-implicit Euler).

``LAND`` targets descend at a fixed speed instead of stopping, over the spot only: while the reference is more
than :data:`LAND_ALIGN_M` from the spot horizontally (a landing that was pushed aside, by traffic or a detour),
it holds its height and goes back first, descending again as it comes within half that (so it never flies
sideways near the ground, nor touches down moving); the reference is kept at
most :data:`LAND_MAX_LEAD_M` below the vehicle so that, on the ground, the controller asks
for less-than-hover thrust (what the land detector looks for) without winding up. ``DESCEND``
(landing without a horizontal position) descends the same way with no position control: the horizontal
position reference stays on the vehicle (no position error, ever) while the velocity reference brakes to
``vel_ned_m_s`` (zero) within the acceleration and jerk limits, so the cascade stops the vehicle on its
(dead-reckoned) velocity and then holds its attitude level with the integrators' wind trim.

``VELOCITY`` targets (OFFBOARD velocity setpoints, POSCTL sticks) replace step 1 by the commanded velocity within the
speed limits; the position reference integrates it but stays within :data:`VELOCITY_MAX_LEAD_M` of the
vehicle, so a vehicle that cannot follow (the ground, saturation) is not pulled by a runaway reference.
A yaw rate (``yaw_rate_rad_s``, when no yaw is given) turns the heading reference at that rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from mavlink_bridge.contract.wire import Vec3, fast_frozen_init

#: Slope of the final approach, 1/s: ``v_des <= K_APPROACH · distance``.
K_APPROACH = 1.0
#: Reaction time (s) budgeted in the braking profile for the jerk-limited deceleration ramp.
BRAKE_LAG_S = 0.5
#: Time constant (s) of the velocity reference's pull toward ``v_des``.
TAU_VEL_S = 0.3
#: In LAND, the reference stays at most this far below the vehicle (m).
LAND_MAX_LEAD_M = 1.0
#: A LAND reference farther than this from the spot horizontally does not descend (m); full descent within half.
LAND_ALIGN_M = 2.0
#: For VELOCITY targets, the position reference stays at most this far from the vehicle (m, horizontal and
#: vertical separately).
VELOCITY_MAX_LEAD_M = 2.0


class TargetKind(Enum):
    """What the vehicle is asked to do."""

    IDLE = "idle"  # armed or not, on the ground: motors idle, controller off
    POSITION = "position"  # reach ``pos_ned_m`` and hold it
    LAND = "land"  # hold xy of ``pos_ned_m``, descend at ``speed_down_m_s`` until touchdown
    VELOCITY = "velocity"  # fly at ``vel_ned_m_s`` (within the speed limits); ``pos_ned_m`` is not used
    DESCEND = "descend"  # no position control: brake to ``vel_ned_m_s``, descend at ``speed_down_m_s``


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class NavTarget:
    """A navigation target: where to go and how fast (NED about the local origin, SI)."""

    kind: TargetKind
    pos_ned_m: Vec3 = (0.0, 0.0, 0.0)
    yaw_rad: float = math.nan  # NaN: keep the current yaw setpoint
    speed_xy_m_s: float = 5.0
    speed_up_m_s: float = 3.0
    speed_down_m_s: float = 1.5
    vel_ned_m_s: Vec3 = (0.0, 0.0, 0.0)  # VELOCITY and DESCEND (horizontal part only)
    yaw_rate_rad_s: float = math.nan  # VELOCITY only, used when ``yaw_rad`` is NaN (NaN: keep the heading)


@dataclass(frozen=True, slots=True)
class SetpointLimits:
    """Acceleration, jerk and yaw-rate limits of the reference (MPC_ACC_*, MPC_JERK_AUTO, MPC_YAWRAUTO_MAX)."""

    acc_xy_m_s2: float = 3.0
    acc_up_m_s2: float = 3.0
    acc_down_m_s2: float = 2.0
    jerk_m_s3: float = 8.0
    yaw_rate_rad_s: float = math.radians(45.0)


def _approach_speed(distance_m: float, v_max: float, acc_max: float) -> float:
    a_t = acc_max * BRAKE_LAG_S
    return min(v_max, math.sqrt(a_t * a_t + 2.0 * acc_max * distance_m) - a_t, K_APPROACH * distance_m)


def _accel_toward(dv: float, acc_max: float, jerk_max: float) -> float:
    """Magnitude of the acceleration that closes a velocity gap ``dv >= 0`` without overshoot."""
    return min(acc_max, math.sqrt(2.0 * jerk_max * dv), dv / TAU_VEL_S)


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Reference:
    """The position controller's reference at one step: NED about the estimator origin, yaw (rad)."""

    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    acc_ned_m_s2: Vec3
    yaw_rad: float


class SetpointGenerator:
    """A jerk-limited reference that flies toward :class:`NavTarget` s; state is scalars (no allocation).

    Attributes ``pos_ned``, ``vel_ned``, ``acc_ned`` (lists of 3 floats, written in place)
    and ``yaw_rad`` are the reference after the latest :meth:`update`.
    """

    def __init__(self, limits: SetpointLimits | None = None) -> None:
        self.limits = limits or SetpointLimits()
        self.pos_ned = [0.0, 0.0, 0.0]
        self.vel_ned = [0.0, 0.0, 0.0]
        self.acc_ned = [0.0, 0.0, 0.0]
        self.yaw_rad = 0.0
        self._version = 0  # counts changes of the reference (update, reset, set_reference)
        self._prepared: tuple[object, ...] | None = None  # prepare()'s inputs and result

    def reset(self, pos_ned: Vec3, vel_ned: Vec3, yaw_rad: float) -> None:
        """Restart the reference at the vehicle's state (at takeoff, or after the controller was off)."""
        self.pos_ned[:] = pos_ned
        self.vel_ned[:] = vel_ned
        self.acc_ned[:] = (0.0, 0.0, 0.0)
        self.yaw_rad = yaw_rad
        self._version += 1

    def set_reference(self, pos_ned: Vec3, vel_ned: Vec3, acc_ned: Vec3) -> None:
        """Override position, velocity and acceleration (e.g. the avoidance detour); use this, not the lists."""
        self.pos_ned[:] = pos_ned
        self.vel_ned[:] = vel_ned
        self.acc_ned[:] = acc_ned
        self._version += 1

    def prepare(self, target: NavTarget, dt_s: float) -> None:
        """Compute the next :meth:`update`'s position, velocity and acceleration ahead of time (the runner calls
        this after answering the sim); ``update`` uses them when its target has the same kind, position and
        speed objects, ``dt_s`` and limits are the same and the reference did not change since: the same floats
        as computing them then (they depend on nothing else), so a step with the same target costs less."""
        if target.kind is TargetKind.IDLE or target.kind is TargetKind.VELOCITY or target.kind is TargetKind.DESCEND:
            self._prepared = None  # VELOCITY, DESCEND: the reference is set about the vehicle in update()
            return
        self._prepared = (
            self._version,
            target.kind,
            target.pos_ned_m,
            target.speed_xy_m_s,
            target.speed_up_m_s,
            target.speed_down_m_s,
            dt_s,
            self.limits,
            self._next_reference(target, dt_s),
        )

    def reference(self) -> Reference:
        """The reference in force (after the latest update, reset or override), as a frozen message."""
        p, v, a = self.pos_ned, self.vel_ned, self.acc_ned
        return Reference((p[0], p[1], p[2]), (v[0], v[1], v[2]), (a[0], a[1], a[2]), self.yaw_rad)

    def update(self, target: NavTarget, dt_s: float, vehicle_pos_ned: Vec3) -> Reference:
        """Advance the reference by ``dt_s`` toward ``target``; returns it."""
        kind = target.kind
        if kind is TargetKind.IDLE:
            self.reset(vehicle_pos_ned, (0.0, 0.0, 0.0), self.yaw_rad)
            return self.reference()
        prep = self._prepared
        if (
            prep is not None
            and prep[0] == self._version
            and prep[1] is kind
            and prep[2] is target.pos_ned_m
            and prep[3] is target.speed_xy_m_s
            and prep[4] is target.speed_up_m_s
            and prep[5] is target.speed_down_m_s
            and prep[6] == dt_s
            and prep[7] is self.limits
        ):
            a0, a1, a2, v0, v1, v2, p0, p1, p2 = prep[8]  # type: ignore[misc]
        else:
            a0, a1, a2, v0, v1, v2, p0, p1, p2 = self._next_reference(target, dt_s)
        self._prepared = None
        self._version += 1
        pos = self.pos_ned
        self.acc_ned[0], self.acc_ned[1], self.acc_ned[2] = a0, a1, a2
        self.vel_ned[0], self.vel_ned[1], self.vel_ned[2] = v0, v1, v2
        pos[0], pos[1], pos[2] = p0, p1, p2
        if kind is TargetKind.LAND and p2 > vehicle_pos_ned[2] + LAND_MAX_LEAD_M:
            pos[2] = vehicle_pos_ned[2] + LAND_MAX_LEAD_M
        elif kind is TargetKind.VELOCITY:
            self._leash(vehicle_pos_ned)
        elif kind is TargetKind.DESCEND:  # no position error, ever: only the velocity reference acts
            pos[0], pos[1] = vehicle_pos_ned[0], vehicle_pos_ned[1]
            pos[2] = min(p2, vehicle_pos_ned[2] + LAND_MAX_LEAD_M)
        # yaw: rate-limited turn toward the target heading along the shorter way
        if not math.isnan(target.yaw_rad):
            err = (target.yaw_rad - self.yaw_rad + math.pi) % (2.0 * math.pi) - math.pi
            step = self.limits.yaw_rate_rad_s * dt_s
            self.yaw_rad += max(-step, min(step, err))
            self.yaw_rad = (self.yaw_rad + math.pi) % (2.0 * math.pi) - math.pi
        elif kind is TargetKind.VELOCITY and not math.isnan(target.yaw_rate_rad_s):
            limit = self.limits.yaw_rate_rad_s
            self.yaw_rad += max(-limit, min(limit, target.yaw_rate_rad_s)) * dt_s
            self.yaw_rad = (self.yaw_rad + math.pi) % (2.0 * math.pi) - math.pi
        return Reference((pos[0], pos[1], pos[2]), (v0, v1, v2), (a0, a1, a2), self.yaw_rad)

    def _leash(self, vehicle_pos_ned: Vec3) -> None:
        """Keep the position reference within VELOCITY_MAX_LEAD_M of the vehicle (horizontally, vertically)."""
        pos = self.pos_ned
        dn, de = pos[0] - vehicle_pos_ned[0], pos[1] - vehicle_pos_ned[1]
        d_xy = math.hypot(dn, de)
        if d_xy > VELOCITY_MAX_LEAD_M:
            k = VELOCITY_MAX_LEAD_M / d_xy
            pos[0], pos[1] = vehicle_pos_ned[0] + dn * k, vehicle_pos_ned[1] + de * k
        dd = pos[2] - vehicle_pos_ned[2]
        if abs(dd) > VELOCITY_MAX_LEAD_M:
            pos[2] = vehicle_pos_ned[2] + math.copysign(VELOCITY_MAX_LEAD_M, dd)

    def _next_reference(
        self, target: NavTarget, dt_s: float
    ) -> tuple[float, float, float, float, float, float, float, float, float]:
        """Acceleration, velocity and position (NED) one step of ``dt_s`` toward ``target`` (not IDLE), before
        the LAND lead clamp; from the current reference, which it does not change."""
        lim = self.limits
        pos, vel, acc = self.pos_ned, self.vel_ned, self.acc_ned
        acc_xy, jerk = lim.acc_xy_m_s2, lim.jerk_m_s3
        kind = target.kind
        tn, te, td = target.pos_ned_m
        if kind is TargetKind.VELOCITY or kind is TargetKind.DESCEND:  # the commanded velocity, within the limits
            vn_des, ve_des, vd_cmd = target.vel_ned_m_s
            s_xy = math.hypot(vn_des, ve_des)
            if s_xy > target.speed_xy_m_s:
                vn_des, ve_des = vn_des * (target.speed_xy_m_s / s_xy), ve_des * (target.speed_xy_m_s / s_xy)
        else:  # horizontal: desired velocity along the line to the target
            dn, de = tn - pos[0], te - pos[1]
            d_xy = math.hypot(dn, de)
            if d_xy > 1e-9:
                v = _approach_speed(d_xy, target.speed_xy_m_s, acc_xy) / d_xy
                vn_des, ve_des = dn * v, de * v
            else:
                vn_des = ve_des = 0.0
        dvn, dve = vn_des - vel[0], ve_des - vel[1]
        dv_xy = math.hypot(dvn, dve)
        if dv_xy > 1e-12:
            a = _accel_toward(dv_xy, acc_xy, jerk) / dv_xy
            an_des, ae_des = dvn * a, dve * a
        else:
            an_des = ae_des = 0.0
        # vertical (down positive): a braking profile, or a constant descent when landing
        if kind is TargetKind.LAND:  # over the spot: from LAND_ALIGN_M / 2 (full) to LAND_ALIGN_M (none)
            off = math.hypot(tn - pos[0], te - pos[1])
            vd_des = target.speed_down_m_s * min(max(2.0 - 2.0 * off / LAND_ALIGN_M, 0.0), 1.0)
        elif kind is TargetKind.DESCEND:
            vd_des = target.speed_down_m_s
        elif kind is TargetKind.VELOCITY:
            vd_des = max(-target.speed_up_m_s, min(target.speed_down_m_s, vd_cmd))
        else:
            dd = td - pos[2]
            if dd > 0.0:
                vd_des = math.copysign(_approach_speed(dd, target.speed_down_m_s, lim.acc_down_m_s2), dd)
            else:
                vd_des = math.copysign(_approach_speed(-dd, target.speed_up_m_s, lim.acc_up_m_s2), dd)
        dvd = vd_des - vel[2]
        if dvd > 0.0:
            ad_des = math.copysign(_accel_toward(dvd, lim.acc_down_m_s2, jerk), dvd)
        else:
            ad_des = math.copysign(_accel_toward(-dvd, lim.acc_up_m_s2, jerk), dvd)
        # jerk limit (each component moves at most jerk·dt toward its goal), then integrate (semi-implicit Euler)
        dj = jerk * dt_s
        a0, a1, a2 = acc
        a0 = a0 + dj if an_des > a0 + dj else (a0 - dj if an_des < a0 - dj else an_des)
        a1 = a1 + dj if ae_des > a1 + dj else (a1 - dj if ae_des < a1 - dj else ae_des)
        a2 = a2 + dj if ad_des > a2 + dj else (a2 - dj if ad_des < a2 - dj else ad_des)
        v0, v1, v2 = vel[0] + a0 * dt_s, vel[1] + a1 * dt_s, vel[2] + a2 * dt_s
        return a0, a1, a2, v0, v1, v2, pos[0] + v0 * dt_s, pos[1] + v1 * dt_s, pos[2] + v2 * dt_s
