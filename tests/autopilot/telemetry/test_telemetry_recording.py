"""Rerun telemetry: a flight fed to the listener is read back from the .rrd (issue 7, SPEC §9)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from autopilot.control.airframe import load_airframe
from autopilot.control.cascade import CascadeController, ControlSample
from autopilot.control.gains import CascadeGains
from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from autopilot.telemetry import RerunTelemetry, make_listener
from autopilot.telemetry import entities as ent
from autopilot.telemetry.recording_reader import RecordingReadError, read_recording
from autopilot.telemetry.rerun_logger import DECIMATION, SERIES
from autopilot.telemetry.sinks import RerunSink, SinkKind, open_recording
from tools.benchmarks.telemetry import CONTROL_HZ, synthetic_records

N_STEPS = 1500  # 6 s of sim time at 250 Hz
IDLE_STEPS = 50


@pytest.fixture(scope="module")
def flight(tmp_path_factory: pytest.TempPathFactory):
    """Fly the synthetic flight into a recording; keep copies of what was fed in."""
    path = tmp_path_factory.mktemp("rrd") / "flight.rrd"
    rec = open_recording(RerunSink(SinkKind.SAVE, str(path)))
    telemetry = RerunTelemetry(rec, batch_rows=400)  # several batches, the last one partial
    fed = {"t_us": [], "pos": [], "sp": [], "q": [], "kp": [], "att_err": [], "motor": []}
    for record in synthetic_records(N_STEPS):
        values = record.control.values if record.control is not None else (math.nan,) * ControlSample.SIZE
        fed["t_us"].append(record.time_us)
        fed["pos"].append(record.state.pos_ned_m)
        fed["sp"].append(record.pos_sp_ned_m)
        fed["q"].append(record.state.q_ned_frd)
        fed["kp"].append(values[ControlSample.KP])
        fed["att_err"].append(values[ControlSample.ATT_ERR])
        fed["motor"].append(record.motor_cmd)
        telemetry.on_step(record)
    telemetry.on_step(record)  # a repeated frame is ignored (sim time stays strictly increasing)
    telemetry.close()
    telemetry.close()  # idempotent
    return read_recording(path), {k: np.asarray(v) for k, v in fed.items()}


def test_entities_present(flight) -> None:
    recording, _ = flight
    names = set(recording.entities)
    expected = {path for path, *_ in SERIES} | {
        ent.WORLD,
        ent.VEHICLE,
        ent.VEHICLE_BODY,
        ent.SETPOINT,
        ent.TARGETS,
        ent.HOME,
        ent.LOG,
        ent.DETOUR,
        ent.OBSTACLES_SENSED,
        ent.OBSTACLES_SAFETY,
    }
    assert expected <= names, sorted(expected - names)
    assert any(n.startswith(ent.TRAIL + "/") for n in names)
    assert recording.application_id == "quadsitl"
    assert recording.static_component(ent.WORLD, "ViewCoordinates:xyz") == [[5, 3, 2]]  # Forward, Right, Down: NED


def test_every_step_is_a_row_with_monotonic_sim_time(flight) -> None:
    """Every step of the full-rate series; every N-th step (from the first) of the decimated ones."""
    recording, fed = flight
    for path, _, width, _ in SERIES:
        s = recording.scalars(path)
        every = DECIMATION.get(path, 1)
        want = fed["t_us"][::every]
        assert s.values.shape == (len(want), width), path
        np.testing.assert_array_equal(s.t_us, want)
        assert np.all(np.diff(s.t_us) > 0)
    assert DECIMATION.get(ent.POS_NED, 1) == DECIMATION.get(ent.ATT_ERR, 1) == DECIMATION.get(ent.MOTORS, 1) == 1


def test_logged_positions_equal_the_input(flight) -> None:
    recording, fed = flight
    np.testing.assert_array_equal(recording.scalars(ent.POS_NED).values, fed["pos"])
    np.testing.assert_array_equal(recording.scalars(ent.POS_SP_NED).values, fed["sp"][:: DECIMATION[ent.POS_SP_NED]])
    np.testing.assert_allclose(recording.scalars(ent.POS_ERR_NED).values, fed["sp"] - fed["pos"], atol=1e-12)
    np.testing.assert_array_equal(recording.scalars(ent.MOTORS).values, fed["motor"])


def test_controller_series_are_nan_while_idle_and_equal_diagnostics_after(flight) -> None:
    recording, fed = flight
    every = DECIMATION[ent.gain_path("attitude", "kp")]
    kp_att = recording.scalars(ent.gain_path("attitude", "kp")).values
    kp_pos = recording.scalars(ent.gain_path("position", "kp")).values
    idle = -(-IDLE_STEPS // every)  # decimated rows still idle
    assert np.all(np.isnan(kp_att[:idle]))
    np.testing.assert_array_equal(kp_pos[idle:], fed["kp"][::every][idle:, :3])
    np.testing.assert_array_equal(kp_att[idle:], fed["kp"][::every][idle:, 3:])
    att_err = recording.scalars(ent.ATT_ERR).values[IDLE_STEPS:]
    np.testing.assert_allclose(att_err, np.degrees(fed["att_err"][IDLE_STEPS:]), rtol=1e-12)


def test_pose_is_decimated_to_25_hz_and_matches_the_input(flight) -> None:
    recording, fed = flight
    tr = recording.translations()
    q = recording.quaternions_wxyz()
    duration_s = (fed["t_us"][-1] - fed["t_us"][0]) * 1e-6
    assert len(tr.t_us) == math.floor(duration_s * 25.0) + 1
    assert np.all(np.diff(tr.t_us) == 40_000)
    idx = np.searchsorted(fed["t_us"], tr.t_us)
    np.testing.assert_array_equal(fed["t_us"][idx], tr.t_us)
    np.testing.assert_allclose(tr.values, fed["pos"][idx], atol=1e-5)  # float32 in the file
    np.testing.assert_allclose(q.values, fed["q"][idx], atol=1e-6)


def test_trail_segments_join_into_the_whole_path(flight) -> None:
    recording, _ = flight
    segments = sorted(e for e in recording.entities if e.startswith(ent.TRAIL + "/"))
    pts = []
    for k, seg in enumerate(segments):
        s = recording.latest_component(seg, "LineStrips3D:strips")[0]
        pts.extend(s if k == 0 else s[1:])  # each segment starts at the previous one's end
    tr = recording.translations()
    np.testing.assert_allclose(np.asarray(pts), tr.values, atol=1e-5)


def test_targets_are_drawn_once_each(flight) -> None:
    recording, _ = flight
    strip = recording.latest_component(ent.TARGETS, "LineStrips3D:strips")[0]
    assert strip == [[20.0, 0.0, -5.0]]  # one target in the 6 s flight (a new one every 10 s)


def test_a_landing_is_one_target_though_its_down_follows_the_vehicle(tmp_path: Path) -> None:
    """LAND targets carry the vehicle's own down (only their xy is held): one point, not one per 3D sample."""
    path = tmp_path / "land.rrd"
    rec = open_recording(RerunSink(SinkKind.SAVE, str(path)))
    telemetry = RerunTelemetry(rec)
    first_land_down = None
    for k, record in enumerate(synthetic_records(1000, with_planner=False)):
        if k >= 600:  # descend over (5, 5): the target's down is the vehicle's, a new value every step
            down = record.state.pos_ned_m[2]
            first_land_down = down if first_land_down is None else first_land_down
            record = dataclasses.replace(record, target=NavTarget(TargetKind.LAND, (5.0, 5.0, down)))
        telemetry.on_step(record)
    telemetry.close()
    strip = read_recording(path).latest_component(ent.TARGETS, "LineStrips3D:strips")[0]
    np.testing.assert_allclose(strip, [[20.0, 0.0, -5.0], [5.0, 5.0, first_land_down]], atol=1e-5)


