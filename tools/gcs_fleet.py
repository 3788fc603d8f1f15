"""``python -m tools.gcs fly FLEET.yaml``: the ground station flies every vehicle of a fleet world (SPEC §13).

Over the one GCS port every vehicle sends to (PX4: 14550+N), vehicle i of the world's ``vehicles:`` is system id
i+1. The ground station waits to hear every vehicle, uploads each its own fence and mission (the ``vehicles:``
entry's, about the world's home), then arms and starts them, vehicle 0 first and each next one ``--stagger-s``
seconds of sim time later (0: all together), shows one progress bar per vehicle and waits until each has landed
and disarmed. A vehicle whose telemetry stops (its autopilot died) fails, and so does one whose flight makes no
progress (no item reached, no change of landed state or arming) for ``--stall-s`` of sim time (default 120: a
crashed vehicle, which the simulator freezes); the others fly on.

The summary (``--summary PATH``) holds one :class:`tools.gcs.FlySummary` per vehicle and the closest approach of
two vehicles' centres the ground station saw in their GLOBAL_POSITION_INT (estimated positions; the simulator's
``sim_summary.json`` has the true surface-to-surface figure). Exit code 0 only when every vehicle succeeded.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from autopilot.mission.files import MissionFileError, load_fleet_missions
from autopilot.mission.plan import MissionPlan
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.status_texts import is_bypassed
from mavlink_bridge.contract.vehicle_api import FlightMode, LandedState
from mavlink_bridge.gcs_client.client import CommandFailedError, GcsClient, GcsError, VehicleStatus
from mavlink_bridge.gcs_client.fleet_link import FleetLink
from tools.gcs import (
    FlySummary,
    GcsScriptError,
    arm_when_ready,
    failsafe_reason,
    mission_done,
    say,
    upload_when_ready,
)
from tools.gcs_progress import MissionBars, flight_state_text, sim_time_text

#: Wall seconds without any message from a flying vehicle before the ground station gives it up.
LOST_AFTER_S = 10.0
_SETUP_TIMEOUT_S = 60.0


@dataclass(slots=True)
class _Vehicle:
    """One vehicle's flight as the ground station follows it."""

    sys_id: int
    plan: MissionPlan
    client: GcsClient
    start_at_sim_s: float | None = None  # when to arm and start (sim time), None: not yet scheduled
    started: bool = False
    seen_armed: bool = False
    text_serial: int = 0
    reason: str = ""
    done: bool = False
    t_done: float = 0.0
    status: VehicleStatus | None = None
    progress: tuple[int, int, bool] = (-1, -1, False)  # (items reached, landed state, armed) last seen changing
    progress_at_sim_s: float | None = None
    geo: tuple[float, float, float] | None = None  # latest reported lat_deg, lon_deg, alt AMSL (m)


def fleet_plans(path: str) -> list[MissionPlan]:
    """The per-vehicle plans of a fleet world (``[]``: not a fleet world)."""
    return load_fleet_missions(path)


def fly_fleet(url: str, plans: list[MissionPlan], args: argparse.Namespace) -> tuple[dict[str, object], bool]:
    """Fly every plan (plan i on system id i+1) over the one GCS socket at ``url``; (summary, all succeeded)."""
    t0 = time.monotonic()
    with FleetLink(url) as link:
        _wait_for_fleet(link, len(plans), args.wait_s)
        vehicles = [
            _Vehicle(i + 1, plan, link.client(i + 1, timeout_s=args.timeout_step_s)) for i, plan in enumerate(plans)
        ]
        for v in vehicles:
            v.text_serial = v.client.statustext_serial
            say(f"{v.plan.name} (system {v.sys_id}): fence and mission")
            try:
                upload_when_ready(v.client, v.plan, min(_SETUP_TIMEOUT_S, args.timeout_s))
                v.client.forget_reached_items()
            except (GcsError, GcsScriptError) as exc:
                v.reason, v.done = f"upload failed: {exc}", True
        sep_m = _follow(vehicles, link, args, t0)
        summaries = [_summary(v, t0) for v in vehicles]
    ok = all(s.ok for s in summaries)
    summary: dict[str, object] = {
        "ok": ok,
        "vehicles": [
            {"name": v.plan.name, "sys_id": v.sys_id, **asdict(s)} for v, s in zip(vehicles, summaries, strict=True)
        ],
        "stagger_s": args.stagger_s,
        "min_separation_seen_m": None if sep_m is None else round(sep_m, 2),
        "wall_time_s": round(time.monotonic() - t0, 3),
    }
    return summary, ok


def _wait_for_fleet(link: FleetLink, count: int, wait_s: float) -> None:
    wanted = set(range(1, count + 1))
    deadline = time.monotonic() + wait_s
    said = False
    while not wanted <= set(link.systems_heard):
        if time.monotonic() >= deadline:
            missing = sorted(wanted - set(link.systems_heard))
            raise GcsScriptError(
                f"no vehicle with system id {missing} heard on {link.link.url} within {wait_s:g} s; fix: start the "
                "fleet (quadsitl up --world FILE) with the same --instance"
            )
        if not said and time.monotonic() > deadline - wait_s + 1.0:
            say(f"waiting for {count} vehicles (system ids 1..{count}) on {link.link.url}")
            said = True
        link.poll(0.1)


