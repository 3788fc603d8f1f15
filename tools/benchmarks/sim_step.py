"""The simulator's own cost per lockstep step, by part (issue 4: what the sim adds to the messaging floor).

In-process, no sockets: a hovering x500 in gusty wind, the sim side of one control step as
``sim.server`` does it — the frame's datagram (IMU/baro/mag, GPS at 10 Hz, ground truth and the
MAVLink bytes: ``sim.frame_kernel.SensorValues`` then ``mavlink_bridge.wire.frame_writer.FrameWriter``, one
numba call each), the answer's decoding, physics
(4 RK4 substeps). The reference path it replaced (``SensorModel``/``ground_truth`` dataclasses +
``encode_frame``, byte-identical) is measured too, part by part and as a whole step, in the same run.
Times are CPU time of this thread (``time.thread_time``),
the minimum over several rounds, so that other processes on a shared machine inflate them less
than wall time; the lockstep's wall time per step is in ``lockstep_flight`` / ``sim_summary.json``.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from mavlink_bridge.contract.wire import ActuatorCommand
from mavlink_bridge.lockstep import LockstepFrame, encode_frame
from mavlink_bridge.wire.codec import SIM_COMPONENT_ID, SIM_SYSTEM_ID, Decoder, Encoder
from mavlink_bridge.wire.frame_writer import FrameWriter
from sim.frame_kernel import SensorValues
from sim.sensors import SensorModel
from sim.vehicle import VehicleSim
from sim.vehicle_config import load_vehicle
from sim.world import WindConfig, World, empty_world
from tools.benchmarks import BenchResult

STEPS_PER_ROUND = 250


def _setup() -> tuple[VehicleSim, SensorModel, float]:
    vehicle = load_vehicle("x500")
    world = World(empty_world().home, (), WindConfig(mean_ned_m_s=(2.0, -1.0, 0.0), gust_m_s=1.0, seed=7), 0.0)
    sim = VehicleSim(vehicle, world=world, seed=0)
    sim.reset(pos_ned=[0.0, 0.0, -30.0])
    sim.omega_rad_s[:] = sim.hover_omega_rad_s()
    return sim, SensorModel(vehicle, world.home, 0), sim.hover_omega_rad_s() / vehicle.omega_max_rad_s


def _cpu_us(fn: Callable[[int], object], rounds: int) -> float:
    """Minimum over ``rounds`` of the mean CPU µs of ``fn(k)`` over ``STEPS_PER_ROUND`` calls."""
    best = float("inf")
    for _ in range(rounds):
        t0 = time.thread_time()
        for k in range(STEPS_PER_ROUND):
            fn(k)
        best = min(best, (time.thread_time() - t0) / STEPS_PER_ROUND * 1e6)
    return best


def measure(rounds: int) -> dict[str, float]:
    """CPU µs per step of each part and of the whole sim-side step (keys as in ``run``)."""
    sim, sensors, hover = _setup()
    enc, dec = Encoder(SIM_SYSTEM_ID, SIM_COMPONENT_ID), Decoder()
    answer_enc = Encoder()
    answers = [answer_enc.actuators(ActuatorCommand(k, (hover,) * 4, True)) for k in range(STEPS_PER_ROUND)]
    frame = LockstepFrame(sensors.imu_baro_mag(sim), None, sim.ground_truth())
    cmd = (hover, hover, hover, hover)
    values, writer = SensorValues(sim, SensorModel(sim.vehicle, sim.world.home, 0)), FrameWriter()

    def datagram() -> bytes:
        return writer.write(values.values, sim.t_us, values.fill())

    def whole_step(k: int) -> None:
        datagram()
        (answer,) = dec.decode(answers[k])
        sim.step(answer.motor_cmd)  # type: ignore[union-attr]

    def whole_step_reference(k: int) -> None:
        f = LockstepFrame(sensors.imu_baro_mag(sim), sensors.gps(sim), sim.ground_truth())
        encode_frame(enc, f)
        (answer,) = dec.decode(answers[k])
        sim.step(answer.motor_cmd)  # type: ignore[union-attr]

    parts: dict[str, Callable[[int], object]] = {
        "sim_frame_fused_us": lambda k: datagram(),
        "sim_sensor_values_us": lambda k: values.fill(),
        "sim_sensors_us": lambda k: sensors.imu_baro_mag(sim),
        "sim_ground_truth_us": lambda k: sim.ground_truth(),
        "lockstep_frame_encode_us": lambda k: encode_frame(enc, frame),
        "lockstep_answer_decode_us": lambda k: dec.decode(answers[k]),
        "sim_physics_us": lambda k: sim.step(cmd),
        "sim_step_cpu_us": whole_step,
        "sim_step_reference_cpu_us": whole_step_reference,
    }
    _cpu_us(whole_step, 2)  # warm-up (JIT, caches)
    _cpu_us(whole_step_reference, 2)
    return {key: _cpu_us(fn, rounds) for key, fn in parts.items()}


def run(quick: bool) -> list[BenchResult]:
    us = measure(rounds=5 if quick else 20)
    notes = {
        "sim_frame_fused_us": "sensors + GPS (10 Hz) + truth (SensorValues) + datagram (FrameWriter), as sent",
        "sim_sensor_values_us": "sensors + GPS (10 Hz) + truth into the contract's values array, one numba call",
        "sim_sensors_us": "reference path: IMU + baro + mag sample (SensorModel.imu_baro_mag)",
        "sim_ground_truth_us": "reference path: VehicleSim.ground_truth (geodetic)",
        "lockstep_frame_encode_us": "reference path: HIL_STATE_QUATERNION + HIL_SENSOR datagram (encode_frame)",
        "lockstep_answer_decode_us": "HIL_ACTUATOR_CONTROLS datagram -> ActuatorCommand",
        "sim_physics_us": "one 250 Hz control step: 4 RK4 substeps at 1 kHz",
        "sim_step_cpu_us": "the sim side of a lockstep step (fused frame + answer decode + physics), CPU time",
        "sim_step_reference_cpu_us": "the same step with the reference frame path (sensors, gps, truth, encode_frame)",
    }
    return [BenchResult(key, value, note=notes[key]) for key, value in us.items()]