def test_text_log_has_modes_arming_and_events_in_sim_time(flight) -> None:
    recording, fed = flight
    log = recording.text_log()
    texts = [t for _, _, t in log]
    assert texts[:4] == ["mode AUTO_LOITER", "armed", "mode AUTO_MISSION", "Takeoff"]
    assert [t for t, _, text in log if text == "armed"] == [int(fed["t_us"][25])]
    assert all(fed["t_us"][0] <= t <= fed["t_us"][-1] for t, _, _ in log)


def test_real_cascade_diagnostics_are_gathered_exactly(tmp_path: Path) -> None:
    """The live views of a real CascadeController are copied by one gather (offsets found from the views)."""
    controller = CascadeController(load_airframe("x500"), CascadeGains.paper_default(1.0, 2.0), 1, 1.0 / CONTROL_HZ)
    rec = open_recording(RerunSink(SinkKind.SAVE, str(tmp_path / "real.rrd")))
    telemetry = RerunTelemetry(rec)
    fed_kp, fed_err, fed_thrust = [], [], []
    for k, record in enumerate(synthetic_records(300, with_planner=False)):
        s = record.state
        sp = np.asarray(record.pos_sp_ned_m) + np.array([0.3 * math.sin(k / 20), 0.0, 0.2])
        controller.update_position(
            np.asarray(s.pos_ned_m),
            np.zeros(3),
            np.asarray(s.q_ned_frd),
            np.zeros(3),
            sp,
            np.zeros(3),
            np.zeros(3),
            0.3,
        )
        d = controller.diagnostics
        fed_kp.append(d.kp[0].copy())
        fed_err.append(d.att_err_rad[0].copy())
        fed_thrust.append(float(d.thrust_n[0]))
        telemetry.on_step(dataclasses.replace(record, control=controller.sample()))
    telemetry.close()
    r = read_recording(tmp_path / "real.rrd")
    kp = np.hstack(
        [r.scalars(ent.gain_path("position", "kp")).values, r.scalars(ent.gain_path("attitude", "kp")).values]
    )
    every = DECIMATION[ent.gain_path("position", "kp")]
    assert DECIMATION[ent.THRUST] == every
    idle = -(-IDLE_STEPS // every)
    fed_kp_a = np.asarray(fed_kp)
    np.testing.assert_array_equal(kp[idle:], fed_kp_a[::every][idle:])
    assert np.ptp(fed_kp_a[IDLE_STEPS:, 0]) > 0.0  # the gains really vary with the error (k1 != k2)
    np.testing.assert_allclose(r.scalars(ent.ATT_ERR).values[IDLE_STEPS:], np.degrees(fed_err[IDLE_STEPS:]))
    np.testing.assert_array_equal(r.scalars(ent.THRUST).values[idle:, 0], fed_thrust[::every][idle:])


def test_make_listener_saves_blueprint_route_fence_and_true_obstacles(tmp_path: Path) -> None:
    mission = tmp_path / "m.yaml"
    mission.write_text(
        "name: t\nhome: {lat_deg: 30.0, lon_deg: 120.0, alt_m: 10.0}\nmission:\n  - takeoff: {alt_m: 10}\n"
        "  - waypoint: {north_m: 40, east_m: 0, alt_m: 10}\n  - land: {}\n"
        "fence:\n  - exclusion_circle: {north_m: 60, east_m: 10, radius_m: 8}\n"
        "world:\n  obstacles:\n    - cylinder: {north_m: 20, east_m: 1, radius_m: 3, height_m: 25}\n"
        "    - box: {north_m: 50, east_m: -2, size_m: [6, 8, 30], yaw_deg: 15}\n"
        "    - sphere: {north_m: 70, east_m: 0, alt_m: 10, radius_m: 2.5}\n"
    )
    path = tmp_path / "sub" / "flight.rrd"
    telemetry = make_listener(f"save:{path}", vehicle="delivery650", mission_file=mission)
    assert telemetry is not None
    for record in synthetic_records(100, with_planner=False):
        telemetry.on_step(record)
    telemetry.close()
    r = read_recording(path)
    assert r.blueprints >= 1
    route = np.asarray(r.static_component(ent.ROUTE, "LineStrips3D:strips")[0])
    np.testing.assert_allclose(route, [[0, 0, 0], [0, 0, -10], [40, 0, -10], [40, 0, 0]], atol=1e-3)
    assert r.static_component(f"{ent.OBSTACLES_TRUE}/cylinders", "Cylinders3D:lengths") == [25.0]
    assert len(r.static_component(f"{ent.OBSTACLES_TRUE}/boxes", "Boxes3D:half_sizes")) == 1
    assert r.static_component(f"{ent.OBSTACLES_TRUE}/spheres", "Ellipsoids3D:centers") == [[70.0, 0.0, -10.0]]
    fence = r.static_component(ent.FENCE, "LineStrips3D:strips")
    radii = np.hypot(np.asarray(fence[0])[:, 0] - 60.0, np.asarray(fence[0])[:, 1] - 10.0)
    np.testing.assert_allclose(radii, 8.0, rtol=1e-5)


def test_make_listener_off_and_bad_files(tmp_path: Path) -> None:
    assert make_listener("off") is None
    with pytest.raises(RecordingReadError):
        read_recording(tmp_path / "missing.rrd")
    bad = tmp_path / "bad.rrd"
    bad.write_bytes(b"not a recording")
    with pytest.raises(RecordingReadError):
        read_recording(bad)
