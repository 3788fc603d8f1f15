"""Compile every numba kernel once and write numba's on-disk cache (run by the Makefile after install).

The physics, world, sensor and control kernels are ``@njit(cache=True)``: the first process that
calls one compiles it (tens of seconds on a small machine) and writes ``*.nbi|nbc`` to the directory
``mavlink_bridge.contract.jit_cache`` keys by every kernel source; later processes load it in milliseconds.
Doing it at setup keeps that first compile out of the lockstep, where a silent autopilot would be declared
lost, and out of the first ``make run``.

Usage: ``python -m tools.warm_jit`` (idempotent; a warm cache makes it take about a second).
"""

from __future__ import annotations

import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np


def warm() -> dict[str, float]:
    """Exercise every cached kernel with the argument types the processes use; seconds per part. The simulator's
    and the bridge's kernels compile in a second process while this one compiles the autopilot's (two cores:
    the compile is CPU-bound and numba writes each kernel's cache file atomically)."""
    with ProcessPoolExecutor(max_workers=1) as pool:
        sim_and_bridge = pool.submit(_warm_sim_and_bridge)
        timings = _warm_autopilot()
        timings.update(_warm_traffic())
        timings.update(sim_and_bridge.result())
    return timings


def _warm_sim_and_bridge() -> dict[str, float]:
    timings = _warm_sim()
    timings.update(_warm_bridge())
    timings.update(_warm_cascade_arrays())
    return timings


def _warm_cascade_arrays() -> dict[str, float]:
    """The cascade's array paths (one vehicle, and a batch), which the tuning tools and the controller tests call;
    the autopilot itself flies the scalar path (warmed with it). In this process, beside the autopilot's warm-up."""
    t0 = time.perf_counter()
    from autopilot.control import CascadeController, CascadeGains, load_airframe

    airframe, gains, level = load_airframe("x500"), CascadeGains.paper_default(), np.array([1.0, 0.0, 0.0, 0.0])
    z3 = np.zeros(3)
    CascadeController(airframe, gains, n=1).update_position(z3, z3, level, z3, z3, z3, z3, 0.0)
    z = np.zeros((2, 3))
    CascadeController(airframe, gains, n=2).update_position(z, z, np.tile(level, (2, 1)), z, z, z, z, np.zeros(2))
    return {"cascade_arrays_s": time.perf_counter() - t0}


def _warm_sim() -> dict[str, float]:
    """The physics, world, sensor and frame kernels of the simulator."""
    t0 = time.perf_counter()
    from mavlink_bridge.wire.frame_writer import FrameWriter
    from sim.batch import BatchSim
    from sim.frame_kernel import SensorValues
    from sim.obstacle_sensor import ObstacleSensor
    from sim.sensors import SensorModel
    from sim.separation_kernel import pair_separation_step
    from sim.vehicle import VehicleSim
    from sim.vehicle_config import load_vehicle
    from sim.world import load_world

    vehicle = load_vehicle("x500")
    world = load_world(
        {
            "world": {
                "obstacles": [
                    {"cylinder": {"north_m": 20, "east_m": 0, "radius_m": 2, "height_m": 20}},
                    {"box": {"north_m": 40, "east_m": 0, "size_m": [4, 4, 20], "yaw_deg": 10}},
                    {"sphere": {"north_m": 60, "east_m": 0, "alt_m": 10, "radius_m": 2}},
                ],
                "wind": {"north_m_s": 1.0, "east_m_s": 0.0, "down_m_s": 0.0, "gust_m_s": 0.5, "seed": 1},
            }
        }
    )
    single = VehicleSim(vehicle, world=world, seed=1)
    sensors = SensorModel(vehicle, world.home, 1)
    single.step(np.full(4, 0.6))
    sensors.imu_baro_mag(single)
    single.ground_truth()
    values = SensorValues(single, SensorModel(vehicle, world.home, 1))  # sim.frame_kernel
    FrameWriter().write(values.values, single.t_us, values.fill())  # mavlink_bridge.wire.frame_writer
    ObstacleSensor(world, seed=1).detect(single.pos_ned, single.q_ned_frd, 0)
    batch = BatchSim(vehicle, 3, world=world, seed=1)
    batch.step(np.full((3, 4), 0.6))
    for pos_ned in (batch.state[:, 0:3], np.zeros((3, 3))):  # one airframe's view of its batch, a mixed fleet's copy
        n, seen = len(pos_ned), np.zeros((3, 3), dtype=np.bool_)
        pair_separation_step(
            pos_ned,
            np.ones(n),
            batch.on_ground,
            10.0,
            5.0,
            np.full(n, np.inf),
            np.full(n, np.inf),
            seen.copy(),
            seen.copy(),
            seen.copy(),
            np.zeros((n * n, 3), dtype=np.int64),
        )  # sim.separation_kernel
    return {"sim_s": time.perf_counter() - t0}


