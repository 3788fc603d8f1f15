"""The simulator process: the vehicles of a world served to their autopilots over the lockstep (SPEC §4, §12, §13).

A world without ``vehicles:`` is a fleet of one (``sim.fleet_run``). Vehicle i (MAV_SYS_ID i+1) has its own
lockstep server on the listen port + i. Loop per control step (``control_hz``, default 250 Hz)::

    for each vehicle whose autopilot lives: traffic reports due + sensors + truth + detections -> datagram -> send
    record the previous step (truth hashes, tilt, truth log) while the autopilots work
    for each of them: wait for its answer (each lockstep re-sends on its own)  -> time advances only now
    apply answers (armed -> motors, else 0; gripper release -> payload dropped) -> physics of all -> contacts
    end checks (every vehicle ended, duration, stop request, every autopilot lost, with ``end_when_landed``
    every flight over: ``FleetRun.flights_over``) -> pacing (``--speed``)

Time is owned here and only advances after every answer for the current step arrived, so a run is a
deterministic function of (world, vehicles, seed, autopilots) at any ``speed``; the wall clock only paces
(``speed`` = sim seconds per wall second, None = as fast as possible). Before the HEARTBEATs the sim does not
advance (it waits for every autopilot, up to ``start_timeout_s``; when none came the run ends STOPPED). An
autopilot silent for ``autopilot_timeout_s`` loses its vehicle: its motors stop (it falls), nobody waits for it;
when every autopilot is lost the run ends AUTOPILOT_LOST at once (with one vehicle: when its autopilot is). On
exit a summary is returned (and written as ``sim_summary.json`` by the CLI): a ``SimSummary`` for a world
without ``vehicles:``, else a ``FleetSummary`` (``sim.summary_file``).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from mavlink_bridge.lockstep import DEFAULT_SPIN_S, AutopilotLost, LockstepInterrupted, LockstepServer
from mavlink_bridge.wire.link import LinkUrl
from sim.end_reason import EndReason
from sim.fleet_run import FleetRun, fleet_airframes
from sim.fleet_world import FleetSpec, load_fleet
from sim.summary_file import FleetSummary, LinkCounts, SimSummary, solo_summary
from sim.traffic_link import TrafficLinkConfig
from sim.world import empty_world, load_world

log = logging.getLogger(__name__)

DEFAULT_VEHICLE = "x500"


class SimSetupError(ValueError):
    """The world, vehicle or options were refused; the message says which and why."""


@dataclass(frozen=True, slots=True)
class SimConfig:
    """Everything a simulator run needs (the CLI options of SPEC §12)."""

    listen_url: str = "udpin:127.0.0.1:14560"  # vehicle 0's; vehicle i listens on its port + i
    world_path: Path | None = None
    vehicle: str | None = None  # name or path; None: the mission's ``vehicle:`` or DEFAULT_VEHICLE
    seed: int = 0
    speed: float | None = None  # sim s per wall s; None = as fast as possible
    duration_s: float | None = None  # sim time limit; None = until stopped
    end_when_landed: bool = False  # end COMPLETED once every vehicle flew and is disarmed on the ground
    physics_hz: int = 1000
    control_hz: int = 250
    autopilot_timeout_s: float = 3.0  # wall seconds of silence before AUTOPILOT_LOST
    start_timeout_s: float | None = None  # wall seconds to wait for the first HEARTBEAT; None = forever
    resend_timeout_s: float = 0.02  # ceiling of the adaptive resend timeout (wall s)
    sensor_noise: bool = True
    truth_log: Path | None = None  # .npz of the truth state at control rate
    recording: Path | None = None  # a fleet world: the world part of the run's Rerun recording (.rrd)
    recording_id: str = ""  # that recording's id (the autopilots' own)
    lockstep_spin_s: float = DEFAULT_SPIN_S  # busy-poll for the answer before sleeping (0 = never)
    loss_fraction: float = 0.0  # > 0: the lockstep drops this share of datagrams each way (seeded; --sim-loss)
    #: the traffic link's numbers given on the command line, ``(TrafficLinkConfig field, value)``: over the world's
    #: ``traffic_link:`` and the defaults (``--traffic-range-m`` is ``adsb_range_m``)
    traffic_link: tuple[tuple[str, float], ...] = ()


def mission_vehicle(world_path: Path | None) -> str | None:
    """The ``vehicle:`` of a mission YAML (None: no file, or none named)."""
    if world_path is None:
        return None
    doc: Any = yaml.safe_load(world_path.read_text())
    vehicle = doc.get("vehicle") if isinstance(doc, dict) else None
    return vehicle if isinstance(vehicle, str) else None


def _listen_url(base: LinkUrl, i: int) -> str:
    """Vehicle i's lockstep address: the base port + i (0 stays 0: any free port)."""
    return f"udpin:{base.host}:{base.port + i if base.port else 0}"


