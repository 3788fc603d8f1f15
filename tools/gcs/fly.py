"""``python -m tools.gcs fly FILE``: the ground station flies a mission file's vehicle, or every vehicle of a fleet
world (``vehicles:``), by one path: a single-vehicle mission is a fleet of one (SPEC §12, §13).

Vehicle i of the file is system id ``--system`` + i (a fleet world from ``quadsitl up --world``: 1..n), all on the
one GCS port. The ground station waits to hear every vehicle, waits for each one's 3D GPS fix and uploads its fence
and mission, then arms and starts vehicle 0 and each next one ``--stagger-s`` seconds of sim time later (0: all
together), shows one progress bar per vehicle and waits until each has landed and disarmed. Each is judged on its
own: done (mission complete, landed, disarmed, no failsafe during it), failed (landed early, a failsafe, a refused
upload or arming, the wall-clock limit), telemetry lost (silent for ``LOST_AFTER_S`` of wall time: its autopilot
died) or stalled (no item reached, no change of landed state or arming for ``--stall-s`` of sim time: a crashed
vehicle, which a fleet's simulator freezes while the others fly on; default 300 s for a fleet world, off for a
single-vehicle mission, whose simulator ends the run on a crash). The others fly on.

``--summary PATH``: a single-vehicle mission's :class:`~tools.gcs.summary.FlySummary`, a fleet world's
:meth:`~tools.gcs.summary.FleetFlight.to_json` (one per vehicle and the closest approach of two vehicles' centres
seen in their GLOBAL_POSITION_INT; the simulator's ``sim_summary.json`` has the true surface-to-surface figure).
Exit code 0 only when every vehicle succeeded.
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from autopilot.mission.files import load_fleet_missions, load_mission_file
from autopilot.mission.plan import MissionPlan
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.vehicle_api import CommandResult, FlightMode, LandedState, MissionResult, MissionType
from mavlink_bridge.gcs_client.client import (
    CommandFailedError,
    GcsClient,
    GcsError,
    MissionUploadError,
    VehicleStatus,
)
from mavlink_bridge.gcs_client.fleet_link import FleetLink
from tools.gcs.link import GcsScriptError, say, vehicle_clients
from tools.gcs.progress import MissionBars, flight_state_text, sim_time_text
from tools.gcs.summary import (
    FLEET_STALL_S,
    FleetFlight,
    ProgressWatch,
    VehicleFlight,
    fly_summary,
    mission_done,
)

#: Wall seconds without any message from a flying vehicle before the ground station gives it up.
LOST_AFTER_S = 10.0
_SETUP_TIMEOUT_S = 60.0
_PUMP_S = 0.01  # each vehicle's turn in the follow loop


@dataclass(frozen=True, slots=True)
class FlyOptions:
    """How to fly: wall-clock limit, sim seconds between take-offs, sim seconds without progress that fail a vehicle
    (None: never), progress bars."""

    timeout_s: float
    stagger_s: float = 0.0
    stall_s: float | None = None
    progress: bool = True


@dataclass(slots=True)
class _Vehicle:
    """One vehicle's flight as the ground station follows it."""

    plan: MissionPlan
    client: GcsClient
    start_sim_s: float | None = None
    started: bool = False
    seen_armed: bool = False
    text_serial: int = 0
    reason: str = ""
    done: bool = False
    t_done: float = 0.0
    status: VehicleStatus | None = None
    watch: ProgressWatch | None = None  # the stuck rule (a fleet world's; None: not judged)
    frame: LocalNedFrame | None = None  # about its home: the positions the stuck rule compares
    geo: tuple[float, float, float] | None = None  # latest reported lat_deg, lon_deg, alt AMSL (m)


def fly(
    link: FleetLink, clients: Sequence[GcsClient], plans: Sequence[MissionPlan], options: FlyOptions
) -> FleetFlight:
    """Fly ``plans[i]`` with ``clients[i]`` (clients of ``link``, their vehicles heard) until each is judged."""
    t0 = time.monotonic()
    vehicles = [_Vehicle(plan, client) for plan, client in zip(plans, clients, strict=True)]
    for v in vehicles:
        with contextlib.suppress(GcsError):  # the flight's own sim time counts from here (SYSTEM_TIME: 1 Hz)
            v.client.wait_until(lambda s: s.sim_time_s is not None, min(3.0, options.timeout_s))
        v.start_sim_s, v.text_serial = v.client.telemetry().sim_time_s, v.client.statustext_serial
    for v in vehicles:
        say(f"{v.plan.name} (system {v.client.target_system}): fence and mission")
        try:
            upload_when_ready(v.client, v.plan, min(_SETUP_TIMEOUT_S, options.timeout_s))
            v.client.forget_reached_items()
        except (GcsError, GcsScriptError) as exc:
            v.reason, v.done = f"upload failed: {exc}", True
    sep_m = _follow(vehicles, link, options, t0)
    flights = tuple(
        VehicleFlight(
            name=v.plan.name,
            sys_id=v.client.target_system,
            summary=fly_summary(
                v.client.telemetry(),
                v.client.statustexts_since(v.text_serial),
                len(v.plan.items),
                v.reason,
                (v.t_done or time.monotonic()) - t0,
            ),
            start_sim_s=v.start_sim_s,
        )
        for v in vehicles
    )
    return FleetFlight(flights, options.stagger_s, sep_m, round(time.monotonic() - t0, 3))


