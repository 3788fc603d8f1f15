"""Sensor-loss failsafes on synthetic EstimatorStatus sequences: GPS lost -> dead reckoning for COM_POS_FS_DELAY ->
land without horizontal position control; recovery before the delay; baro and mag loss reported; and the
commander's blind descent (DESCEND target, land detection on the vertical only)."""

from __future__ import annotations

import itertools
import math

import pytest
from autopilot_fakes import KinematicLoop, command, make_commander, update

from autopilot.estimation import EstimatorStatus
from autopilot.flight_tasks.setpoints import NavTarget, SetpointGenerator, TargetKind
from autopilot.parameters.nav_decls import nav_param_specs
from autopilot.parameters.store import ParamStore
from autopilot.safety.failsafe import FailsafeAction, FailsafeEvent, FailsafeKind, SensorFailsafe
from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import FlightMode, LandedState, Severity

OK = EstimatorStatus(
    aligned=True, healthy=True, gps_fused=True, baro_fused=True, mag_fused=True, pos_horiz_valid=True,
    pos_vert_valid=True, reason="",
)  # fmt: skip
NO_GPS = EstimatorStatus(
    aligned=True, healthy=True, baro_fused=True, mag_fused=True, dead_reckoning=True, pos_horiz_valid=True,
    pos_vert_valid=True, reason="",
)  # fmt: skip
NO_GPS_INVALID = EstimatorStatus(aligned=True, baro_fused=True, mag_fused=True, dead_reckoning=True, reason="x")
S = 1_000_000


def _failsafe(**params: float) -> SensorFailsafe:
    store = ParamStore(nav_param_specs())
    for name, value in params.items():
        store.set(name, value)
    return SensorFailsafe(store)


def _kinds(events: object) -> list[tuple[FailsafeKind, FailsafeAction, bool]]:
    return [(e.kind, e.action, e.cleared) for e in events]  # type: ignore[attr-defined]


def test_gps_loss_dead_reckons_for_the_delay_then_lands_and_recovery_gives_position_back() -> None:
    fs = _failsafe(COM_POS_FS_DELAY=5.0)
    assert fs.update(0, OK, armed=True, in_air=True) == ()
    (lost,) = fs.update(10 * S, NO_GPS, armed=True, in_air=True)
    assert (lost.kind, lost.action) == (FailsafeKind.GPS_LOSS, FailsafeAction.WARN)
    assert "dead reckoning" in lost.message and "in 5 s" in lost.message
    for t in (11 * S, 12 * S, 14 * S + 900_000):  # within the delay: nothing more
        assert fs.update(t, NO_GPS, armed=True, in_air=True) == ()
    (land,) = fs.update(15 * S, NO_GPS, armed=True, in_air=True)
    assert (land.kind, land.action) == (FailsafeKind.POSITION_LOSS, FailsafeAction.LAND)
    assert "no GPS for 5.0 s" in land.message and "baro height" in land.message
    assert fs.update(16 * S, NO_GPS, armed=True, in_air=True) == ()  # once
    (back,) = fs.update(20 * S, OK, armed=True, in_air=True)
    assert _kinds([back]) == [(FailsafeKind.POSITION_LOSS, FailsafeAction.NONE, True)]
    assert "GPS regained after 10.0 s" in back.message


def test_gps_back_before_the_delay_means_the_flight_continues() -> None:
    fs = _failsafe(COM_POS_FS_DELAY=5.0)
    fs.update(0, OK, armed=True, in_air=True)
    assert _kinds(fs.update(10 * S, NO_GPS, armed=True, in_air=True)) == [
        (FailsafeKind.GPS_LOSS, FailsafeAction.WARN, False)
    ]
    (back,) = fs.update(13 * S, OK, armed=True, in_air=True)
    assert _kinds([back]) == [(FailsafeKind.GPS_LOSS, FailsafeAction.NONE, True)] and "continues" in back.message
    assert fs.update(30 * S, OK, armed=True, in_air=True) == () and fs.gps_lost_since_us is None


