"""Failure injection and sensor failsafes wired into the autopilot's step (in-process closed loop, no sockets):
the command over the vehicle interface, what the estimator receives, the motor outputs sent, SYS_STATUS health,
status texts, scripted injection, and the GPS-loss timeline on a scripted EstimatorStatus."""

from __future__ import annotations

from autopilot_fakes import command
from autopilot_loop import SimLoop

from autopilot.commander.script import CommandScript, parse_script
from autopilot.estimation import EstimatorStatus, FrameLike, TruthEstimator, VehicleState
from autopilot.flight_tasks.setpoints import TargetKind
from autopilot.safety.failure_injection import SENSOR_MOTOR_OUTPUTS
from mavlink_bridge.contract.mav_enums import FailureType, FailureUnit, MavCmd
from mavlink_bridge.contract.vehicle_api import CommandResult, FlightMode

NO_GPS = EstimatorStatus(
    aligned=True, healthy=True, baro_fused=True, mag_fused=True, dead_reckoning=True, pos_horiz_valid=True,
    pos_vert_valid=True, reason="",
)  # fmt: skip


class RecordingEstimator(TruthEstimator):
    """The truth estimator that keeps the last frame it was given and reports the status it is told to."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: FrameLike | None = None
        self.forced_status: EstimatorStatus | None = None

    @property
    def status(self) -> EstimatorStatus:
        return self.forced_status if self.forced_status is not None else super().status

    def update(self, frame: FrameLike) -> VehicleState | None:
        self.seen = frame
        return super().update(frame)


def _inject(loop: SimLoop, unit: int, kind: int, instance: int = 0) -> CommandResult:
    return loop.vehicle.handle_command(command(MavCmd.INJECT_FAILURE, unit, kind, instance))


def test_refused_without_sys_failure_en_then_gps_off_reaches_only_the_estimator() -> None:
    est = RecordingEstimator()
    loop = SimLoop("x500", estimator=est)
    loop.run_s(1.0)
    assert _inject(loop, FailureUnit.SENSOR_GPS, FailureType.OFF) is CommandResult.DENIED
    assert "SYS_FAILURE_EN" in loop.ap.commander.last_reason
    assert loop.vehicle.param_set("SYS_FAILURE_EN", 1.0)[0]
    assert _inject(loop, FailureUnit.SENSOR_GPS, FailureType.OFF) is CommandResult.ACCEPTED
    assert _inject(loop, 77, FailureType.OFF) is CommandResult.DENIED  # unknown unit: refused, nothing breaks
    gps_frames = 0
    for _ in range(100):
        frame = loop.frame()
        gps_frames += frame.gps is not None
        loop.apply(loop.ap.step(frame))
        assert est.seen is not None and est.seen.gps is None and est.seen.truth is frame.truth
    assert gps_frames >= 3  # the sim kept sending fixes (10 Hz); the estimator saw none
    texts = [t.text for t in loop.ap.drain_texts()]
    assert "Failure injected: GPS off" in texts


def test_motor_off_zeroes_its_output_reports_it_and_clears_the_health_bit() -> None:
    loop = SimLoop("x500")
    loop.ap.params.set("SYS_FAILURE_EN", 1.0)
    loop.take_off(5.0, settle_s=1.0)
    assert loop.ap.snapshot().sensors_health & SENSOR_MOTOR_OUTPUTS  # type: ignore[union-attr]
    assert _inject(loop, FailureUnit.SYSTEM_MOTOR, FailureType.OFF, 3) is CommandResult.ACCEPTED
    cmd = loop.step()
    assert cmd.motor_cmd[2] == 0.0 and min(cmd.motor_cmd[i] for i in (0, 1, 3)) > 0.0
    assert any("motor 3 off" in t for t in loop.texts)
    assert not loop.ap.snapshot().sensors_health & SENSOR_MOTOR_OUTPUTS  # type: ignore[union-attr]
    loop.run_s(0.5)  # it falls; the autopilot keeps answering
    assert _inject(loop, FailureUnit.SYSTEM_MOTOR, FailureType.OK, 3) is CommandResult.ACCEPTED
    assert loop.step().motor_cmd[2] > 0.0
    assert loop.ap.snapshot().sensors_health & SENSOR_MOTOR_OUTPUTS  # type: ignore[union-attr]


def test_a_scripted_failure_runs_at_its_sim_time() -> None:
    steps = parse_script([{"at_s": 1.0, "cmd": "inject_failure", "unit": "baro", "type": "off"}])
    est = RecordingEstimator()
    loop = SimLoop("x500", estimator=est, script=CommandScript(steps))
    loop.ap.params.set("SYS_FAILURE_EN", 1.0)
    loop.run_s(0.9)
    assert est.seen is not None and est.seen.sensor.pressure_alt_m == est.seen.sensor.pressure_alt_m  # not NaN
    loop.run_s(0.2)
    assert est.seen.sensor.pressure_alt_m != est.seen.sensor.pressure_alt_m  # NaN: no baro sample
    assert "Script inject_failure: ACCEPTED" in loop.texts and "Failure injected: baro off" in loop.texts


def test_gps_loss_status_dead_reckons_for_the_delay_then_lands_blind() -> None:
    est = RecordingEstimator()
    loop = SimLoop("x500", estimator=est)
    loop.ap.params.set("COM_POS_FS_DELAY", 2.0)
    loop.take_off(5.0, settle_s=1.0)
    est.forced_status = NO_GPS
    loop.run_s(1.5)
    assert any(t.startswith("GPS lost: dead reckoning") for t in loop.texts)
    assert loop.ap.commander.mode is FlightMode.AUTO_LOITER  # still dead reckoning
    assert loop.run_until(lambda: loop.ap.commander.mode is FlightMode.AUTO_LAND, 1.0)
    assert any(t.startswith("Failsafe: position lost (no GPS for 2.0 s)") for t in loop.texts)
    loop.step()
    assert loop.ap.record(()).target.kind is TargetKind.DESCEND  # type: ignore[union-attr]
    est.forced_status = None  # GPS back: land with position control where it is
    assert loop.run_until(lambda: any(t.startswith("GPS regained") for t in loop.texts), 1.0)
    loop.step()
    assert loop.ap.record(()).target.kind is TargetKind.LAND  # type: ignore[union-attr]
    assert loop.run_until(lambda: not loop.ap.commander.armed, 30.0)