def upload_when_ready(client: GcsClient, plan: MissionPlan, timeout_s: float) -> None:
    """Wait for a 3D GPS fix, then upload fence + mission, retrying while the vehicle is not ready yet."""
    deadline = time.monotonic() + timeout_s
    if client.telemetry().gps_fix_type < 3:
        say("waiting for the vehicle's 3D GPS fix")
    try:
        client.wait_until(lambda s: s.gps_fix_type >= 3, timeout_s)
    except GcsError as exc:
        raise GcsScriptError(f"no 3D GPS fix reported within {timeout_s:g} s") from exc
    say(f"uploading {len(plan.items)} mission items and {len(plan.fence)} fence items")
    while True:
        try:
            client.upload_mission(plan.fence, MissionType.FENCE)  # first: the mission is checked against it
            client.upload_mission(plan.items, MissionType.MISSION)
            return
        except MissionUploadError as exc:
            transient = exc.result in (MissionResult.ERROR, MissionResult.DENIED)
            if not transient or time.monotonic() >= deadline:
                raise
            client.pump(0.5)


def arm_when_ready(client: GcsClient, timeout_s: float) -> None:
    """Arm, retrying while the vehicle refuses (estimator or GPS not ready yet) until ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    said = False
    while True:
        try:
            client.arm()
            say("armed")
            return
        except CommandFailedError as exc:
            if exc.result not in (CommandResult.DENIED, CommandResult.TEMPORARILY_REJECTED, CommandResult.FAILED):
                raise
            if time.monotonic() >= deadline:
                raise GcsScriptError(f"arming refused for {timeout_s:g} s: {exc}") from exc
            if not said:
                say(f"waiting until the vehicle accepts arming (it says: {exc.text})")
                said = True
            client.pump(0.5)


def _follow(vehicles: list[_Vehicle], link: FleetLink, options: FlyOptions, t0: float) -> float | None:
    """Arm and start each vehicle at its turn, and follow every one until it is done (one progress bar each); the
    closest approach of two vehicles' centres seen (None: never two known at once)."""
    deadline = t0 + options.timeout_s
    min_sep_m = math.inf
    first_start_s: float | None = None
    rows = [(v.plan.name, len(v.plan.items)) for v in vehicles]
    with MissionBars("[bold]{task.description:<10}", rows, enabled=options.progress) as bars:
        while not all(v.done for v in vehicles):
            for i, v in enumerate(vehicles):
                if v.done:
                    continue
                v.client.pump(_PUMP_S)
                status = v.status = v.client.telemetry()
                if not v.started:
                    now_s = status.sim_time_s
                    if first_start_s is None and now_s is not None:
                        first_start_s = now_s
                    if (
                        first_start_s is not None
                        and now_s is not None
                        and now_s >= first_start_s + i * options.stagger_s
                    ):
                        _start(v, options.timeout_s)
                else:
                    _judge(v, link, options.stall_s)
                if status.lat_deg is not None and status.home is not None and status.alt_rel_m is not None:
                    v.geo = (status.lat_deg, status.lon_deg or 0.0, status.home.alt_amsl_m + status.alt_rel_m)
                _show(bars, i, v)
            min_sep_m = min(min_sep_m, _separation_now_m(vehicles))
            if time.monotonic() >= deadline:
                for v in vehicles:
                    if not v.done:
                        v.reason, v.done = f"not landed and disarmed after {options.timeout_s:g} s", True
    return min_sep_m if math.isfinite(min_sep_m) else None


def _start(v: _Vehicle, timeout_s: float) -> None:
    v.started = True
    try:
        arm_when_ready(v.client, min(_SETUP_TIMEOUT_S, timeout_s))
        try:
            v.client.start_mission()
        except CommandFailedError:
            v.client.set_mode(FlightMode.AUTO_MISSION)
        say(f"{v.plan.name}: mission started")
    except (GcsError, GcsScriptError) as exc:
        v.reason, v.done = f"start failed: {exc}", True


