"""Traffic avoidance, the one entry point: :meth:`TrafficAvoidance.update` each navigator step (SPEC §13).

Per step: new reports into the :class:`TrackTable` (bad ones refused with a reason, stale tracks dropped), the
closest approach of every track over NAV_TRAFF_COLL_T (:func:`predict_approach`), advisories (the alert volume,
NAV_TRAFF_A_HOR/A_VER) and conflicts (the class's separation volume), then NAV_TRAFF_AVOID: warn; return, land or
hold as a failsafe event for the commander (once per new conflict, as PX4); or avoid: the give-way vehicle flies
the :class:`Resolution` the :class:`Resolver` picks by the rules of :mod:`autopilot.traffic.rules`, re-checked at
every new report and replanned when it no longer keeps separation, then rejoins the route. Every conflict, its
end and every action is a status text (and so a recording event). Pure: no clock, no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np

from autopilot.safety.failsafe import FailsafeAction, FailsafeEvent, FailsafeKind
from autopilot.traffic.cpa import Approach, predict_approach
from autopilot.traffic.param_decls import SeparationVolume, TrafficAction, TrafficParams
from autopilot.traffic.resolution import (
    AvoidLimits,
    Maneuver,
    OwnShip,
    Resolution,
    Resolver,
    Threat,
    predicted_min_ratio,
)
from autopilot.traffic.rules import (
    COLUMN_SPEED_M_S,
    LAST_RESORT_S,
    Role,
    climbs,
    lateral_sense,
    owns_column,
    parked,
    reciprocates,
    role,
)
from autopilot.traffic.tracks import TrackKey, TrackTable, TrafficTrack
from mavlink_bridge.contract.frames import GeoPoint, Vec3
from mavlink_bridge.contract.traffic import TrafficSource
from mavlink_bridge.contract.vehicle_api import Severity, StatusText

#: NAV_TRAFF_AVOID -> the commander's failsafe action (PX4 maps 2/3/4 to RTL/land/hold the same way).
_FAILSAFE = {TrafficAction.RETURN: FailsafeAction.RTL, TrafficAction.LAND: FailsafeAction.LAND,
             TrafficAction.HOLD: FailsafeAction.HOLD}  # fmt: skip
#: Shortest interval between two replans of a detour that stopped keeping separation (µs).
REPLAN_US = 500_000
#: The same detour (track, role, manoeuvre) planned again is said again only after this long (µs): replanned at
#: every report in a crowd, it was said 30 times in 5 s (encounter case 682).
RESAY_US = 10_000_000
#: Offsets are sized this much beyond the planning volume they are checked against (tracking slack).
OFFSET_SLACK = 1.15
#: How far the conflict window of the most urgent conflict is followed past the horizon (s).
WINDOW_LOOKAHEAD_S = 600.0
#: A descent from manned traffic stops this far above the altitude floor (the detour's curve may overshoot) (m).
FLOOR_SLACK_M = 0.5
#: At most this many fits to cut a descent from manned traffic at the altitude floor.
FLOOR_FITS = 4
#: A refused-report reason is said at most once per this interval (µs).
REJECT_TEXT_US = 10_000_000


@dataclass(frozen=True, slots=True)
class Conflict:
    """A track predicted to come inside its separation volume within the horizon."""

    track: TrafficTrack
    approach: Approach  # against the detection volume (separation grown by half NAV_TRAFF_MARGIN)
    role: Role
    volume: SeparationVolume  # the class's separation volume

    def text(self) -> str:
        a, v = self.approach, self.volume
        return (f"{self.track.name} in {a.loss_in_s:.0f} s, CPA {a.hor_cpa_m:.0f} m/{abs(a.ver_cpa_m):.0f} m "
                f"(keep {v.hor_m:g}/{v.ver_m:g} m)")  # fmt: skip


@dataclass(frozen=True, slots=True)
class TrafficDecision:
    """What traffic avoidance decided at ``t_us``: tracks, conflicts, the detour flown (about home) or the
    failsafe to apply, texts for the GCS and the recording, refused reports."""

    t_us: int
    action: TrafficAction
    tracks: tuple[TrafficTrack, ...] = ()
    conflicts: tuple[Conflict, ...] = ()
    resolution: Resolution | None = None
    failsafe: FailsafeEvent | None = None
    texts: tuple[StatusText, ...] = ()
    rejected: tuple[str, ...] = ()

    def setpoint(self, t_us: int) -> tuple[Vec3, Vec3, Vec3] | None:
        """The detour's (pos, vel, acc) about home at ``t_us``; None when no detour is flown."""
        return self.resolution.setpoint(t_us) if self.resolution is not None else None


