"""Lockstep messaging floor (SPEC §11): a null sim and a null autopilot, two processes over UDP.

The null sim sends the same frames as ``quadsitl sim`` (HIL_GPS at 10 Hz, HIL_STATE_QUATERNION,
HIL_SENSOR at 250 Hz) through ``LockstepServer``; the null autopilot, in another process, answers
each with a constant HIL_ACTUATOR_CONTROLS through ``LockstepClient``. No physics, no control:
the real-time factor measured here bounds any whole-flight ``lockstep_rtf``.

Both sides run the real processes' messaging code path per frame and nothing else: the null sim
writes frame k with the simulator's own sensor kernel and frame writer (``sim.frame_kernel.SensorValues``,
``mavlink_bridge.wire.frame_writer.FrameWriter``, on a vehicle
at rest whose clock is moved on instead of integrated), sends it and waits for the answer, which it
decodes; the null autopilot receives, decodes, builds its ``ActuatorCommand``, encodes and sends,
with the same busy-poll (``spin_s``) as the real processes. On a shared machine the floor varies run
to run: it is measured ``FLOOR_RUNS`` times and reported as the median with the range.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection

from mavlink_bridge.contract.wire import ActuatorCommand, GpsSample, GroundTruth, SensorSample
from mavlink_bridge.lockstep import DEFAULT_SPIN_S, LockstepClient, LockstepFrame, LockstepServer, encode_frame
from mavlink_bridge.wire.codec import Decoder, Encoder
from mavlink_bridge.wire.frame_writer import FrameWriter
from sim.frame_kernel import SensorValues
from sim.sensors import SensorModel
from sim.server import DEFAULT_VEHICLE
from sim.vehicle import VehicleSim
from sim.vehicle_config import load_vehicle
from sim.world import empty_world
from tools.benchmarks import BenchResult

CONTROL_HZ = 250
GPS_EVERY = CONTROL_HZ // 10
FLOOR_RUNS = 3


class NullSimFrames:
    """Frame ``k`` of a vehicle at rest, written by the simulator's frame writer (no physics in between)."""

    def __init__(self) -> None:
        vehicle = load_vehicle(DEFAULT_VEHICLE)
        world = empty_world()
        self._vehicle = VehicleSim(vehicle, control_hz=CONTROL_HZ, world=world, seed=0)
        self._values = SensorValues(self._vehicle, SensorModel(vehicle, world.home, 0))
        self._writer = FrameWriter()

    def datagram(self, k: int) -> tuple[int, bytes]:
        """(frame time µs, datagram) of control step ``k``: the clock moves, the state stays."""
        batch = self._vehicle.batch
        batch._steps = k  # the null sim only advances time (BatchSim keeps time as a step count)
        return batch.t_us, self._writer.write(self._values.values, batch.t_us, self._values.fill())


def null_frame(k: int) -> LockstepFrame:
    """Frame ``k`` of a vehicle hovering at 10 m as wire dataclasses (for the in-process codec measurement)."""
    t_us = k * 1_000_000 // CONTROL_HZ
    z = 1e-4 * k
    sensor = SensorSample(t_us, (0.01, -0.02, -9.81), (0.001, 0.002, z), (0.21, 0.01, 0.43), 1012.1, 10.0 + z, 20.0)
    truth = GroundTruth(
        t_us, (0.99, 0.01, 0.02, 0.1), (0.001, 0.002, z), 30.2635, 120.1233, 22.0 + z, (0.1, 0.2, z), (0.0, 0.0, -9.8)
    )
    gps = None
    if k % GPS_EVERY == 0:
        gps = GpsSample(t_us, 30.2635, 120.1233, 22.0 + z, (0.1, 0.2, z), 0.5, 0.8, 3, 12)
    return LockstepFrame(sensor, gps, truth, ())


def _null_autopilot(
    sim_url: str, idle_exit_s: float, warmup_frames: int, report: Connection, spin_s: float = DEFAULT_SPIN_S
) -> None:
    """Answer every frame with the same hover command until the sim has been silent for ``idle_exit_s``.

    Sends ``(CPU seconds, frames)`` after the warm-up through ``report`` when it exits.
    """
    frames = 0
    cpu0 = cpu_last = 0.0
    with LockstepClient(sim_url, heartbeat_period_s=0.05, spin_s=spin_s) as client:
        last_frame_s = time.monotonic()
        while time.monotonic() - last_frame_s < idle_exit_s:
            frame = client.next_frame(0.1)
            if frame is not None:
                last_frame_s = time.monotonic()
                client.answer(ActuatorCommand(frame.time_us, (0.55, 0.55, 0.55, 0.55), True))
                frames += 1
                cpu_last = time.process_time()
                if frames == warmup_frames:
                    cpu0 = cpu_last
    report.send((cpu_last - cpu0, frames - warmup_frames))