def _judge(v: _Vehicle, link: FleetLink, stall_s: float | None) -> None:
    """Done when landed and disarmed (mission complete or not), when the vehicle went silent, or when it is stuck
    by :class:`ProgressWatch` (``stall_s`` of sim time without mission progress, or a minute without progress and
    without motion once armed; ``stall_s`` None: never)."""
    status = v.client.telemetry()
    progress = (len(status.items_reached), int(status.landed_state), status.armed)
    v.seen_armed = v.seen_armed or status.armed  # armed in telemetry at least once (a fast sim may finish first)
    stuck = ""
    if stall_s is not None and status.sim_time_s is not None:
        if v.watch is None:
            v.watch = ProgressWatch(stall_s)
        pos = None
        if v.seen_armed and v.geo is not None:
            v.frame = v.frame or LocalNedFrame(v.plan.home)
            pos = v.frame.ned_from_geodetic(*v.geo)
        stuck = v.watch.stuck(status.sim_time_s, progress, pos)
    total = len(v.plan.items)
    landed_disarmed = not status.armed and status.landed_state is LandedState.ON_GROUND
    if landed_disarmed and mission_done(status, total):
        v.done = True
    elif landed_disarmed and v.seen_armed:
        v.client.pump(0.5)  # late MISSION_ITEM_REACHED / MISSION_CURRENT
        if not mission_done(v.client.telemetry(), total):
            v.reason = "the vehicle landed and disarmed before the mission was complete"
        v.done = True
    elif time.monotonic() - link.last_heard_s.get(v.client.target_system, -math.inf) > LOST_AFTER_S:
        v.reason, v.done = f"no telemetry from the vehicle for {LOST_AFTER_S:g} s (its autopilot is gone?)", True
    elif stuck:
        v.reason, v.done = stuck, True
    if v.done:
        v.t_done = time.monotonic()


def _separation_now_m(vehicles: list[_Vehicle]) -> float:
    """The smallest distance between two vehicles' centres (their own latest position reports) while one of the
    two is armed; inf when fewer than two are known."""
    live = [v for v in vehicles if v.geo is not None and v.status is not None]
    best = math.inf
    if len(live) < 2:
        return best
    frame = LocalNedFrame(live[0].plan.home)
    ned = [frame.ned_from_geodetic(*v.geo) for v in live if v.geo is not None]
    for (a, pa), (b, pb) in itertools.combinations(zip(live, ned, strict=True), 2):
        if a.status is not None and b.status is not None and (a.status.armed or b.status.armed):
            best = min(best, math.dist(pa, pb))
    return best


def _show(bars: MissionBars, index: int, v: _Vehicle) -> None:
    """Vehicle ``index``'s bar: items reached, then waiting / mode, arming and landed state / done / FAILED, and
    sim time."""
    if v.status is None:
        return
    state = f"{flight_state_text(v.status)} {v.status.landed_state.name}" if v.started else "waiting to start"
    if v.done:
        state = "FAILED: " + v.reason[:40] if v.reason else "done"
    bars.show(index, len(v.status.items_reached), f"{state} t={sim_time_text(v.status)}")


def cmd_fly(args: argparse.Namespace, url: str, signing_key: bytes | None) -> str:
    """``fly FILE``: the one-line result; GcsScriptError when any vehicle failed (after writing ``--summary``)."""
    if args.stagger_s < 0.0 or not math.isfinite(args.stagger_s):
        raise GcsScriptError(f"--stagger-s must be a finite number >= 0, got {args.stagger_s:g}")
    fleet = load_fleet_missions(args.file)
    plans = fleet or [load_mission_file(args.file)]
    stall_s = args.stall_s if args.stall_s is not None else (FLEET_STALL_S if fleet else None)
    options = FlyOptions(args.timeout_s, args.stagger_s, stall_s, progress=not args.no_progress)
    sys_ids = [args.system + i for i in range(len(plans))]
    with vehicle_clients(
        url, sys_ids, signing_key=signing_key, step_timeout_s=args.timeout_step_s, wait_s=args.wait_s
    ) as (link, clients):
        flight = fly(link, clients, plans, options)
    if args.summary:
        Path(args.summary).parent.mkdir(parents=True, exist_ok=True)
        Path(args.summary).write_text(flight.to_json() if fleet else flight.vehicles[0].summary.to_json())
    return _fleet_result(flight) if fleet else _mission_result(flight.vehicles[0])


def _mission_result(flight: VehicleFlight) -> str:
    summary = flight.summary
    if not summary.ok:
        raise GcsScriptError(f"mission failed: {summary.reason or 'not complete'}")
    flown = ""
    if summary.sim_time_s is not None and flight.start_sim_s is not None:  # from this flight's start, not the sim's
        flown = f", {summary.sim_time_s - flight.start_sim_s:.1f} s sim time in {summary.wall_time_s:.1f} s wall"
    bypassed = f", {summary.items_bypassed} bypassed" if summary.items_bypassed else ""
    return f"mission complete: {summary.items_reached}/{summary.items_total} items{bypassed}{flown}"


def _fleet_result(flight: FleetFlight) -> str:
    rows = flight.vehicles
    failed = [f"{v.name}: {v.summary.reason or 'not complete'}" for v in rows if not v.summary.ok]
    if failed:
        raise GcsScriptError(f"{len(failed)} of {len(rows)} vehicles failed: " + "; ".join(failed))
    sep = flight.min_separation_seen_m
    sep_text = f", closest approach seen {round(sep, 2)} m (centres)" if sep is not None else ""
    return f"fleet complete: {len(rows)} vehicles, every mission done{sep_text}"
