"""``sim_summary.json``: the file every simulator run writes (SPEC §12, §13), in one of two shapes.

A fleet world's run is a :class:`FleetSummary` (the run, then one :class:`FleetVehicleSummary` per vehicle); a
world without ``vehicles:`` keeps the single-vehicle :class:`SimSummary` (SPEC §12 keys first, then extras),
which :func:`solo_summary` takes from the fleet summary of its one vehicle and that vehicle's link counters.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

from sim.separation_events import PairEvent

SUMMARY_FILE = "sim_summary.json"


class SummaryFile:
    """Mixin of the frozen summary dataclasses: their JSON text and ``log_dir/sim_summary.json``."""

    __slots__ = ()

    def to_json(self) -> str:
        """Pretty JSON, one key per line."""
        return json.dumps(asdict(self), indent=2) + "\n"  # type: ignore[call-overload]

    def write(self, log_dir: Path) -> Path:
        """Write ``log_dir/sim_summary.json`` (creating the directory)."""
        log_dir.mkdir(parents=True, exist_ok=True)
        path = log_dir / SUMMARY_FILE
        path.write_text(self.to_json())
        return path


@dataclass(frozen=True, slots=True)
class LinkCounts:
    """One vehicle's lockstep link counters (all 0 but ``frames`` when no link carries the frames)."""

    frames: int = 0
    resends: int = 0
    stale_answers: int = 0
    foreign: int = 0
    invalid_answers: int = 0
    malformed: int = 0
    resend_timeout_us: float = 0.0  # the adaptive resend timeout at the end of the run
    exchange_us: float = 0.0  # smoothed frame-to-answer time (the resend timeout's basis)
    loss_dropped: int = 0  # datagrams --sim-loss dropped, both ways


@dataclass(frozen=True, slots=True)
class FleetVehicleSummary:
    """One vehicle's part of a fleet ``sim_summary.json``."""

    name: str
    sys_id: int
    vehicle: str
    sim_port: int  # its lockstep port (0: flown in process)
    end_reason: str
    autopilot_connected: bool
    autopilot_lost_at_s: float | None  # when its autopilot stopped answering (None: it never did)
    contacts: list[str]  # the vehicles it touched (each a COLLISION for both)
    min_separation_m: float | None  # closest approach to another vehicle, surface to surface
    min_volume_sep_m: float | None  # closest airborne approach, max(hor, ver * 2): < 10 m is inside (sim.fleet)
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
class FleetSummary(SummaryFile):
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
    # pair-events (sim.separation_events): each pair once, with the sim time it first came inside
    volume_events: list[PairEvent]  # pairs of airborne vehicles inside the UAV volume (10 m / 5 m at once)
    volume_ground_excluded: list[PairEvent]  # pairs inside it only while one of them stood on the ground
    nmac_events: list[PairEvent]  # (vehicle, aircraft callsign) inside the NMAC volume with the vehicle in flight
    nmac_ground_excluded: list[PairEvent]  # the same only while the vehicle was on (or within 1.5 m of) the ground


@dataclass(frozen=True, slots=True)
class SimSummary(SummaryFile):
    """``sim_summary.json`` of a world without ``vehicles:`` (SPEC §12 keys first, then extras)."""

    end_reason: str
    sim_time_s: float
    wall_time_s: float
    real_time_factor: float
    collisions: int
    min_clearance_m: float | None  # None when the world has no obstacles
    payload_released_at_s: float | None
    max_tilt_deg: float
    vehicle: str
    seed: int
    speed: float | None
    autopilot_connected: bool
    frames: int
    resends: int
    stale_answers: int
    malformed: int
    foreign_datagrams: int  # lockstep datagrams from anyone but the autopilot that started it: dropped unread
    invalid_answers: int  # answers stamped ahead of the frame or with motors NaN / outside [0, 1]: never applied
    resend_timeout_us: float  # the adaptive resend timeout at the end of the run
    exchange_us: float  # smoothed frame-to-answer time (the resend timeout's basis)
    loss_dropped: int  # datagrams --sim-loss dropped, both ways (0 without it)
    final_pos_ned_m: tuple[float, float, float]
    truth_sha256: str  # hash of the truth state after every control step (determinism checks)
    sim_step_us: float  # mean wall time per step in the sim itself (all but the answer wait and pacing sleeps)
    answer_wait_us: float  # mean wall time per step waiting for the answer (autopilot step + transport)
    sim_cpu_us_per_step: float  # process CPU time per step (the sim's own work; unlike wall time, load-independent)


def solo_summary(run: FleetSummary, link: LinkCounts, max_tilt_deg: float) -> SimSummary:
    """The single-vehicle shape of a fleet-of-one run: its one vehicle's entry, its link's counters, its tilt."""
    (v,) = run.vehicles
    return SimSummary(
        end_reason=v.end_reason,
        sim_time_s=run.sim_time_s,
        wall_time_s=run.wall_time_s,
        real_time_factor=run.real_time_factor,
        collisions=run.collisions,
        min_clearance_m=v.min_clearance_m,
        payload_released_at_s=v.payload_released_at_s,
        max_tilt_deg=max_tilt_deg,
        vehicle=v.vehicle,
        seed=run.seed,
        speed=run.speed,
        autopilot_connected=v.autopilot_connected,
        frames=link.frames,
        resends=link.resends,
        stale_answers=link.stale_answers,
        malformed=link.malformed,
        foreign_datagrams=link.foreign,
        invalid_answers=link.invalid_answers,
        resend_timeout_us=link.resend_timeout_us,
        exchange_us=link.exchange_us,
        loss_dropped=link.loss_dropped,
        final_pos_ned_m=v.final_pos_ned_m,
        truth_sha256=v.truth_sha256,
        sim_step_us=run.sim_step_us,
        answer_wait_us=run.answer_wait_us,
        sim_cpu_us_per_step=run.sim_cpu_us_per_step,
    )