def volume_for(params: TrafficParams, track: TrafficTrack) -> SeparationVolume:
    return params.manned if track.source is TrafficSource.MANNED else params.uav


class TrafficAvoidance:
    """Tracks, conflicts and the avoidance action of one vehicle (system id ``system_id``)."""

    def __init__(self, params: TrafficParams, system_id: int = 1) -> None:
        self.params = params
        self.system_id = system_id
        self.table = TrackTable(system_id)
        self.resolution: Resolution | None = None
        self._conflicts: dict[TrackKey, Conflict] = {}
        self._advised: set[TrackKey] = set()
        self._said_reject: dict[str, int] = {}
        self._last_plan_us = -REPLAN_US
        self._last_report_us: dict[TrackKey, int] = {}
        self._said_plan: tuple[tuple[str, str, str], int] = (("", "", ""), -RESAY_US)  # (what, when) last said
        self.decision = TrafficDecision(0, params.action)

    def set_params(self, params: TrafficParams) -> None:
        self.params = params
        if params.action is not TrafficAction.AVOID:
            self.resolution = None

    def set_home(self, home: GeoPoint) -> None:
        self.table.set_home(home)

    @property
    def busy(self) -> bool:
        """Tracks are held or a detour is flown (else a step without reports changes nothing)."""
        return bool(self.table.tracks) or self.resolution is not None or bool(self._conflicts)

    # ------------------------------------------------------------------ the step
    def update(self, own: OwnShip, reports: Iterable[object], limits: AvoidLimits, can_avoid: bool = True,
               airborne: bool = True, quiet: bool = False) -> TrafficDecision:  # fmt: skip
        """One step at ``own.t_us``: ``can_avoid`` says the vehicle may fly a detour now (AUTO_MISSION, a position
        target), ``airborne`` that actions apply (nothing is resolved on the ground); ``quiet``: the reactive layer
        flies now (a detour is dropped without a text, and planned again once it has finished)."""
        p, t_us = self.params, own.t_us
        texts: list[StatusText] = []
        rejected, dropped = self.table.update(t_us, reports, p.max_age_s)
        for reason in rejected:
            if t_us - self._said_reject.get(reason, -REJECT_TEXT_US) >= REJECT_TEXT_US:
                self._said_reject[reason] = t_us
                texts.append(StatusText(Severity.WARNING, f"Traffic report refused: {reason}"))
        for track in dropped:
            if track.key in self._conflicts:
                texts.append(StatusText(Severity.NOTICE, f"Traffic {track.name}: track lost (no report)"))
        tracks = self.table.tracks
        if p.action is TrafficAction.OFF:
            self._conflicts.clear()
            self.resolution = None
            self.decision = TrafficDecision(t_us, p.action, tracks, texts=tuple(texts), rejected=tuple(rejected))
            return self.decision
        conflicts = self._detect(own, tracks, texts) if airborne else []  # on the ground: tracks only
        failsafe = None
        new = [c for c in conflicts if c.track.key not in self._conflicts]
        for c in new:
            texts.append(StatusText(Severity.WARNING, f"Traffic conflict: {c.text()}, {c.role.value}"))
        for key, old in self._conflicts.items():
            if key not in {c.track.key for c in conflicts} and key in {t.key for t in tracks}:
                texts.append(StatusText(Severity.INFO, f"Traffic {old.track.name}: conflict resolved"))
        self._conflicts = {c.track.key: c for c in conflicts}
        if p.action in _FAILSAFE and new and airborne:
            failsafe = FailsafeEvent(FailsafeKind.TRAFFIC, _FAILSAFE[p.action], f"Traffic conflict: {new[0].text()}")
        elif p.action is TrafficAction.AVOID:
            if can_avoid and airborne:
                self._avoid(own, tracks, conflicts, limits, texts)
            else:
                if self.resolution is not None and not quiet:
                    texts.append(StatusText(Severity.NOTICE, "Traffic detour ended: not in a mission"))
                self.resolution = None
                if new and airborne and not quiet:
                    texts.append(StatusText(Severity.WARNING, "Traffic: not in a mission, warning only"))
        self.decision = TrafficDecision(t_us, p.action, tracks, tuple(conflicts), self.resolution, failsafe,
                                        tuple(texts), tuple(rejected))  # fmt: skip
        return self.decision

    def _detect(self, own: OwnShip, tracks: tuple[TrafficTrack, ...], texts: list[StatusText]) -> list[Conflict]:
        p = self.params
        out: list[Conflict] = []
        advised: set[TrackKey] = set()
        for track in tracks:
            if parked(track, own.t_us):
                continue
            rel, rel_vel = _relative(own, track)
            volume = volume_for(p, track)
            # hysteresis: a conflict starts inside the volume grown by half the margin, ends outside the whole margin
            grow = p.margin if track.key in self._conflicts else 0.5 * p.margin
            approach = predict_approach(rel, rel_vel, p.horizon_s, volume.grown(grow), owns_column(track))
            if approach.conflict:
                out.append(Conflict(track, approach, role(self.system_id, track, own.vel_ned_m_s, rel), volume))
                advised.add(track.key)
                continue
            alert = predict_approach(rel, rel_vel, p.horizon_s, p.alert)
            if alert.conflict:
                advised.add(track.key)
                if track.key not in self._advised:
                    text = f"Traffic advisory: {track.name}, CPA {alert.hor_cpa_m:.0f} m in {alert.t_cpa_s:.0f} s"
                    texts.append(StatusText(Severity.INFO, text))
        self._advised = advised
        return out

    # ------------------------------------------------------------------ avoid
    def _threats(self, tracks: tuple[TrafficTrack, ...], grow: float) -> list[Threat]:
        return [Threat(t, volume_for(self.params, t).grown(grow), owns_column(t)) for t in tracks]

    def _avoid(self, own: OwnShip, tracks: tuple[TrafficTrack, ...], conflicts: list[Conflict], limits: AvoidLimits,
               texts: list[StatusText]) -> None:  # fmt: skip
        p, t_us = self.params, own.t_us
        active = self.resolution
        resolver = Resolver(own, limits, p.horizon_s)
        keep = self._threats(tracks, 0.5 * p.margin)  # hysteresis: plan for the margin, keep while half is left
        if active is not None:
            elapsed_s = (t_us - active.start_us) * 1e-6
            finished = active.path is None or elapsed_s > active.path.duration_s
            if finished and (not active.hold_at_end or resolver.choose([(Maneuver.ROUTE, 0.0, (0.0, 0.0, 0.0))],
                                                                       (0.0, 0.0), keep, ()).safe):  # fmt: skip
                texts.append(StatusText(Severity.INFO, "Traffic: clear of conflict, back on the route"))
                self.resolution = active = None
            elif finished and own.route_home_ned_m and self._reported_since_plan(tracks):
                # held, and the route is blocked by a UAV that stays on it (hovering there, or flying along it):
                # plan a way on as if flying the route (traffic crossing the route passes: waiting for it is right)
                flying = replace(own, vel_ned_m_s=_route_velocity(own))
                staying = [t for t in tracks if _stays_on_route(t, flying.vel_ned_m_s)]
                blocking = [c for c in (self._conflict(flying, t) for t in staying) if c is not None]
                if blocking:
                    own, conflicts = flying, blocking
                    self.resolution = active = None
        # a quadsitl vehicle flying on is the reactive layer's (ORCA shares every such pair); the strategic detour
        # re-routes around traffic that will not move aside: manned aircraft, a UAV hovering, landing or taking off
        acting = [c for c in conflicts if (c.role is Role.GIVE_WAY or c.approach.loss_in_s <= LAST_RESORT_S)
                  and not reciprocates(c.track)]  # fmt: skip
        if not acting:
            return
        if active is not None:
            if t_us - self._last_plan_us < REPLAN_US or not self._reported_since_plan(tracks):
                return
            if _remaining_ratio(active, resolver, keep) >= 1.0:
                self._last_plan_us = t_us
                return
        self._last_plan_us = t_us
        self._last_report_us = {t.key: t.t_us for t in tracks}
        primary = min(acting, key=lambda c: c.approach.loss_in_s)
        res = self._resolve(own, resolver, primary, tracks)
        if res.maneuver is Maneuver.ROUTE:
            self.resolution = None
            return
        self.resolution = res
        verb = primary.role.value if primary.role is Role.GIVE_WAY else "last resort"
        severity = Severity.NOTICE if res.safe else Severity.WARNING
        kept = "" if res.safe else f" (keeps only {res.min_ratio:.0%} of the planned separation)"
        refused = f" ({'; '.join(res.refused)})" if res.refused else ""
        plan = (primary.track.name, verb, res.describe())
        if plan != self._said_plan[0] or t_us - self._said_plan[1] >= RESAY_US:
            self._said_plan = (plan, t_us)
            texts.append(StatusText(severity, f"Traffic: {verb} to {plan[0]}: {plan[2]}{kept}{refused}"))

    def _conflict(self, own: OwnShip, track: TrafficTrack) -> Conflict | None:
        """``track`` as a conflict of ``own`` flying straight on (the detection volume), or None."""
        if parked(track, own.t_us):
            return None
        rel, rel_vel = _relative(own, track)
        volume = volume_for(self.params, track)
        approach = predict_approach(rel, rel_vel, self.params.horizon_s, volume.grown(0.5 * self.params.margin),
                                    owns_column(track))  # fmt: skip
        if not approach.conflict:
            return None
        return Conflict(track, approach, role(self.system_id, track, own.vel_ned_m_s, rel), volume)

    def _reported_since_plan(self, tracks: tuple[TrafficTrack, ...]) -> bool:
        return any(self._last_report_us.get(t.key) != t.t_us for t in tracks)

    def _resolve(
        self, own: OwnShip, resolver: Resolver, primary: Conflict, tracks: tuple[TrafficTrack, ...]
    ) -> Resolution:
        """Candidates in the rules' order for the most urgent conflict, checked against every track."""
        p = self.params
        track = primary.track
        plan_volume = volume_for(p, track).grown(p.margin)
        rel, rel_vel = _relative(own, track)
        column = owns_column(track)
        approach = predict_approach(rel, rel_vel, p.horizon_s, plan_volume, column)
        if not approach.conflict:
            approach = primary.approach
        # the whole window, past the horizon (a window the horizon cuts would rejoin the route inside it)
        whole = predict_approach(rel, rel_vel, WINDOW_LOOKAHEAD_S, plan_volume, column)
        if whole.conflict:
            approach = replace(approach, loss_out_s=min(whole.loss_out_s, 2.0 * p.horizon_s))
        t = approach.t_cpa_s
        miss = (rel[0] + rel_vel[0] * t, rel[1] + rel_vel[1] * t)
        n = lateral_sense(miss, rel, rel_vel, self.system_id, track.target_id)
        along = miss[0] * n[0] + miss[1] * n[1]
        hor_m, ver_m = plan_volume.hor_m * OFFSET_SLACK, plan_volume.ver_m * OFFSET_SLACK
        near, far = max(hor_m + along, 1.0), max(hor_m - along, 1.0)  # the preferred side, then across
        ver = rel[2] + rel_vel[2] * t  # other below own > 0 (NED down)
        up, down = max(ver_m - ver, 1.0), max(ver_m + ver, 1.0)
        manned = track.source is TrafficSource.MANNED
        window = (approach.loss_in_s, approach.loss_out_s)
        if manned:  # low under an aircraft: the floor may still clear its half-height (the candidates' check says)
            down = _down_to_floor(resolver, down, window)
        first_up = climbs(self.system_id, track, ver, up, down)
        v1 = (Maneuver.CLIMB, up, (0.0, 0.0, -up)) if first_up else (Maneuver.DESCEND, down, (0.0, 0.0, down))
        v2 = (Maneuver.DESCEND, down, (0.0, 0.0, down)) if first_up else (Maneuver.CLIMB, up, (0.0, 0.0, -up))
        right_first = _is_right_of(own.vel_ned_m_s, rel, n)
        side1 = (Maneuver.RIGHT if right_first else Maneuver.LEFT, near, (n[0] * near, n[1] * near, 0.0))
        side2 = (Maneuver.LEFT if right_first else Maneuver.RIGHT, far, (-n[0] * far, -n[1] * far, 0.0))
        route = (Maneuver.ROUTE, 0.0, (0.0, 0.0, 0.0))
        stop = (Maneuver.STOP, 0.0, (0.0, 0.0, 0.0))
        plans = [route, v1, stop, side1, v2, side2] if manned else [route, side1, v1, stop, side2, v2]
        threats = self._threats(tracks, p.margin)
        must = [th for th in threats if role(self.system_id, th.track, own.vel_ned_m_s, _relative(own, th.track)[0])
                is Role.GIVE_WAY]  # fmt: skip
        return resolver.choose(plans, window, threats, must)