def test_an_invalid_horizontal_position_lands_at_once_and_act_0_only_warns() -> None:
    fs = _failsafe(COM_POS_FS_DELAY=60.0)
    fs.update(0, OK, armed=True, in_air=True)
    events = fs.update(S, NO_GPS_INVALID, armed=True, in_air=True)
    assert _kinds(events) == [
        (FailsafeKind.GPS_LOSS, FailsafeAction.WARN, False),
        (FailsafeKind.POSITION_LOSS, FailsafeAction.LAND, False),
    ]
    assert "horizontal position invalid" in events[1].message
    fs = _failsafe(COM_POS_FS_DELAY=1.0, COM_POS_LOSS_ACT=0.0)
    fs.update(0, OK, armed=True, in_air=True)
    fs.update(S, NO_GPS, armed=True, in_air=True)
    (warn,) = fs.update(2 * S, NO_GPS, armed=True, in_air=True)
    assert (warn.kind, warn.action) == (FailsafeKind.POSITION_LOSS, FailsafeAction.WARN)
    (back,) = fs.update(3 * S, OK, armed=True, in_air=True)  # it never stopped flying: nothing to give back
    assert _kinds([back]) == [(FailsafeKind.GPS_LOSS, FailsafeAction.NONE, True)] and "continues" in back.message


def test_no_position_action_on_the_ground_nothing_before_first_fusion_and_reset_at_disarm() -> None:
    fs = _failsafe(COM_POS_FS_DELAY=1.0)
    assert fs.update(0, NO_GPS, armed=True, in_air=True) == ()  # never fused since arming: not "lost"
    fs.update(S, OK, armed=True, in_air=False)
    assert _kinds(fs.update(2 * S, NO_GPS, armed=True, in_air=False)) == [
        (FailsafeKind.GPS_LOSS, FailsafeAction.WARN, False)
    ]
    assert fs.update(10 * S, NO_GPS, armed=True, in_air=False) == ()  # landed: no position action
    assert fs.update(11 * S, NO_GPS, armed=False, in_air=False) == ()
    assert fs.gps_lost_since_us is None and not fs.position_action_taken
    assert fs.update(12 * S, NO_GPS, armed=True, in_air=True) == ()  # re-armed: waits for GPS to be fused


def test_baro_and_mag_loss_are_reported_with_their_fallback_and_recovery() -> None:
    fs = _failsafe()
    fs.update(0, OK, armed=True, in_air=True)
    no_baro = EstimatorStatus(aligned=True, healthy=True, gps_fused=True, mag_fused=True, pos_horiz_valid=True)
    (baro,) = fs.update(S, no_baro, armed=True, in_air=True)
    assert (baro.kind, baro.message) == (FailsafeKind.BARO_LOSS, "Baro lost: height from GPS")
    no_mag = EstimatorStatus(aligned=True, healthy=True, gps_fused=True, baro_fused=True, pos_horiz_valid=True)
    events = fs.update(2 * S, no_mag, armed=True, in_air=True)
    assert _kinds(events) == [
        (FailsafeKind.BARO_LOSS, FailsafeAction.NONE, True),
        (FailsafeKind.MAG_LOSS, FailsafeAction.WARN, False),
    ]
    assert "heading from the gyro" in events[1].message
    assert _kinds(fs.update(3 * S, OK, armed=True, in_air=True)) == [(FailsafeKind.MAG_LOSS, FailsafeAction.NONE, True)]
    assert not (fs.baro_lost or fs.mag_lost)


def test_the_same_status_object_costs_nothing() -> None:
    fs = _failsafe()
    fs.update(0, OK, armed=True, in_air=True)
    first = fs.update(S, OK, armed=True, in_air=True)
    assert first == () and fs.update(2 * S, OK, armed=True, in_air=True) is first