def _follow(vehicles: list[_Vehicle], link: FleetLink, args: argparse.Namespace, t0: float) -> float | None:
    """Arm and start each vehicle at its turn, and follow every one until it is done (one progress bar each); the
    closest approach of two vehicles' centres seen (None: never two known at once)."""
    deadline = t0 + args.timeout_s
    min_sep_m = math.inf
    first_start_s: float | None = None
    rows = [(v.plan.name, len(v.plan.items)) for v in vehicles]
    with MissionBars("[bold]{task.description:<10}", rows, enabled=not args.no_progress) as bars:
        while not all(v.done for v in vehicles):
            for i, v in enumerate(vehicles):
                if v.done:
                    continue
                v.client.pump(0.01)
                status = v.status = v.client.telemetry()
                if not v.started:
                    now_s = status.sim_time_s
                    if first_start_s is None and now_s is not None:
                        first_start_s = now_s
                    if first_start_s is not None and now_s is not None and now_s >= first_start_s + i * args.stagger_s:
                        _start(v, args)
                else:
                    _judge(v, link, args.stall_s)
                if status.lat_deg is not None and status.home is not None and status.alt_rel_m is not None:
                    v.geo = (status.lat_deg, status.lon_deg or 0.0, status.home.alt_amsl_m + status.alt_rel_m)
                _show(bars, i, v)
            min_sep_m = min(min_sep_m, _separation_now_m(vehicles))
            if time.monotonic() >= deadline:
                for v in vehicles:
                    if not v.done:
                        v.reason, v.done = f"not landed and disarmed after {args.timeout_s:g} s", True
    return min_sep_m if math.isfinite(min_sep_m) else None


def _start(v: _Vehicle, args: argparse.Namespace) -> None:
    v.started = True
    try:
        arm_when_ready(v.client, min(_SETUP_TIMEOUT_S, args.timeout_s))
        try:
            v.client.start_mission()
        except CommandFailedError:
            v.client.set_mode(FlightMode.AUTO_MISSION)
        say(f"{v.plan.name}: mission started")
    except (GcsError, GcsScriptError) as exc:
        v.reason, v.done = f"start failed: {exc}", True


def _judge(v: _Vehicle, link: FleetLink, stall_s: float) -> None:
    """Done when landed and disarmed (mission complete or not), when the vehicle went silent, or when its flight
    made no progress (item reached, landed state, arming) for ``stall_s`` of sim time (e.g. it crashed into
    another: the simulator freezes a crashed vehicle and keeps serving its autopilot)."""
    status = v.client.telemetry()
    progress = (len(status.items_reached), int(status.landed_state), status.armed)
    if progress != v.progress or v.progress_at_sim_s is None:
        v.progress, v.progress_at_sim_s = progress, status.sim_time_s
    v.seen_armed = v.seen_armed or status.armed
    total = len(v.plan.items)
    landed_disarmed = not status.armed and status.landed_state is LandedState.ON_GROUND
    if landed_disarmed and mission_done(status, total):
        v.done = True
    elif landed_disarmed and v.seen_armed:
        v.client.pump(0.5)  # late MISSION_ITEM_REACHED / MISSION_CURRENT
        if not mission_done(v.client.telemetry(), total):
            v.reason = "the vehicle landed and disarmed before the mission was complete"
        v.done = True
    elif time.monotonic() - link.last_heard_s.get(v.sys_id, -math.inf) > LOST_AFTER_S:
        v.reason, v.done = f"no telemetry from the vehicle for {LOST_AFTER_S:g} s (its autopilot is gone?)", True
    elif status.sim_time_s is not None and status.sim_time_s - (v.progress_at_sim_s or 0.0) > stall_s:
        v.reason, v.done = f"no mission progress for {stall_s:g} s of sim time (crashed or stuck?)", True
    if v.done:
        v.t_done = time.monotonic()


def _summary(v: _Vehicle, t0: float) -> FlySummary:
    status = v.client.telemetry()
    texts = v.client.statustexts_since(v.text_serial)
    reason = v.reason
    errors = [t.text for t in texts if t.severity <= 3]
    if reason and errors:
        reason += f" (last error: {errors[-1]})"
    reason = reason or failsafe_reason(texts)
    total = len(v.plan.items)
    landed = status.landed_state is LandedState.ON_GROUND
    return FlySummary(
        ok=not reason and landed and not status.armed and mission_done(status, total),
        items_total=total,
        items_reached=len(status.items_reached),
        sim_time_s=status.sim_time_s,
        wall_time_s=round((v.t_done or time.monotonic()) - t0, 3),
        landed=landed,
        disarmed=not status.armed,
        reason=reason,
        items_bypassed=sum(is_bypassed(t.text) for t in texts),
    )


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
    """Vehicle ``index``'s bar: items reached, then waiting / mode and arming / done / FAILED, and sim time."""
    if v.status is None:
        return
    state = flight_state_text(v.status) if v.started else "waiting to start"
    if v.done:
        state = "FAILED: " + v.reason[:40] if v.reason else "done"
    bars.show(index, len(v.status.items_reached), f"{state} t={sim_time_text(v.status)}")


def cmd_fly_fleet(url: str, plans: list[MissionPlan], args: argparse.Namespace) -> str:
    """``fly`` with a fleet world: the one-line result; GcsScriptError when any vehicle failed."""
    summary, _ = fly_fleet(url, plans, args)
    if args.summary:
        Path(args.summary).parent.mkdir(parents=True, exist_ok=True)
        Path(args.summary).write_text(json.dumps(summary, indent=2) + "\n")
    rows = summary["vehicles"]
    assert isinstance(rows, list)
    failed = [f"{r['name']}: {r['reason'] or 'not complete'}" for r in rows if not r["ok"]]
    if failed:
        raise GcsScriptError(f"{len(failed)} of {len(rows)} vehicles failed: " + "; ".join(failed))
    sep = summary["min_separation_seen_m"]
    sep_text = f", closest approach seen {sep} m (centres)" if sep is not None else ""
    return f"fleet complete: {len(rows)} vehicles, every mission done{sep_text}"


__all__ = ["MissionFileError", "cmd_fly_fleet", "fleet_plans", "fly_fleet"]
