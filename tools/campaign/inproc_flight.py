"""One campaign case flown in one process (``mode: inproc``): the simulator's and the autopilot's own modules,
the lockstep's own wire format, no sockets and no ground station (SPEC §2: tools may compose sim and autopilot).

Each control step is what ``sim.server.SimServer`` and ``autopilot.io_loop.run_loop`` do over UDP: the sim's
measurements and truth (``SensorValues.fill``) written as the lockstep datagram (``FrameWriter``) with the
obstacle sensor's detections at its rate, decoded by the autopilot's ``Decoder`` into a ``LockstepFrame``,
``Autopilot.step``, its answer written (``AnswerWriter``) and read back by the sim (``read_answer``: motor
commands as float32, as on the wire), then the physics step. The mission and fence are handed to the autopilot
before the first step (the sitl mode uploads them before the simulator starts), the script arms and starts the
mission at fixed sim times (the world's ``failures:`` merged in, as ``autopilot --world-failures`` does), and
the run ends at ``sim_time_s`` like ``sim --duration-s``. The truth hash is the
simulator's (sha256 of the state after every control step), so a case flies to the same hash in both modes.
The wall-clock deadline is checked every simulated second (a step cannot be interrupted in-process).
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from autopilot.commander.script import CommandScript, failure_steps, load_script, merged
from autopilot.mission.files import load_mission_file
from autopilot.runner import Autopilot, AutopilotConfig
from autopilot.vehicle_adapter import VehicleAdapter
from mavlink_bridge.contract.vehicle_api import MissionItem, MissionResult, MissionType
from mavlink_bridge.contract.wire import ObstacleDetection
from mavlink_bridge.lockstep import FrameAssembler
from mavlink_bridge.lockstep.answer_kernel import (
    A_ARMED,
    A_GRIPPER_RELEASE,
    A_MOTORS,
    ANSWER_OK,
    AnswerWriter,
    read_answer,
)
from mavlink_bridge.wire.frame_writer import FrameWriter
from mavlink_bridge.wire.mission_items import xy_from_int, xy_to_int
from sim.end_reason import EndReason
from sim.frame_kernel import SensorValues
from sim.obstacle_sensor import ObstacleSensor
from sim.sensors import SensorModel
from sim.server import tilt_deg
from sim.vehicle import VehicleSim
from sim.vehicle_config import load_vehicle
from sim.world import load_world

CONTROL_HZ = 250


def _f32(value: float) -> float:
    return float(np.float32(value))


def as_on_the_wire(item: MissionItem) -> MissionItem:
    """``item`` as the autopilot receives it in MISSION_ITEM_INT (the sitl mode's upload): x/y as int32 at the
    frame's scale, params and z as float32."""
    frame = item.frame
    return replace(
        item,
        param1=_f32(item.param1),
        param2=_f32(item.param2),
        param3=_f32(item.param3),
        param4=_f32(item.param4),
        x_lat_deg=xy_from_int(xy_to_int(item.x_lat_deg, frame), frame),
        y_lon_deg=xy_from_int(xy_to_int(item.y_lon_deg, frame), frame),
        z_alt_m=_f32(item.z_alt_m),
    )


def fly(case_dir: Path, deadline_s: float | None = None, rerun: str | None = None) -> dict[str, Any]:
    """Fly the case in ``case_dir`` (``case.json`` + world, params and script files); the flight record with
    ``sim`` / ``autopilot`` summaries shaped like the processes' JSON files (``error`` says what went wrong,
    ``timed_out`` whether the deadline stopped it). ``rerun``: record the flight as ``autopilot --rerun`` does
    (``save:PATH``)."""
    t0 = time.monotonic()
    case = json.loads((case_dir / "case.json").read_text())
    world_path = case_dir / "world.yaml"
    world = load_world(world_path)
    vehicle_cfg = load_vehicle(case["vehicle"])
    seed = int(case["sim_seed"])
    v = VehicleSim(vehicle_cfg, world=world, seed=seed)
    values = SensorValues(v, SensorModel(vehicle_cfg, world.home, seed))
    writer = FrameWriter()
    obstacle_sensor = ObstacleSensor(world, seed)
    detection_period_us = round(1e6 / obstacle_sensor.config.rate_hz)
    next_detection_us = 0
    config = AutopilotConfig(
        vehicle=case["vehicle"], estimator=case["estimator"], params_file=str(case_dir / "params.yaml")
    )
    ap = Autopilot(
        config, script=CommandScript(merged(load_script(case_dir / "script.yaml"), failure_steps(world.failures)))
    )
    if world.failures:  # as ``autopilot --world-failures``: a world that schedules failures enables the injection
        ap.params.set("SYS_FAILURE_EN", 1.0)
    if rerun:
        from autopilot.telemetry import make_listener

        ap.listener = make_listener(
            rerun,
            vehicle=case["vehicle"],
            mission_file=str(world_path),
            safety_radius_m=ap.params.get("CA_RSAFE_M"),
            rtl_alt_m=ap.params.get("MIS_RTL_ALT"),
        )
    vehicle_api = VehicleAdapter(ap)
    plan = load_mission_file(world_path)
    texts: list[str] = []
    error = ""
    for mission_type, items in ((MissionType.FENCE, plan.fence), (MissionType.MISSION, plan.items)):
        result, why = vehicle_api.replace_mission(mission_type, [as_on_the_wire(item) for item in items])
        if result is not MissionResult.ACCEPTED:
            error = f"{mission_type.name} upload refused: {result.name} {why}"
    wire = FrameAssembler()
    answers = AnswerWriter(1, 1)
    answer, payload = np.zeros(16), np.zeros(96, dtype=np.uint8)
    motors_off = np.zeros(4)
    truth_hash = hashlib.sha256()
    state = v.batch.state[0]
    max_tilt = 0.0
    duration_s = float(case["sim_time_s"])
    end_codes, running = v.batch.end_reason, EndReason.RUNNING.value
    timed_out = False
    steps = 0
    while end_codes[0] == running and not error:
        if v.t_s >= duration_s - 1e-9:
            v.end(EndReason.COMPLETED)
            break
        detections: tuple[ObstacleDetection, ...] = ()
        if obstacle_sensor is not None and v.t_us >= next_detection_us:
            next_detection_us += detection_period_us
            detections = tuple(obstacle_sensor.detect(v.pos_ned, v.q_ned_frd, v.t_us))
        gps_due = values.fill()
        cmd = ap.step(wire.frame(writer.write(values.values, v.t_us, gps_due, detections)))
        step_texts = ap.drain_texts()
        texts += [t.text for t in step_texts]
        if ap.listener is not None:
            record = ap.record(step_texts)
            if record is not None:
                ap.listener.on_step(record)
        n = answers.write(cmd.time_us, cmd.motor_cmd, cmd.armed, cmd.gripper_release, cmd.lockstep)
        if read_answer(answers.buffer, n, v.t_us, answer, payload) != ANSWER_OK:
            error = f"the autopilot's answer at t={v.t_us} us was refused by the simulator's reader"
            break
        ap.after_answer()
        if answer[A_GRIPPER_RELEASE] == 1.0 and v.payload_kg > 0.0:
            v.release_payload()
        v.step(answer[A_MOTORS : A_MOTORS + 4] if answer[A_ARMED] == 1.0 else motors_off)
        truth_hash.update(state)
        max_tilt = max(max_tilt, tilt_deg(state[6:10]))
        steps += 1
        if steps % CONTROL_HZ == 0 and deadline_s is not None and time.monotonic() - t0 > deadline_s:
            timed_out = True
            v.end(EndReason.STOPPED)
            break
    texts += [t.text for t in ap.drain_texts()]
    if ap.listener is not None:
        close = getattr(ap.listener, "close", None)
        if close is not None:
            close()
    wall_s = time.monotonic() - t0
    clearance = v.min_clearance_m
    sim = {
        "end_reason": v.end_reason.name,
        "sim_time_s": v.t_s,
        "wall_time_s": wall_s,
        "collisions": int(v.end_reason is EndReason.COLLISION),
        "min_clearance_m": clearance if math.isfinite(clearance) else None,
        "max_tilt_deg": max_tilt,
        "truth_sha256": truth_hash.hexdigest(),
    }
    return {
        "error": error,
        "timed_out": timed_out,
        "sim": sim,
        "autopilot": ap.summary(wall_s),
        "texts": texts,
        "wall_s": wall_s,
    }


def warm() -> None:
    """Load the compiled kernels of an in-process flight (a Dask worker's setup, before its first case)."""
    import autopilot.runner  # noqa: F401
    import sim.vehicle  # noqa: F401