# ---- the commander's side: a blind descent ------------------------------------------------------------------
def test_setpoint_descend_brakes_without_position_control_and_descends() -> None:
    gen = SetpointGenerator()
    gen.reset((5.0, 5.0, -10.0), (4.0, -2.0, 0.0), 0.3)  # cruising when the position was lost
    target = NavTarget(TargetKind.DESCEND, (math.nan, math.nan, math.nan), math.nan, 5.0, 3.0, 0.7)
    vehicle = (5.0, 5.0, -10.0)
    speeds = []
    for k in range(750):
        vehicle = (5.0 + 0.01 * k, 5.0 - 0.005 * k, -10.0 + 0.002 * k)  # wherever the estimate says it is
        ref = gen.update(target, 0.004, vehicle)
        assert (ref.pos_ned_m[0], ref.pos_ned_m[1]) == vehicle[:2]  # no position error, ever
        assert math.hypot(ref.acc_ned_m_s2[0], ref.acc_ned_m_s2[1]) <= 3.0 + 1e-9  # MPC_ACC_HOR
        speeds.append(math.hypot(ref.vel_ned_m_s[0], ref.vel_ned_m_s[1]))
    assert all(b <= a + 1e-12 for a, b in itertools.pairwise(speeds))  # braking only
    assert speeds[-1] < 0.01 and speeds[250] > 0.5  # stopped within 3 s, not at once
    assert ref.vel_ned_m_s[2] == pytest.approx(0.7, abs=0.01)  # descends at speed_down
    assert ref.pos_ned_m[2] <= vehicle[2] + 1.0 and ref.yaw_rad == pytest.approx(0.3)  # LAND lead, yaw kept


def _fly(loop: KinematicLoop) -> None:
    commander = loop.commander
    loop.step()
    commander.handle_command(command(MavCmd.NAV_TAKEOFF, *[0] * 6, 10.0, is_int=True, frame=6))
    commander.handle_command(command(MavCmd.COMPONENT_ARM_DISARM, 1.0))
    assert loop.run_until(lambda: commander.mode is FlightMode.AUTO_LOITER, 30.0)
    commander.drain_texts()


def test_position_loss_lands_blind_and_a_regained_position_lands_with_position_control() -> None:
    loop = KinematicLoop(make_commander())
    commander = loop.commander
    _fly(loop)
    commander.apply_failsafe(FailsafeEvent(FailsafeKind.POSITION_LOSS, FailsafeAction.LAND, "Failsafe: position lost"))
    (text,) = commander.drain_texts()[:1]
    assert text.severity is Severity.CRITICAL and commander.mode is FlightMode.AUTO_LAND
    loop.vel = (3.0, 0.0, 0.0)  # dead-reckoned drift: the land detector must not wait for it
    target = update(commander, loop.state(), 1.0)
    assert target.kind is TargetKind.DESCEND and target.vel_ned_m_s == (0.0, 0.0, 0.0)  # brake
    assert update(commander, loop.state(), 1.0) is target  # one object while nothing changes
    assert commander.landed_state is LandedState.LANDING
    loop.run_s(2.0)
    assert -loop.pos[2] < 9.0  # descending
    commander.apply_failsafe(FailsafeEvent(FailsafeKind.POSITION_LOSS, FailsafeAction.NONE, "GPS regained", True))
    assert commander.drain_texts()[-1].severity is Severity.NOTICE
    spot = loop.pos[:2]
    target = update(commander, loop.state(), 1.0)
    assert target.kind is TargetKind.LAND and target.pos_ned_m[:2] == pytest.approx(spot)
    assert loop.run_until(lambda: not commander.armed, 60.0)