def _down_to_floor(resolver: Resolver, down_m: float, window: tuple[float, float]) -> float:
    """The descent ``down_m`` (m), cut so that the detour's curve stays above the altitude floor (CA_MIN_AGL_M).

    The NMAC half-height (30 m) is more than a delivery drone's cruise height: sized for the grown volume, a descent
    from an aircraft flying 35-45 m up reaches under the floor and was refused, although the floor itself clears the
    half-height. The curve through the offset points sags below them over a long window, so the cut is iterated
    on the fitted curve's lowest point (a few fits, only in a manned conflict)."""
    floor_m = resolver.limits.down_max_m
    start_m = resolver.own.pos_home_ned_m[2]
    down = min(down_m, floor_m - start_m - FLOOR_SLACK_M)
    for _ in range(FLOOR_FITS):
        if down < 1.0:  # no room above the floor: the candidate as sized (the floor check refuses it)
            return down_m
        path, _ = resolver.offset(Maneuver.DESCEND, (0.0, 0.0, down), window)
        below_m = float(path.sample(1.0)[:, 2].max()) - (floor_m - FLOOR_SLACK_M)
        if below_m <= 0.0:
            return down
        down -= below_m
    return down_m if down < 1.0 else down


def _route_velocity(own: OwnShip) -> Vec3:
    """The velocity of flying the route at cruise speed from where the vehicle is (zero without a route)."""
    to = own.route_home_ned_m[0] if own.route_home_ned_m else own.pos_home_ned_m
    d = (to[0] - own.pos_home_ned_m[0], to[1] - own.pos_home_ned_m[1], to[2] - own.pos_home_ned_m[2])
    n = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    return (
        (0.0, 0.0, 0.0)
        if n < 1e-6
        else (d[0] / n * own.cruise_m_s, d[1] / n * own.cruise_m_s, d[2] / n * own.cruise_m_s)
    )