class SimServer:
    """One simulator run of a world's vehicles: ``run()`` blocks until the end and returns the summary."""

    def __init__(self, config: SimConfig, fleet: FleetSpec | None = None) -> None:
        """``fleet``: the world's fleet part when already loaded (default: read from ``config.world_path``)."""
        self.config = config
        if config.speed is not None and not (config.speed > 0.0 and math.isfinite(config.speed)):
            raise SimSetupError(f"speed: expected 'max' or a positive number, got {config.speed}")
        if config.world_path is not None and not config.world_path.is_file():
            raise SimSetupError(f"world: no such file {str(config.world_path)!r}")
        if not 0.0 <= config.loss_fraction < 1.0:
            raise SimSetupError(f"sim loss: expected a fraction in [0, 1), got {config.loss_fraction}")
        path = config.world_path
        self.world = load_world(path) if path else empty_world()
        self.fleet = fleet or (load_fleet(path) if path else FleetSpec(self.world.home, (), ()))
        self.solo = not self.fleet.is_fleet  # a world without vehicles: (the single-vehicle summary and logs)
        self.airframes = fleet_airframes(self.fleet, config.vehicle or mission_vehicle(path) or DEFAULT_VEHICLE)
        try:
            self.fleet_run = FleetRun(
                self.world,
                self.fleet,
                self.airframes,
                seed=config.seed,
                physics_hz=config.physics_hz,
                control_hz=config.control_hz,
                sensor_noise=config.sensor_noise,
                traffic_link=TrafficLinkConfig.with_overrides(self.fleet.traffic_link, config.traffic_link),
                recording=config.recording,
                recording_id=config.recording_id,
            )
        except ValueError as exc:
            raise SimSetupError(str(exc)) from exc
        self.sim = self.fleet_run.sim
        self.names = [v.name for v in self.fleet_run.vehicles]
        base = LinkUrl.parse(config.listen_url)
        n = self.sim.n
        self.servers: list[LockstepServer] = []
        try:
            for i in range(n):
                self.servers.append(
                    LockstepServer(
                        _listen_url(base, i),
                        resend_timeout_s=config.resend_timeout_s,
                        peer_lost_timeout_s=config.autopilot_timeout_s,
                        spin_s=config.lockstep_spin_s,
                        loss_fraction=config.loss_fraction,  # --sim-loss: dropped at this end, both ways, seeded
                        loss_seed=self.sim.seeds[i],  # one vehicle: the run's seed
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
    def local_address(self) -> tuple[str, int]:
        """Where vehicle 0's autopilot sends (its lockstep server)."""
        return self.servers[0].local_address

    @property
    def local_addresses(self) -> list[tuple[str, int]]:
        """Where each vehicle's autopilot sends (vehicle i's lockstep server)."""
        return [server.local_address for server in self.servers]

    def request_stop(self) -> None:
        """Finish the run at the next step (signal-handler safe): end reason STOPPED."""
        self._stop_requested = True
        for server in self.servers:
            server.interrupt()

    def _wait_for_autopilots(self) -> None:
        """Until every vehicle's autopilot sent its HEARTBEAT, a stop, or the start timeout (the others never fly)."""
        cfg = self.config
        deadline = None if cfg.start_timeout_s is None else time.monotonic() + cfg.start_timeout_s
        if self.solo:
            log.info("waiting for the autopilot HEARTBEAT on %s:%d", *self.local_address)
        else:
            log.info("waiting for the autopilots' HEARTBEATs on ports %s", self.ports)
        waiting = list(range(self.sim.n))
        while waiting and not self._stop_requested:
            remaining = 0.25 if deadline is None else min(0.25, deadline - time.monotonic())
            if remaining <= 0.0:
                if self.solo:
                    log.warning("no autopilot HEARTBEAT within %.1f s", cfg.start_timeout_s)
                else:
                    log.warning("no HEARTBEAT from the autopilots of %s", [self.names[i] for i in waiting])
                return
            for i in list(waiting):
                if self.servers[i].wait_for_autopilot(remaining / len(waiting)):
                    log.info("autopilot connected" if self.solo else f"{self.names[i]}: autopilot connected")
                    self.connected[i] = self.alive[i] = True
                    waiting.remove(i)

    def _lose(self, i: int, why: str) -> None:
        if self.solo:
            log.warning("autopilot lost: %s", why)
        else:
            log.warning("%s: autopilot lost (%s); its motors stop", self.names[i], why)
        self.alive[i] = False
        self.lost_at_s[i] = self.sim.t_s
        self.fleet_run.stop_motors(i)

    def _answers(self, live: list[int]) -> bool:
        """Wait for the answers of the vehicles in ``live`` and apply them (a silent one is lost); False when a
        stop interrupted the wait."""
        for i in live:
            server = self.servers[i]
            try:
                server.wait_answer_into()
            except AutopilotLost as exc:
                self._lose(i, str(exc))
                continue
            except LockstepInterrupted:
                return False
            self.fleet_run.apply(i, server.answer)
            if server.own_reports:
                self.fleet_run.uplink(i, server.own_reports)
        return True

    def run(self) -> SimSummary | FleetSummary:
        """Wait for the autopilots, then step in lockstep until an end condition; always returns a summary."""
        cfg, sim, run = self.config, self.sim, self.fleet_run
        truth_rows: list[np.ndarray] = []

        def record() -> None:
            sim.record()
            if cfg.truth_log is not None:
                truth_rows.append(np.concatenate([[sim.t_s], *(sim.state_row(i) for i in range(sim.n))]))

        wait_s = sleep_s = physics_s = 0.0
        end = EndReason.STOPPED
        unrecorded = False  # a step is integrated but not yet in the hashes / tilt / truth log
        wall0, cpu0 = time.perf_counter(), time.process_time()
        try:
            self._wait_for_autopilots()
            wall0, cpu0 = time.perf_counter(), time.process_time()
            while True:
                if not sim.any_running():
                    end = EndReason(int(sim.end_reason.max()))
                    break
                if self._stop_requested:
                    break
                if cfg.duration_s is not None and sim.t_s >= cfg.duration_s - 1e-9:
                    end = EndReason.COMPLETED
                    break
                if cfg.end_when_landed and run.flights_over():
                    end = EndReason.COMPLETED
                    break
                if not self.alive.any():  # nobody connected: STOPPED before the start
                    end = EndReason.AUTOPILOT_LOST if self.connected.any() else EndReason.STOPPED
                    break
                t_us = sim.t_us
                live = []
                for i, datagram in run.frames(self.alive):
                    self.servers[i].send_datagram(t_us, datagram)
                    live.append(i)
                if unrecorded:  # the state is unchanged until the answers: record while the autopilots work
                    record()
                    unrecorded = False
                wait0 = time.perf_counter()
                answered = self._answers(live)
                wait_s += time.perf_counter() - wait0
                if not answered:
                    break
                if not self.alive.any():  # the last autopilot is lost: the run ends before another step
                    end = EndReason.AUTOPILOT_LOST
                    break
                physics0 = time.perf_counter()
                run.advance()
                physics_s += time.perf_counter() - physics0
                unrecorded = True
                if cfg.speed is not None:
                    ahead_s = wall0 + sim.t_s / cfg.speed - time.perf_counter()
                    if ahead_s > 0.0:
                        time.sleep(ahead_s)
                        sleep_s += ahead_s
            if unrecorded:
                record()
        finally:
            wall_s = time.perf_counter() - wall0
            cpu_s = time.process_time() - cpu0
            for server in self.servers:
                server.close()
            run.close()
        if cfg.truth_log is not None:
            self._write_truth_log(cfg.truth_log, truth_rows)
        return self._summary(end, wall_s, (wait_s, sleep_s, physics_s, cpu_s))

    def _write_truth_log(self, path: Path, rows: list[np.ndarray]) -> None:
        """``t_s`` (steps,) and ``state`` (steps, 17): pos_ned, vel_ned, q_ned_frd, rate_frd, omega_rad_s; a fleet
        world's ``state`` is (steps, vehicles, 17)."""
        n = self.sim.n
        data = np.array(rows) if rows else np.zeros((0, 1 + 17 * n))
        state = data[:, 1:] if self.solo else data[:, 1:].reshape(len(data), n, 17)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, t_s=data[:, 0], state=state)

    def _summary(
        self, end: EndReason, wall_s: float, timing_s: tuple[float, float, float, float]
    ) -> SimSummary | FleetSummary:
        links = []
        for server in self.servers:
            st = server.stats
            links.append(
                LinkCounts(
                    st.frames,
                    st.resends,
                    st.stale_answers,
                    st.foreign,
                    st.invalid_answers,
                    st.malformed,
                    st.resend_timeout_us,
                    st.exchange_us,
                    server.dropped,
                )
            )
        run, cfg = self.fleet_run, self.config
        vehicles = run.summaries(end, self.connected, self.lost_at_s, links, self.ports)
        summary = run.summary(end, vehicles, seed=cfg.seed, speed=cfg.speed, wall_s=wall_s, timing_s=timing_s)
        return solo_summary(summary, links[0], self.sim.max_tilt_deg(0)) if self.solo else summary
