"""The simulator process for a fleet world: every vehicle served to its own autopilot, one time (SPEC §13).

Vehicle i (instance i, MAV_SYS_ID i+1) has its own lockstep server on ``base port + i`` (14560+i, shifted by
``--instance``). Per control step::

    for each vehicle whose autopilot lives: traffic reports due + sensors -> one datagram -> send
    record the previous step (per-vehicle truth hashes) while the autopilots work
    for each of them: wait for its answer (each lockstep re-sends on its own)  -> time advances only now
    apply answers (a vehicle whose autopilot is gone: motors stopped) -> physics of all batches -> contacts

An autopilot that is silent for ``autopilot_timeout_s`` loses its vehicle: from then on its motors are stopped
(it falls), nobody waits for it, the summary reports when. The run ends at ``duration_s``, on a stop request,
when every autopilot is gone or when every vehicle has ended (crashed). The simulator is also every vehicle's
transponder receiver (``sim.traffic``): reports ride in the frame datagram, from component MAV_COMP_ID_ADSB.
"""

from __future__ import annotations

import json
import logging
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from mavlink_bridge.lockstep import AutopilotLost, LockstepInterrupted, LockstepServer
from mavlink_bridge.lockstep.answer_kernel import A_ARMED, A_GRIPPER_RELEASE, A_MOTORS
from mavlink_bridge.wire.codec import Encoder, Heartbeat
from mavlink_bridge.wire.frame_writer import FrameWriter
from mavlink_bridge.wire.link import LinkUrl
from mavlink_bridge.wire.traffic_codec import MAV_COMP_ID_ADSB, MAV_TYPE_ADSB
from sim.end_reason import EndReason
from sim.fleet import FleetSim
from sim.fleet_world import FleetSpec, load_fleet
from sim.server import DEFAULT_VEHICLE, SUMMARY_FILE, SimConfig, SimSetupError, mission_vehicle
from sim.traffic import MannedProximity, ScriptedTraffic, TrafficReceiver
from sim.vehicle_config import load_vehicle
from sim.world import load_world

log = logging.getLogger(__name__)
_MAV_AUTOPILOT_INVALID = 8
_RUNNING = int(EndReason.RUNNING)


@dataclass(frozen=True, slots=True)
class FleetVehicleSummary:
    """One vehicle's part of a fleet ``sim_summary.json``."""

    name: str
    sys_id: int
    vehicle: str
    sim_port: int
    end_reason: str
    autopilot_connected: bool
    autopilot_lost_at_s: float | None  # when its autopilot stopped answering (None: it never did)
    contacts: list[str]  # the vehicles it touched (each a COLLISION for both)
    min_separation_m: float | None  # closest approach to another vehicle, surface to surface
    min_clearance_m: float | None  # to the world's obstacles
    payload_released_at_s: float | None
    final_pos_ned_m: tuple[float, float, float]
    truth_sha256: str
    frames: int
    resends: int
    stale_answers: int
    foreign_datagrams: int
    invalid_answers: int
    traffic_reports: int  # reports its receiver sent (UTM + ADS-B)
    min_manned_distance_m: float | None  # closest 3D approach to a scripted aircraft (None: none flew)
    nmac_at_s: float | None  # first NMAC with a scripted aircraft (sim.traffic.NMAC_HOR_M/VER_M; None: none)


@dataclass(frozen=True, slots=True)
class FleetSummary:
    """``sim_summary.json`` of a fleet world: the run, what bounds its speed, then one entry per vehicle."""

    end_reason: str
    sim_time_s: float
    wall_time_s: float
    real_time_factor: float
    seed: int
    speed: float | None
    collisions: int  # vehicles that ended in a COLLISION (obstacles or each other)
    vehicle_contacts: int  # pairs of vehicles that touched
    manned_nmacs: int  # vehicles that came inside the NMAC volume of a scripted aircraft
    frames: int  # control steps
    sim_step_us: float  # mean wall time per step in the sim's own work (physics, sensors, datagrams, hashes)
    physics_us: float  # of which the batched physics and contacts
    answer_wait_us: float  # waiting for the slowest autopilot's answer (autopilot steps + transport)
    sim_cpu_us_per_step: float
    vehicles: list[FleetVehicleSummary]

    def to_json(self) -> str:
        """Pretty JSON, one key per line."""
        return json.dumps(asdict(self), indent=2) + "\n"

    def write(self, log_dir: Path) -> Path:
        """Write ``log_dir/sim_summary.json`` (creating the directory)."""
        log_dir.mkdir(parents=True, exist_ok=True)
        path = log_dir / SUMMARY_FILE
        path.write_text(self.to_json())
        return path


