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

import logging
import math
import time

import numpy as np

from mavlink_bridge.lockstep import AutopilotLost, LockstepInterrupted, LockstepServer
from mavlink_bridge.wire.link import LinkUrl
from sim.end_reason import EndReason
from sim.fleet_run import FleetRun, FleetSummary, FleetVehicleSummary, LinkCounts, fleet_airframes
from sim.fleet_world import FleetSpec, load_fleet
from sim.server import DEFAULT_VEHICLE, SimConfig, SimSetupError, mission_vehicle
from sim.world import load_world

__all__ = ["FleetServer", "FleetSummary", "FleetVehicleSummary"]
log = logging.getLogger(__name__)


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
        self.airframes = fleet_airframes(self.fleet, default)
        try:
            self.fleet_run = FleetRun(
                self.world,
                self.fleet,
                self.airframes,
                seed=config.seed,
                physics_hz=config.physics_hz,
                control_hz=config.control_hz,
                sensor_noise=config.sensor_noise,
                traffic_range_m=config.traffic_range_m,
                recording=config.recording,
                recording_id=config.recording_id,
            )
        except ValueError as exc:
            raise SimSetupError(str(exc)) from exc
        self.sim = self.fleet_run.sim
        base = LinkUrl.parse(config.listen_url)
        n = self.sim.n
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
        self.alive = np.zeros(n, dtype=bool)  # autopilot answering
        self.connected = np.zeros(n, dtype=bool)
        self.lost_at_s: list[float | None] = [None] * n
        self._stop_requested = False

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

    def _lose(self, i: int, why: str) -> None:
        log.warning("%s: autopilot lost (%s); its motors stop", self.fleet.vehicles[i].name, why)
        self.alive[i] = False
        self.lost_at_s[i] = self.sim.t_s
        self.fleet_run.stop_motors(i)

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
                live = []
                for i, datagram in self.fleet_run.frames(self.alive):
                    self.servers[i].send_datagram(t_us, datagram)
                    live.append(i)
                if unrecorded:  # the state is unchanged until the answers: hash while the autopilots work
                    sim.record()
                wait0 = time.perf_counter()
                for i in live:
                    try:
                        self.servers[i].wait_answer_into()
                    except AutopilotLost as exc:
                        self._lose(i, str(exc))
                        continue
                    self.fleet_run.apply(i, self.servers[i].answer)
                wait_s += time.perf_counter() - wait0
                if self._stop_requested:
                    break
                physics0 = time.perf_counter()
                self.fleet_run.advance()
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
            self.fleet_run.close()
        return self._summary(end, wall_s, (wait_s, sleep_s, physics_s, cpu_s))

    def _summary(self, end: EndReason, wall_s: float, timing_s: tuple[float, float, float, float]) -> FleetSummary:
        links = [
            LinkCounts(st.frames, st.resends, st.stale_answers, st.foreign, st.invalid_answers)
            for st in (server.stats for server in self.servers)
        ]
        vehicles = self.fleet_run.summaries(end, self.connected, self.lost_at_s, links, self.ports)
        cfg = self.config
        return self.fleet_run.summary(end, vehicles, seed=cfg.seed, speed=cfg.speed, wall_s=wall_s, timing_s=timing_s)