@dataclass(frozen=True, slots=True)
class FloorRun:
    """One floor measurement: wall-clock rate and each side's CPU per frame (load-independent)."""

    rtf: float
    frame_us: float  # wall time per frame exchange
    resends: int
    sim_cpu_us: float  # null sim process CPU per frame
    autopilot_cpu_us: float  # null autopilot process CPU per frame


def measure_floor_run(n_frames: int, warmup_frames: int = 200, spin_s: float = DEFAULT_SPIN_S) -> FloorRun:
    """``n_frames`` exchanges after a warm-up, null sim here and null autopilot in a spawned process.

    ``spin_s`` is both ends' busy-poll before sleeping (``LockstepServer``/``LockstepClient`` option).
    """
    frames = NullSimFrames()  # before the null autopilot starts: it gives up after idle_exit_s without frames
    server = LockstepServer("udpin:127.0.0.1:0", resend_timeout_s=0.02, peer_lost_timeout_s=5.0, spin_s=spin_s)
    host, port = server.local_address
    ctx = mp.get_context("spawn")
    report_rx, report_tx = ctx.Pipe(duplex=False)
    proc = ctx.Process(
        target=_null_autopilot, args=(f"udpout:{host}:{port}", 0.5, warmup_frames, report_tx, spin_s), daemon=True
    )
    proc.start()
    try:
        if not server.wait_for_autopilot(30.0):
            raise RuntimeError("null autopilot did not start")
        for k in range(warmup_frames):
            server.send_datagram(*frames.datagram(k))
            server.wait_answer()
        t0, cpu0 = time.perf_counter(), time.process_time()
        for k in range(warmup_frames, warmup_frames + n_frames):
            server.send_datagram(*frames.datagram(k))
            server.wait_answer()
        wall_s, cpu_s = time.perf_counter() - t0, time.process_time() - cpu0
        resends = server.stats.resends
        ap_cpu_s, ap_frames = report_rx.recv() if report_rx.poll(10.0) else (math.nan, 1)
    finally:
        server.close()
        proc.join(5.0)
        if proc.is_alive():
            proc.terminate()
    return FloorRun(
        n_frames / CONTROL_HZ / wall_s,
        wall_s / n_frames * 1e6,
        resends,
        cpu_s / n_frames * 1e6,
        ap_cpu_s / max(ap_frames, 1) * 1e6,
    )


def measure_codec_us(n: int = 2000) -> float:
    """Mean µs to encode a frame + decode it + encode and decode its answer (one process, no sockets)."""
    enc, dec = Encoder(), Decoder()
    frames = [null_frame(k) for k in range(n)]
    cmd_enc = Encoder()
    t0 = time.perf_counter()
    for f in frames:
        dec.decode(encode_frame(enc, f))
        dec.decode(cmd_enc.actuators(ActuatorCommand(f.time_us, (0.5, 0.5, 0.5, 0.5), True)))
    return (time.perf_counter() - t0) / n * 1e6


def run(quick: bool) -> list[BenchResult]:
    n_frames = 1500 if quick else 7500
    runs = sorted((measure_floor_run(n_frames) for _ in range(FLOOR_RUNS)), key=lambda r: r.rtf)
    mid = runs[len(runs) // 2]
    where = f"2 processes, UDP, {CONTROL_HZ} Hz, {n_frames} frames"
    return [
        BenchResult("lockstep_floor_rtf", mid.rtf, note=f"null sim + null autopilot, {where}, median of {FLOOR_RUNS}"),
        BenchResult("lockstep_floor_rtf_min", runs[0].rtf, note="slowest floor run"),
        BenchResult("lockstep_floor_rtf_max", runs[-1].rtf, note="fastest floor run"),
        BenchResult("lockstep_floor_frame_us", mid.frame_us, note="wall time per frame exchange (median run)"),
        BenchResult(
            "lockstep_floor_sim_cpu_us", min(r.sim_cpu_us for r in runs), note="null sim CPU per frame (best run)"
        ),
        BenchResult(
            "lockstep_floor_autopilot_cpu_us",
            min(r.autopilot_cpu_us for r in runs),
            note="null autopilot CPU per frame (best run)",
        ),
        BenchResult(
            "lockstep_floor_resends",
            float(sum(r.resends for r in runs)),
            note="frames re-sent, all runs (0 on loopback)",
        ),
        BenchResult("lockstep_codec_frame_us", measure_codec_us(), note="encode+decode frame and answer, in-process"),
    ]