class FleetServer:
    """One fleet run: ``run()`` blocks until the end and returns the summary."""

    def __init__(self, config: SimConfig, fleet: FleetSpec | None = None) -> None:
        self.config = config
        if config.world_path is None or not config.world_path.is_file():
            raise SimSetupError(f"world: no such file {str(config.world_path)!r}")
        if config.speed is not None and not (config.speed > 0.0 and math.isfinite(config.speed)):
            raise SimSetupError(f"speed: expected 'max' or a positive number, got {config.speed}")
        self.world = load_world(config.world_path)
        self.fleet = fleet or load_fleet(config.world_path)
        if not self.fleet.is_fleet:
            raise SimSetupError(f"{config.world_path}: no vehicles: list (a single-vehicle world: use SimServer)")
        default = config.vehicle or mission_vehicle(config.world_path) or DEFAULT_VEHICLE
        names = [v.vehicle or default for v in self.fleet.vehicles]
        loaded = {name: load_vehicle(name) for name in dict.fromkeys(names)}
        self.airframes = tuple(loaded[name] for name in names)
        try:
            self.sim = FleetSim(
                self.world,
                self.fleet,
                self.airframes,
                seed=config.seed,
                physics_hz=config.physics_hz,
                control_hz=config.control_hz,
                sensor_noise=config.sensor_noise,
            )
            receiver = TrafficReceiver(
                self.world.home,
                tuple(v.sys_id for v in self.fleet.vehicles),
                ScriptedTraffic(self.fleet.traffic),
                config.control_hz,
                config.traffic_range_m,
            )
        except ValueError as exc:
            raise SimSetupError(str(exc)) from exc
        self.receiver = receiver
        self.proximity = MannedProximity(receiver.traffic, self.sim.n)
        base = LinkUrl.parse(config.listen_url)
        n = self.sim.n
        self.writers = [FrameWriter(v.sys_id) for v in self.fleet.vehicles]
        self.receiver_encoders = [Encoder(v.sys_id, MAV_COMP_ID_ADSB) for v in self.fleet.vehicles]
        self._receiver_heartbeat = Heartbeat(MAV_TYPE_ADSB, _MAV_AUTOPILOT_INVALID, 0, 0, 4)  # MAV_STATE_ACTIVE
        self.servers: list[LockstepServer] = []
        try:
            for i in range(n):
                self.servers.append(
                    LockstepServer(
                        f"udpin:{base.host}:{base.port + i if base.port else 0}",
                        resend_timeout_s=config.resend_timeout_s,
                        peer_lost_timeout_s=config.autopilot_timeout_s,
                        spin_s=config.lockstep_spin_s,
                        loss_fraction=config.loss_fraction,
                        loss_seed=self.sim.seeds[i],
                    )
                )
        except OSError:
            for server in self.servers:
                server.close()
            raise
        self.ports = [server.local_address[1] for server in self.servers]
        rate_hz = self.sim.obstacle_sensors[0].config.rate_hz
        self._detection_period_us = period_us = round(1e6 / rate_hz)
        control_us = 1_000_000 // config.control_hz
        # staggered over the period (vehicle i's first at i/n of it, on a control step): no step senses for all
        self._next_detection_us = [(i * period_us // n) // control_us * control_us for i in range(n)]
        self.alive = np.zeros(n, dtype=bool)  # autopilot answering
        self.connected = np.zeros(n, dtype=bool)
        self.lost_at_s: list[float | None] = [None] * n
        self.traffic_sent = np.zeros(n, dtype=np.int64)
        self._stop_requested = False
        self._heartbeat_due = False

    @property
    def local_addresses(self) -> list[tuple[str, int]]:
        """Where each vehicle's autopilot sends (vehicle i's lockstep server)."""
        return [server.local_address for server in self.servers]

    def request_stop(self) -> None:
        """Finish the run at the next step (signal-handler safe)."""
        self._stop_requested = True
        for server in self.servers:
            server.interrupt()

    # ---- the loop ------------------------------------------------------------------------------------
    def _wait_for_autopilots(self) -> None:
        """Until every vehicle's autopilot sent its HEARTBEAT (or the start timeout: the others never fly)."""
        cfg = self.config
        deadline = None if cfg.start_timeout_s is None else time.monotonic() + cfg.start_timeout_s
        waiting = list(range(self.sim.n))
        while waiting and not self._stop_requested:
            if deadline is not None and time.monotonic() >= deadline:
                log.warning("no HEARTBEAT from the autopilots of %s", [self.fleet.vehicles[i].name for i in waiting])
                break
            for i in list(waiting):
                if self.servers[i].wait_for_autopilot(0.01):
                    self.connected[i] = self.alive[i] = True
                    waiting.remove(i)

    def _datagram(self, i: int, reports: list, detect: bool) -> bytes:
        """Vehicle i's frame: receiver HEARTBEAT and traffic reports (when due), sensors, truth, detections."""
        sim = self.sim
        gps_due = sim.values[i].fill()
        detections = sim.detect(i) if detect else ()
        frame = self.writers[i].write(sim.values[i].values, sim.t_us, gps_due, detections)
        if not reports and not self._heartbeat_due:
            return frame
        encoder = self.receiver_encoders[i]
        head = [encoder.heartbeat(self._receiver_heartbeat)] if self._heartbeat_due else []
        head += [encoder.traffic(r) for r in reports]
        self.traffic_sent[i] += len(reports)
        return b"".join(head) + frame

    def _apply(self, i: int) -> None:
        """Vehicle i's answer into its motors (stopped when disarmed); a gripper release drops its payload."""
        answer = self.servers[i].answer
        if answer[A_GRIPPER_RELEASE] == 1.0 and self.sim.payload_kg(i) > 0.0:
            self.sim.release_payload(i)
        self.sim.set_motors(i, answer[A_MOTORS : A_MOTORS + 4] if answer[A_ARMED] == 1.0 else 0.0)

    def _lose(self, i: int, why: str) -> None:
        log.warning("%s: autopilot lost (%s); its motors stop", self.fleet.vehicles[i].name, why)
        self.alive[i] = False
        self.lost_at_s[i] = self.sim.t_s
        self.sim.set_motors(i, np.zeros(4))

    def run(self) -> FleetSummary:
        """Wait for the autopilots, then step in lockstep until an end condition; always returns a summary."""
        cfg, sim = self.config, self.sim
        wait_s = sleep_s = physics_s = 0.0
        end = EndReason.STOPPED
        wall0, cpu0 = time.perf_counter(), time.process_time()
        try:
            self._wait_for_autopilots()
            wall0, cpu0 = time.perf_counter(), time.process_time()
            unrecorded = False
            while True:
                if self._stop_requested:
                    break
                if cfg.duration_s is not None and sim.t_s >= cfg.duration_s - 1e-9:
                    end = EndReason.COMPLETED
                    break
                if not self.alive.any():
                    end = EndReason.AUTOPILOT_LOST
                    break
                if not sim.running.any():
                    end = EndReason(int(sim.end_reason.max()))
                    break
                t_us = sim.t_us
                self._heartbeat_due = self.receiver.heartbeat_due(sim.steps)
                reports = self.receiver.reports(sim.steps, t_us, sim.pos_ned, sim.vel_ned, self.alive)
                live = np.flatnonzero(self.alive).tolist()
                for i in live:
                    detect = t_us >= self._next_detection_us[i]
                    if detect:
                        self._next_detection_us[i] += self._detection_period_us
                    self.servers[i].send_datagram(t_us, self._datagram(i, reports[i], detect))
                if unrecorded:  # the state is unchanged until the answers: hash while the autopilots work
                    sim.record()
                wait0 = time.perf_counter()
                for i in live:
                    try:
                        self.servers[i].wait_answer_into()
                    except AutopilotLost as exc:
                        self._lose(i, str(exc))
                        continue
                    self._apply(i)
                wait_s += time.perf_counter() - wait0
                if self._stop_requested:
                    break
                physics0 = time.perf_counter()
                sim.step()
                self.proximity.update(sim.t_s, sim.pos_ned)
                physics_s += time.perf_counter() - physics0
                unrecorded = True
                if cfg.speed is not None:
                    ahead_s = wall0 + sim.t_s / cfg.speed - time.perf_counter()
                    if ahead_s > 0.0:
                        time.sleep(ahead_s)
                        sleep_s += ahead_s
            if unrecorded:
                sim.record()
        except LockstepInterrupted:
            end = EndReason.STOPPED
        finally:
            wall_s = time.perf_counter() - wall0
            cpu_s = time.process_time() - cpu0
            for server in self.servers:
                server.close()
        return self._summary(end, wall_s, (wait_s, sleep_s, physics_s, cpu_s))

    def _summary(self, end: EndReason, wall_s: float, timing: tuple[float, float, float, float]) -> FleetSummary:
        sim = self.sim
        wait_s, sleep_s, physics_s, cpu_s = timing
        steps = max(sim.steps, 1)
        vehicles = []
        for i, spec in enumerate(self.fleet.vehicles):
            code = int(sim.end_reason[i])
            if code == _RUNNING:
                gone = self.lost_at_s[i] is not None or not self.connected[i]
                code = int(EndReason.AUTOPILOT_LOST if gone else end)
            b, row = sim.rows[i]
            batch = sim.batches[b]
            clearance = float(batch.min_clearance_m[row])
            released = float(batch.payload_released_at_s[row])
            separation = float(sim.min_separation_m[i])
            manned_m = float(self.proximity.min_distance_m[i])
            stats = self.servers[i].stats
            pos = sim.pos_ned[i]
            vehicles.append(
                FleetVehicleSummary(
                    name=spec.name,
                    sys_id=spec.sys_id,
                    vehicle=self.airframes[i].name,
                    sim_port=self.ports[i],
                    end_reason=EndReason(code).name,
                    autopilot_connected=bool(self.connected[i]),
                    autopilot_lost_at_s=self.lost_at_s[i],
                    contacts=[self.fleet.vehicles[j].name for j in sim.contacts_of(i)],
                    min_separation_m=separation if math.isfinite(separation) else None,
                    min_clearance_m=clearance if math.isfinite(clearance) else None,
                    payload_released_at_s=released if math.isfinite(released) else None,
                    final_pos_ned_m=(float(pos[0]), float(pos[1]), float(pos[2])),
                    truth_sha256=sim.hashes[i].hexdigest(),
                    frames=stats.frames,
                    resends=stats.resends,
                    stale_answers=stats.stale_answers,
                    foreign_datagrams=stats.foreign,
                    invalid_answers=stats.invalid_answers,
                    traffic_reports=int(self.traffic_sent[i]),
                    min_manned_distance_m=manned_m if math.isfinite(manned_m) else None,
                    nmac_at_s=self.proximity.nmac_at_s[i],
                )
            )
        return FleetSummary(
            end_reason=end.name,
            sim_time_s=sim.t_s,
            wall_time_s=wall_s,
            real_time_factor=sim.t_s / wall_s if wall_s > 0.0 else 0.0,
            seed=self.config.seed,
            speed=self.config.speed,
            collisions=sum(v.end_reason == EndReason.COLLISION.name for v in vehicles),
            vehicle_contacts=len(sim.contacts),
            manned_nmacs=sum(v.nmac_at_s is not None for v in vehicles),
            frames=sim.steps,
            sim_step_us=(wall_s - wait_s - sleep_s) / steps * 1e6,
            physics_us=physics_s / steps * 1e6,
            answer_wait_us=wait_s / steps * 1e6,
            sim_cpu_us_per_step=cpu_s / steps * 1e6,
            vehicles=vehicles,
        )