def _warm_autopilot() -> dict[str, float]:
    """The cascade and EKF kernels of the autopilot."""
    t0 = time.perf_counter()
    from autopilot.control.airframe import load_airframe
    from autopilot.control.cascade import CascadeController
    from autopilot.control.gains import CascadeGains
    from autopilot.runner import Autopilot, AutopilotConfig

    Autopilot(AutopilotConfig(vehicle="x500", estimator="ekf"))  # warms the cascade and the EKF kernels
    batch = CascadeController(load_airframe("x500"), CascadeGains.paper_default(), 3)
    z3, q3 = np.zeros((3, 3)), np.tile([1.0, 0.0, 0.0, 0.0], (3, 1))
    batch.update_position(z3, z3, q3, z3, z3, z3, z3, np.zeros(3))
    batch.update_attitude(q3, z3, z3, np.full(3, 10.0))
    return {"autopilot_s": time.perf_counter() - t0}


def _warm_traffic() -> dict[str, float]:
    """The reactive layer's ORCA kernels (every autopilot with traffic solves at 50 Hz): one solve that finds an
    admissible velocity and one that has none (a closing ring and a stack: the fallback's least violation)."""
    t0 = time.perf_counter()
    from autopilot.traffic.param_decls import TrafficParams
    from autopilot.traffic.reactive import Phase, ReactiveLayer, ReactiveLimits
    from autopilot.traffic.tracks import TrafficTrack
    from mavlink_bridge.contract.traffic import TrafficSource

    def uav(sys_id: int, pos: tuple[float, float, float], vel: tuple[float, float, float]) -> TrafficTrack:
        return TrafficTrack(TrafficSource.UAV, sys_id, "", pos, vel, 0)

    limits = ReactiveLimits(
        speed_xy_m_s=12.0, up_m_s=3.0, down_m_s=1.5, acc_m_s2=3.0, floor_down_m=-2.0, ceiling_down_m=-120.0
    )
    params, own, still = TrafficParams(), (0.0, 0.0, -15.0), (0.0, 0.0, 0.0)
    ReactiveLayer(1).solve(0, own, still, (0.0, 5.0, 0.0), [uav(2, (0.0, 40.0, -15.0), (0.0, -5.0, 0.0))], params,
                           limits, Phase.MISSION)  # fmt: skip
    angles = np.arange(8) * np.pi / 4.0
    crowd = [uav(10 + k, (12.0 * np.cos(a), 12.0 * np.sin(a), -15.0), (-8.0 * np.cos(a), -8.0 * np.sin(a), 0.0))
             for k, a in enumerate(angles)]  # fmt: skip
    crowd += [uav(30, (0.0, 0.0, -21.0), (0.0, 0.0, 3.0)), uav(31, (0.0, 0.0, -9.0), (0.0, 0.0, -3.0))]
    command = ReactiveLayer(1).solve(0, own, still, (0.0, 5.0, 0.0), crowd, params, limits, Phase.MISSION)
    if command is None or not command.fallback:  # a check of this warm-up itself, kept under python -O
        raise RuntimeError("warm_jit: the crowd left an admissible velocity, so least_violating was not compiled")
    return {"traffic_s": time.perf_counter() - t0}


def _warm_bridge() -> dict[str, float]:
    """The geodetic, frame reader and lockstep answer kernels both processes use."""
    t0 = time.perf_counter()
    from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame

    LocalNedFrame(GeoPoint(47.0, 8.0, 400.0)).geodetic_from_ned(1.0, 2.0, -3.0)  # contract.geodetic kernels
    LocalNedFrame(GeoPoint(47.0, 8.0, 400.0)).ned_from_geodetic(47.0, 8.0, 401.0)
    from mavlink_bridge.wire.frame_reader import new_out, read_values

    read_values(b"", new_out())  # the lockstep reader both processes use (codec.Decoder)
    from mavlink_bridge.lockstep.answer_kernel import N_ANSWER, AnswerWriter, read_answer

    AnswerWriter(1, 1).write(0, (0.5, 0.5, 0.5, 0.5), True, False, True)  # the autopilot's answer
    read_answer(np.zeros(128, dtype=np.uint8), 0, 0, np.zeros(N_ANSWER), np.zeros(96, dtype=np.uint8))  # the sim's
    return {"bridge_s": time.perf_counter() - t0}


def main() -> int:
    print(
        "[setup] compiling the numba kernels (physics, controller, codec, traffic): about 35 s the first time, "
        "a few seconds once cached...",
        flush=True,
    )
    t0 = time.perf_counter()
    timings = warm()
    parts = ", ".join(f"{k} {v:.1f}" for k, v in timings.items())
    print(f"numba kernels compiled and cached in {time.perf_counter() - t0:.1f} s ({parts})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
