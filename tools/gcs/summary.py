"""What ``fly`` found: one :class:`FlySummary` per vehicle (``fly --summary`` of a single-vehicle mission writes it
as is; of a fleet world, one per vehicle in :meth:`FleetFlight.to_json` with the closest approach seen), and the
rules that judge a vehicle's flight from its telemetry and status texts.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

from mavlink_bridge.contract.status_texts import first_failsafe, is_bypassed
from mavlink_bridge.contract.vehicle_api import LandedState, StatusText
from mavlink_bridge.gcs_client.client import VehicleStatus

MISSION_STATE_COMPLETE = 5
#: How the reason of a vehicle given up as stuck (no mission progress for too long) begins: a campaign row whose
#: vehicle was stuck ends ``STUCK`` (tools.campaign.fleet_record).
STUCK_PREFIX = "stuck:"
#: Sim seconds without mission progress (an item reached, a change of landed state or arming) that give a moving
#: vehicle of a fleet world up as stuck, in the ground station (``--stall-s``) and in a campaign's in-process judge.
#: Time enough to give way and come back: a vehicle that fled a light aircraft 250-300 m out and back, or a slow
#: one on a 300 m leg, reaches its next item well after 120 s (7 of the 8 encounter cases judged STUCK at 120 s
#: completed every vehicle when given 400 s, the last at 333 s of sim; 2026-12-02).
FLEET_STALL_S = 300.0
#: Sim seconds without mission progress and without motion (within STILL_MOVE_M of where it last moved or
#: progressed) that give a vehicle up as stuck sooner: time enough to hold for traffic and resume.
FLEET_STILL_S = 60.0
STILL_MOVE_M = 2.0
#: A vehicle within this of its home's height is on its pad (waiting there, for traffic say, is not being stuck).
PAD_AGL_M = 1.5


@dataclass(slots=True)
class ProgressWatch:
    """Whether a vehicle's flight still progresses (the one rule of the fleet ground station and the campaign's
    in-process judge): stuck after ``stall_s`` of sim time without mission progress (an item reached, a change of
    landed state or arming; None: never), or after ``still_s`` without progress and without motion in the air (on
    its pad, within ``PAD_AGL_M`` of home's height, a vehicle may wait longer: a departure held for traffic)."""

    stall_s: float | None = FLEET_STALL_S
    still_s: float = FLEET_STILL_S
    progress: tuple[object, ...] = ()
    progress_at_s: float = 0.0
    still_ned: tuple[float, float, float] | None = None  # where it was when it last moved or progressed
    still_at_s: float = 0.0

    def stuck(self, t_s: float, progress: tuple[object, ...], pos_ned_m: Sequence[float] | None) -> str:
        """Update at sim time ``t_s`` with the vehicle's progress and position (NED about home, m; None: unknown,
        only the stall rule applies); the stuck reason (``stuck: ...``) once it is stuck, else ''."""
        if progress != self.progress:
            self.progress, self.progress_at_s = progress, t_s
        pos = None if pos_ned_m is None else (float(pos_ned_m[0]), float(pos_ned_m[1]), float(pos_ned_m[2]))
        if pos is not None and -pos[2] < PAD_AGL_M:  # on the pad: waiting there is not being stuck
            pos, self.still_ned = None, None
        moved = pos is not None and (self.still_ned is None or math.dist(pos, self.still_ned) > STILL_MOVE_M)
        if self.progress_at_s == t_s or moved:
            self.still_ned, self.still_at_s = pos, t_s
        if pos is not None and t_s - self.still_at_s > self.still_s:
            why = f"no mission progress and no motion (within {STILL_MOVE_M:g} m) for {self.still_s:g} s of sim time"
            return stuck_reason(why)
        if self.stall_s is not None and t_s - self.progress_at_s > self.stall_s:
            why = f"no mission progress for {self.stall_s:g} s of sim time (moving, not along its mission)"
            return stuck_reason(why)
        return ""


def stuck_reason(why: str) -> str:
    """The reason of a vehicle given up as stuck: ``stuck: <why>``."""
    return f"{STUCK_PREFIX} {why}"


def is_stuck(reason: str) -> bool:
    return reason.startswith(STUCK_PREFIX)


@dataclass(frozen=True, slots=True)
class FlySummary:
    """One vehicle's flight, as ``fly --summary`` writes it (SPEC §12)."""

    ok: bool
    items_total: int
    items_reached: int
    sim_time_s: float | None
    wall_time_s: float
    landed: bool
    disarmed: bool
    reason: str
    items_bypassed: int = 0  # waypoints the vehicle flew around instead of reaching ("Bypassed item N: ...")

    def to_json(self) -> str:
        return json.dumps(asdict(self), indent=2) + "\n"


@dataclass(frozen=True, slots=True)
class VehicleFlight:
    """A vehicle's summary with its name, system id and the sim time its flight began at (None: never heard)."""

    name: str
    sys_id: int
    summary: FlySummary
    start_sim_s: float | None


@dataclass(frozen=True, slots=True)
class FleetFlight:
    """Every vehicle's flight and the closest approach of two vehicles' centres the ground station saw."""

    vehicles: tuple[VehicleFlight, ...]
    stagger_s: float
    min_separation_seen_m: float | None
    wall_time_s: float

    @property
    def ok(self) -> bool:
        return all(v.summary.ok for v in self.vehicles)

    def to_json(self) -> str:
        """The fleet summary: one entry per vehicle (name, sys_id and its FlySummary's fields) and the fleet's."""
        rows = [{"name": v.name, "sys_id": v.sys_id, **asdict(v.summary)} for v in self.vehicles]
        sep = self.min_separation_seen_m
        summary = {
            "ok": self.ok,
            "vehicles": rows,
            "stagger_s": self.stagger_s,
            "min_separation_seen_m": None if sep is None else round(sep, 2),
            "wall_time_s": self.wall_time_s,
        }
        return json.dumps(summary, indent=2) + "\n"


def mission_done(status: VehicleStatus, total: int) -> bool:
    """The vehicle reports its mission complete, or reached its last item."""
    return status.mission_state == MISSION_STATE_COMPLETE or (total > 0 and total - 1 in status.items_reached)


def failsafe_reason(texts: Sequence[StatusText]) -> str:
    """A mission during which a failsafe fired (a geofence breach too, even when GF_ACTION only warns) failed:
    the first such STATUSTEXT is the reason; empty when none fired."""
    text = first_failsafe(t.text for t in texts)
    return f"failsafe during the mission: {text}" if text else ""


def fly_summary(
    status: VehicleStatus, texts: Sequence[StatusText], total: int, reason: str, wall_time_s: float
) -> FlySummary:
    """The summary of a flight that ended in ``status`` with the status texts ``texts`` sent since it began;
    ``reason`` is why the ground station gave it up (empty: it did not); the vehicle's last error is appended to it."""
    errors = [t.text for t in texts if t.severity <= 3]
    if reason and errors:
        reason += f" (last error: {errors[-1]})"
    reason = reason or failsafe_reason(texts)
    landed = status.landed_state is LandedState.ON_GROUND
    return FlySummary(
        ok=not reason and landed and not status.armed and mission_done(status, total),
        items_total=total,
        items_reached=len(status.items_reached),
        sim_time_s=status.sim_time_s,
        wall_time_s=round(wall_time_s, 3),
        landed=landed,
        disarmed=not status.armed,
        reason=reason,
        items_bypassed=sum(is_bypassed(t.text) for t in texts),
    )