def test_blind_descent_touches_down_and_disarms_on_the_vertical_alone() -> None:
    loop = KinematicLoop(make_commander())
    commander = loop.commander
    _fly(loop)
    commander.apply_failsafe(FailsafeEvent(FailsafeKind.POSITION_LOSS, FailsafeAction.LAND, "Failsafe: position lost"))
    assert loop.run_until(lambda: loop.pos[2] > -0.01, 60.0)

    def drifting_on_ground() -> bool:  # the estimate keeps a horizontal drift on the ground
        loop.vel = (2.5, 0.0, loop.vel[2])
        return not commander.armed

    assert loop.run_until(drifting_on_ground, 10.0)
    assert commander.landed_state is LandedState.ON_GROUND
    modes = [m for _, m in commander.mode_history]
    assert modes[-2:] == [FlightMode.AUTO_LAND, FlightMode.AUTO_LOITER]  # disarm leaves LAND
    commander.request_mode(FlightMode.AUTO_LAND)
    assert not commander.land.blind  # a later landing has its position control back


def test_warn_and_cleared_gps_events_change_nothing_but_the_log() -> None:
    loop = KinematicLoop(make_commander())
    commander = loop.commander
    _fly(loop)
    commander.apply_failsafe(FailsafeEvent(FailsafeKind.GPS_LOSS, FailsafeAction.WARN, "GPS lost: dead reckoning"))
    commander.apply_failsafe(FailsafeEvent(FailsafeKind.GPS_LOSS, FailsafeAction.NONE, "GPS regained", True))
    assert commander.mode is FlightMode.AUTO_LOITER
    assert [t.severity for t in commander.drain_texts()] == [Severity.WARNING, Severity.NOTICE]


# ---- the cascade on the simulator (in-process closed loop): a blind descent in wind ---------------------------
def test_blind_descent_in_wind_stays_level_and_lands_on_the_vertical_alone() -> None:
    """The position-loss landing on the real cascade and physics: the horizontal position reference follows the
    estimate and the velocity reference is zero, so the vehicle holds the attitude its integrators trimmed for
    the wind (no position correction; at most carried by the wind), descends at the land speeds and touches
    down gently; the land detector disarms it."""
    from autopilot_loop import SimLoop

    from sim.world import WindConfig, World, empty_world

    calm = empty_world()
    world = World(calm.home, (), WindConfig((2.0, -1.0, 0.0), 0.3, 7), 0.0)
    loop = SimLoop("x500", world=world)
    loop.take_off(10.0, settle_s=6.0)
    commander = loop.ap.commander
    start_ne = (float(loop.sim.pos_ned[0]), float(loop.sim.pos_ned[1]))
    tilts: list[float] = []

    def tilt() -> None:
        q = loop.sim.q_ned_frd
        tilts.append(math.degrees(math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (q[1] ** 2 + q[2] ** 2))))))

    tilt()
    hover_tilt_deg = tilts.pop()  # the wind trim (~2 deg here)
    commander.apply_failsafe(FailsafeEvent(FailsafeKind.POSITION_LOSS, FailsafeAction.LAND, "Failsafe: position lost"))
    assert commander.mode is FlightMode.AUTO_LAND
    t0 = loop.sim.t_us
    assert loop.run_until(lambda: (tilt(), not commander.armed)[1], 40.0), loop.texts
    landed_after_s = (loop.sim.t_us - t0) * 1e-6
    assert landed_after_s <= 10.0 / 0.7 + 2.5  # at worst all of it at MPC_LAND_SPEED, detection, COM_DISARM_LAND
    assert max(tilts) < hover_tilt_deg + 1.5  # held its wind trim: no position correction, no manoeuvre
    drift_m = math.dist(start_ne, (float(loop.sim.pos_ned[0]), float(loop.sim.pos_ned[1])))
    assert drift_m < 2.3 * landed_after_s  # at most carried by the 2.2 m/s wind
    assert "Landing detected" in loop.texts and loop.alt_m < 0.2
    assert loop.sim.end_reason.name == "RUNNING"  # a touchdown, not a ground impact
