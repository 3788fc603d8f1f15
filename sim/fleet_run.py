"""One world's run without sockets (SPEC §12, §13): what the simulator does for every vehicle each control step.

``FleetRun`` owns the vehicles (:class:`~sim.fleet.FleetSim`; a world without ``vehicles:`` is a fleet of one),
their transponder receivers (:class:`~sim.traffic.TrafficReceiver`; a world of one vehicle without ``traffic:``
has none: its datagrams are the single-vehicle simulator's), the manned-traffic proximity truth and the world part
of the recording. Per control step its user (the UDP server ``sim.server`` or the in-process flight
``tools.campaign.inproc_flight``) does::

    frames = run.frames(alive)          # per live vehicle: receiver HEARTBEAT + traffic due + sensors -> datagram
    ...each autopilot answers...        # run.apply(i, answer) / run.stop_motors(i) for a lost one;
                                        # run.uplink(i, reports): its own UTM reports that came with the answer
    run.advance()                       # physics of all batches, contacts, manned proximity, recording

so both transports fly the same bytes and the same physics. ``flights_over()`` (checked by both before a step when
the run should end with the flight, ``--end-when-landed``) says when every vehicle has flown and is done: armed
once, now disarmed on the ground, or ended (crash, contact). ``summaries`` turns the end state into the
per-vehicle part of ``sim_summary.json``, ``summary`` into the whole (``sim.summary_file``).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mavlink_bridge.lockstep.answer_kernel import A_ARMED, A_GRIPPER_RELEASE, A_MOTORS
from mavlink_bridge.wire.codec import Encoder, Heartbeat
from mavlink_bridge.wire.frame_writer import FrameWriter
from mavlink_bridge.wire.traffic_codec import MAV_COMP_ID_ADSB, MAV_TYPE_ADSB
from sim.end_reason import EndReason
from sim.fleet import FleetSim, world_vehicles
from sim.fleet_world import FleetSpec
from sim.separation_events import MannedPairs, pair_events
from sim.summary_file import FleetSummary, FleetVehicleSummary, LinkCounts
from sim.traffic import MannedProximity, ScriptedTraffic, TrafficLinkConfig, TrafficReceiver
from sim.vehicle_config import VehicleConfig, load_vehicle
from sim.world import World

if TYPE_CHECKING:
    from sim.world_recording import WorldRecorder

log = logging.getLogger(__name__)
_MAV_AUTOPILOT_INVALID = 8
_MAV_STATE_ACTIVE = 4
_RUNNING = int(EndReason.RUNNING)


class FleetRun:
    """The vehicles, receivers and truth of one run, stepped by a transport (see the module docstring)."""

    def __init__(
        self,
        world: World,
        fleet: FleetSpec,
        airframes: tuple[VehicleConfig, ...],
        *,
        seed: int = 0,
        physics_hz: int = 1000,
        control_hz: int = 250,
        sensor_noise: bool = True,
        traffic_link: TrafficLinkConfig | None = None,
        recording: Path | None = None,
        recording_id: str = "",
    ) -> None:
        """ValueError for vehicles placed in contact, a bad rate or bad traffic-link numbers. ``traffic_link``:
        the receivers' link (None: the world's ``traffic_link:`` over the defaults)."""
        self.fleet = fleet
        self.airframes = airframes
        self.sim = sim = FleetSim(
            world, fleet, airframes, seed=seed, physics_hz=physics_hz, control_hz=control_hz, sensor_noise=sensor_noise
        )
        self.vehicles = vehicles = sim.vehicles
        self.receiver = TrafficReceiver(
            world.home,
            tuple(v.sys_id for v in vehicles),
            ScriptedTraffic(fleet.traffic),
            control_hz,
            traffic_link or TrafficLinkConfig.with_overrides(fleet.traffic_link),
            seed,
        )
        self.receiving = fleet.is_fleet or bool(fleet.traffic)  # a lone vehicle in an empty sky has no receiver
        self.proximity = MannedProximity(self.receiver.traffic, sim.n)
        self.manned_pairs = MannedPairs(self.receiver.traffic, sim.n)
        names = [v.name for v in vehicles]
        self.recorder: WorldRecorder | None = None
        if recording is not None:  # imported here: rerun costs a process without a recording half a second to load
            from sim.world_recording import WorldRecorder

            self.recorder = WorldRecorder(names, self.receiver.traffic, recording, recording_id)
        self.writers = [FrameWriter(v.sys_id) for v in vehicles]
        self.receiver_encoders = [Encoder(v.sys_id, MAV_COMP_ID_ADSB) for v in vehicles]
        self._receiver_heartbeat = Heartbeat(MAV_TYPE_ADSB, _MAV_AUTOPILOT_INVALID, 0, 0, _MAV_STATE_ACTIVE)
        n = sim.n
        period_us = round(1e6 / sim.obstacle_sensors[0].config.rate_hz)
        self._detection_period_us = period_us
        control_us = 1_000_000 // control_hz
        # staggered over the period (vehicle i's first at i/n of it, on a control step): no step senses for all
        self._next_detection_us = [(i * period_us // n) // control_us * control_us for i in range(n)]
        self.traffic_sent = np.zeros(n, dtype=np.int64)
        self._no_reports: list[list] = [[] for _ in range(n)]
        self._armed_seen = [False] * n  # the answers said armed at least once
        self._armed = [False] * n  # the last answer said armed

    @property
    def n(self) -> int:
        return self.sim.n

    def frames(self, alive: np.ndarray) -> Iterator[tuple[int, bytes]]:
        """``(vehicle, datagram)`` for each vehicle whose autopilot is alive (``alive`` (n,) bool), this step:
        its receiver's HEARTBEAT and traffic reports when due, sensors, truth, obstacle detections when due.
        A generator (a transport sends each before the next is built); consume it whole, once per step."""
        sim = self.sim
        t_us = sim.t_us
        heartbeat_due, reports = False, self._no_reports
        if self.receiving:
            heartbeat_due = self.receiver.heartbeat_due(sim.steps)
            reports = self.receiver.reports(sim.steps, t_us, sim.pos_ned, alive)
        for i, live in enumerate(alive.tolist()):  # one conversion, no index array per step
            if not live:
                continue
            detect = t_us >= self._next_detection_us[i]
            if detect:
                self._next_detection_us[i] += self._detection_period_us
            gps_due = sim.values[i].fill()
            detections = sim.detect(i) if detect else ()
            frame = self.writers[i].write(sim.values[i].values, t_us, gps_due, detections)
            if reports[i] or heartbeat_due:
                encoder = self.receiver_encoders[i]
                head = [encoder.heartbeat(self._receiver_heartbeat)] if heartbeat_due else []
                head += [encoder.traffic(r) for r in reports[i]]
                self.traffic_sent[i] += len(reports[i])
                frame = b"".join(head) + frame
            yield i, frame

    def apply(self, i: int, answer: np.ndarray) -> None:
        """Vehicle i's decoded answer (``answer_kernel`` layout) into its motors (stopped when disarmed); a
        gripper release drops its payload."""
        if answer[A_GRIPPER_RELEASE] == 1.0 and self.sim.payload_kg(i) > 0.0:
            self.sim.release_payload(i)
            who = f"{self.vehicles[i].name}: " if self.fleet.is_fleet else ""
            log.info("%spayload released at t=%.3f s", who, self.sim.t_s)
        armed = bool(answer[A_ARMED] == 1.0)
        self._armed[i] = armed
        if armed:
            self._armed_seen[i] = True
        self.sim.set_motors(i, answer[A_MOTORS : A_MOTORS + 4] if armed else 0.0)

    def flights_over(self) -> bool:
        """True when every vehicle's flight is over: it was armed and is now disarmed on the ground, or it ended
        (crash, contact, non-finite state). A vehicle never armed is not over (it has not flown yet)."""
        seen, armed, on_ground = self._armed_seen, self._armed, self.sim.on_ground
        for i, end in enumerate(self.sim.end_reason.tolist()):
            if end == _RUNNING and not (seen[i] and not armed[i] and on_ground[i]):  # in flight: no array look-up
                return False
        return True

    def uplink(self, i: int, reports: tuple[object, ...] | list[object]) -> None:
        """Vehicle i's own UTM_GLOBAL_POSITION reports (decoded) that came with its answer to this step's frame:
        relayed to the others by the receivers (``TrafficReceiver.uplink``), when the world has receivers."""
        if self.receiving and reports:
            self.receiver.uplink(i, self.sim.t_us, reports)

    def stop_motors(self, i: int) -> None:
        """Vehicle i's autopilot is gone: its motors stop (it falls; disarmed for ``flights_over``)."""
        self._armed[i] = False
        self.sim.set_motors(i, np.zeros(4))

    def advance(self) -> None:
        """Physics of every vehicle one control step, contacts, manned proximity, the world recording."""
        sim = self.sim
        sim.step()
        self.proximity.update(sim.t_s, sim.pos_ned, sim.on_ground)
        self.manned_pairs.update(sim.t_s, sim.pos_ned, sim.on_ground)
        if self.recorder is not None:
            self.recorder.sample(sim.t_us, sim.pos_ned)

    def close(self) -> None:
        """Write the world part of the recording (when recording)."""
        if self.recorder is not None:
            self.recorder.write()

    def summaries(
        self,
        end: EndReason,
        connected: np.ndarray,
        lost_at_s: list[float | None],
        links: list[LinkCounts],
        ports: list[int],
    ) -> list[FleetVehicleSummary]:
        """Every vehicle's end state: a vehicle still running ends with ``end``, or AUTOPILOT_LOST when its autopilot
        was lost or never connected while others flew."""
        sim = self.sim
        out = []
        anyone = bool(np.any(connected))
        for i, spec in enumerate(self.vehicles):
            code = int(sim.end_reason[i])
            if code == _RUNNING:
                lost = lost_at_s[i] is not None or (anyone and not connected[i])
                code = int(EndReason.AUTOPILOT_LOST if lost else end)
            b, row = sim.rows[i]
            batch = sim.batches[b]
            link = links[i]
            pos = sim.pos_ned[i]
            out.append(
                FleetVehicleSummary(
                    name=spec.name,
                    sys_id=spec.sys_id,
                    vehicle=self.airframes[i].name,
                    sim_port=ports[i],
                    end_reason=EndReason(code).name,
                    autopilot_connected=bool(connected[i]),
                    autopilot_lost_at_s=lost_at_s[i],
                    contacts=[self.vehicles[j].name for j in sim.contacts_of(i)],
                    min_separation_m=_finite(sim.min_separation_m[i]),
                    min_volume_sep_m=_finite(sim.min_volume_sep_m[i]),
                    min_clearance_m=_finite(batch.min_clearance_m[row]),
                    payload_released_at_s=_finite(batch.payload_released_at_s[row]),
                    final_pos_ned_m=(float(pos[0]), float(pos[1]), float(pos[2])),
                    truth_sha256=sim.hashes[i].hexdigest(),
                    frames=link.frames,
                    resends=link.resends,
                    stale_answers=link.stale_answers,
                    foreign_datagrams=link.foreign,
                    invalid_answers=link.invalid_answers,
                    traffic_reports=int(self.traffic_sent[i]),
                    min_manned_distance_m=_finite(self.proximity.min_distance_m[i]),
                    nmac_at_s=self.proximity.nmac_at_s[i],
                )
            )
        return out

    def summary(
        self,
        end: EndReason,
        vehicles: list[FleetVehicleSummary],
        *,
        seed: int,
        speed: float | None,
        wall_s: float,
        timing_s: tuple[float, float, float, float],
    ) -> FleetSummary:
        """The run's summary; ``timing_s`` = (answer wait, pacing sleep, physics, process CPU) in seconds."""
        sim = self.sim
        wait_s, sleep_s, physics_s, cpu_s = timing_s
        steps = max(sim.steps, 1)
        names = [v.name for v in self.vehicles]
        callsigns = [a.callsign for a in self.receiver.traffic.aircraft]
        manned = self.manned_pairs
        # a pair also inside in flight is an event, not an exclusion
        volume_ground = {k: t for k, t in sim.volume_pairs_ground.items() if k not in sim.volume_pairs}
        nmac_ground = {k: t for k, t in manned.ground.items() if k not in manned.airborne}
        return FleetSummary(
            end_reason=end.name,
            sim_time_s=sim.t_s,
            wall_time_s=wall_s,
            real_time_factor=sim.t_s / wall_s if wall_s > 0.0 else 0.0,
            seed=seed,
            speed=speed,
            collisions=sum(v.end_reason == EndReason.COLLISION.name for v in vehicles),
            vehicle_contacts=len(sim.contacts),
            manned_nmacs=sum(v.nmac_at_s is not None for v in vehicles),
            frames=sim.steps,
            sim_step_us=(wall_s - wait_s - sleep_s) / steps * 1e6,
            physics_us=physics_s / steps * 1e6,
            answer_wait_us=wait_s / steps * 1e6,
            sim_cpu_us_per_step=cpu_s / steps * 1e6,
            vehicles=vehicles,
            volume_events=pair_events(sim.volume_pairs, names, names),
            volume_ground_excluded=pair_events(volume_ground, names, names),
            nmac_events=pair_events(manned.airborne, names, callsigns),
            nmac_ground_excluded=pair_events(nmac_ground, names, callsigns),
        )


def fleet_airframes(fleet: FleetSpec, default: str) -> tuple[VehicleConfig, ...]:
    """Each vehicle's airframe (its ``vehicle:``, else ``default``), each airframe file loaded once."""
    names = [v.vehicle or default for v in world_vehicles(fleet)]
    loaded = {name: load_vehicle(name) for name in dict.fromkeys(names)}
    return tuple(loaded[name] for name in names)


def _finite(value: float) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None