def _stays_on_route(track: TrafficTrack, route_vel_ned_m_s: Vec3) -> bool:
    """A UAV whose velocity across the route is below COLUMN_SPEED_M_S (hovering on it, or flying along it)."""
    n, e = route_vel_ned_m_s[0], route_vel_ned_m_s[1]
    speed = math.hypot(n, e)
    if track.source is not TrafficSource.UAV or speed < 1e-6:
        return False
    return abs(track.vel_ned_m_s[0] * e - track.vel_ned_m_s[1] * n) / speed < COLUMN_SPEED_M_S


def _is_right_of(own_vel_ned_m_s: Vec3, rel_pos_ned_m: Vec3, direction_ne: tuple[float, float]) -> bool:
    """Whether ``direction_ne`` points right of the vehicle's course (or, hovering, of the line to the other)."""
    fn, fe = own_vel_ned_m_s[0], own_vel_ned_m_s[1]
    if math.hypot(fn, fe) < 0.5:
        fn, fe = rel_pos_ned_m[0], rel_pos_ned_m[1]
    return fn * direction_ne[1] - fe * direction_ne[0] >= 0.0


def _relative(own: OwnShip, track: TrafficTrack) -> tuple[Vec3, Vec3]:
    """The track about the vehicle now, where its intent puts it (:meth:`TrafficTrack.predict`): (position,
    velocity), NED."""
    tp, tv = track.predict(own.t_us)
    op, ov = own.pos_home_ned_m, own.vel_ned_m_s
    return (tp[0] - op[0], tp[1] - op[1], tp[2] - op[2]), (tv[0] - ov[0], tv[1] - ov[1], tv[2] - ov[2])


def _remaining_ratio(active: Resolution, resolver: Resolver, threats: list[Threat]) -> float:
    """The active detour's predicted separation ratio from now on (straight tracks, as at planning; past the
    path's end the vehicle goes on with the end velocity, or holds the end point)."""
    path = active.path
    if path is None:
        return math.inf
    own = resolver.own
    offset_s = (own.t_us - active.start_us) * 1e-6
    end_pos, end_vel, _ = path.state_tuple(path.duration_s)
    samples = np.empty((len(resolver.times), 3))
    for k, t in enumerate(resolver.times):
        ts = offset_s + float(t)
        if ts <= path.duration_s:
            samples[k] = path.state_tuple(ts)[0]
        else:
            late = 0.0 if active.hold_at_end else ts - path.duration_s
            samples[k] = (
                end_pos[0] + end_vel[0] * late,
                end_pos[1] + end_vel[1] * late,
                end_pos[2] + end_vel[2] * late,
            )
    return predicted_min_ratio(samples, resolver.times, own.t_us, threats, active.hold_at_end)
