"""The track table: received traffic reports, checked, about home, aged out and extrapolated (SPEC §13).

One track per ``(source, target_id)``: the newest report wins, an older or duplicate one is ignored. Positions are
converted once per report to NED about home with the one geodetic conversion (:class:`LocalNedFrame`) and
extrapolated with the reported velocity (constant velocity: the receiver reports at 1 Hz). A report that is not
a finite, plausible position and velocity is rejected with a one-line reason and changes nothing.

A UTM report may carry the sender's intent (its next waypoint, converted about home too): :meth:`TrafficTrack.predict`
flies it from the reported position toward that waypoint at the reported speed and holds it there, so a climb,
descent or turn toward the waypoint is predicted before it shows in the velocity; without intent it is
:meth:`TrafficTrack.position_at`'s constant velocity.

A vehicle this one also sees (its obstacle sensor's detection associated with the track,
:mod:`autopilot.traffic.sensor_fusion`) gets *fixes*: :meth:`TrackTable.observe` runs an alpha-beta filter over them
(position and velocity about home), and while its fixes are newer than the track's report and keep coming, the
track flies on the filter's position, velocity, time and accuracy instead of the report's (a UTM report is a second
old when it arrives; the camera's frame is not). The report still says who it is, its intent and its flight state.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace

from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame, Vec3
from mavlink_bridge.contract.traffic import TrafficReport, TrafficSource, UtmFlightState

#: Plausibility bounds of a report (anything outside is garbage, not traffic).
MAX_SPEED_H_M_S = 350.0
MAX_SPEED_V_M_S = 100.0
ALT_RANGE_M = (-1000.0, 30000.0)
#: Below this reported speed (m/s) intent is not flown: a vehicle standing still says nothing of how fast it will go.
MIN_INTENT_SPEED_M_S = 0.1
#: A next waypoint further than this from the reported position (m) is not believed (garbage, not intent).
MAX_INTENT_DISTANCE_M = 50_000.0
#: A report stamped this far after the autopilot's clock is rejected (the simulator owns time).
MAX_FUTURE_US = 1_000_000

TrackKey = tuple[TrafficSource, int]

#: Fixes: the alpha-beta filter's gains at the camera's 10 Hz (alpha: position, beta: velocity; Kalata's
#: tracking index about 0.5, a steady filter for a vehicle manoeuvring at a few m/s^2).
FIX_ALPHA = 0.5
FIX_BETA = 0.15
#: A fix this long after the previous one (µs) starts the filter again from the track's own prediction.
FIX_RESTART_US = 500_000
#: Fixes stop moving the track this long after the last one (µs): the reports take over again.
FIX_HOLD_US = 1_000_000


@dataclass(frozen=True, slots=True)
class TrafficTrack:
    """One target: its last report, its position about home at that time, its velocity (NED) and, from a UTM report,
    its intent and accuracy: ``next_pos_home_ned_m`` (its next waypoint about home, None: none announced),
    ``flight_state``, ``h_acc_m``/``v_acc_m`` (1-sigma, NaN: unknown, as every ADS-B report).
    ``reported_vel_ned_m_s``: on a track flown on its camera fixes, the velocity its own report gave (None: the
    track is the report); see :attr:`steady_vel_ned_m_s`."""

    source: TrafficSource
    target_id: int
    callsign: str
    pos_home_ned_m: Vec3  # at t_us
    vel_ned_m_s: Vec3
    t_us: int
    next_pos_home_ned_m: Vec3 | None = None
    flight_state: UtmFlightState = UtmFlightState.UNKNOWN
    h_acc_m: float = math.nan
    v_acc_m: float = math.nan
    reported_vel_ned_m_s: Vec3 | None = None

    @property
    def steady_vel_ned_m_s(self) -> Vec3:
        """The velocity that says what the target is doing: its report's (its own estimator's, a second or two
        old), not the fixes' (differentiated at the camera's 10 Hz, it swings by a metre a second about a UAV
        standing on its pad 24 m off: encounter case 625). The rules' classifications (on the ground, owning its
        column, head-on) and the column checks' predictions over tens of seconds read it; the reactive layer's
        velocity obstacles, over seconds, read :attr:`vel_ned_m_s`."""
        return self.vel_ned_m_s if self.reported_vel_ned_m_s is None else self.reported_vel_ned_m_s

    @property
    def key(self) -> TrackKey:
        return (self.source, self.target_id)

    @property
    def name(self) -> str:
        """How texts name it: the callsign, else the class and id."""
        if self.callsign.strip():
            return self.callsign.strip()
        return f"UAV {self.target_id}" if self.source is TrafficSource.UAV else f"ICAO {self.target_id:06X}"

    def position_at(self, t_us: int) -> Vec3:
        """Position about home at ``t_us``, extrapolated along the reported velocity."""
        dt = (t_us - self.t_us) * 1e-6
        p, v = self.pos_home_ned_m, self.vel_ned_m_s
        return (p[0] + v[0] * dt, p[1] + v[1] * dt, p[2] + v[2] * dt)

    def predict(self, t_us: int) -> tuple[Vec3, Vec3]:
        """(position about home, velocity NED) at ``t_us`` using the intent: from the reported position straight
        toward the next waypoint at the reported speed (3D), then holding at the waypoint (velocity 0). Without a
        next waypoint, below ``MIN_INTENT_SPEED_M_S``, or for a time before the report: constant velocity
        (:meth:`position_at`). The strategic layer's minute-long predictions use it; the reactive layer flies on
        the reports themselves (over its seconds the velocity says more, and a vehicle avoiding is off its route)."""
        p, v, w = self.pos_home_ned_m, self.vel_ned_m_s, self.next_pos_home_ned_m
        dt = (t_us - self.t_us) * 1e-6
        speed = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        if w is None or dt < 0.0 or speed < MIN_INTENT_SPEED_M_S:
            return self.position_at(t_us), v
        d = (w[0] - p[0], w[1] - p[1], w[2] - p[2])
        dist = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        if dist <= speed * dt:
            return w, (0.0, 0.0, 0.0)
        k = speed / dist
        u = (d[0] * k, d[1] * k, d[2] * k)
        return (p[0] + u[0] * dt, p[1] + u[1] * dt, p[2] + u[2] * dt), u


@dataclass(slots=True)
class _Fix:
    """The alpha-beta filter of one track's fixes: the last fix's time, position and velocity about home, 1-sigma."""

    t_us: int
    pos: list[float]
    vel: list[float]
    sigma_m: float


def report_problem(report: object, now_us: int, own_system_id: int) -> str | None:
    """Why a report cannot be used (one line), or None when it can."""
    if not isinstance(report, TrafficReport):
        return f"not a TrafficReport: {type(report).__name__}"
    r = report
    who = f"traffic report {r.source.name if isinstance(r.source, TrafficSource) else r.source}/{r.target_id}"
    if not isinstance(r.source, TrafficSource):
        return f"{who}: unknown source {r.source!r}"
    if not isinstance(r.target_id, int) or r.target_id < 0:
        return f"{who}: target id must be a non-negative integer"
    if r.source is TrafficSource.UAV and r.target_id == own_system_id:
        return f"{who}: reports this vehicle itself"
    numbers = (r.lat_deg, r.lon_deg, r.alt_amsl_m, r.vel_n_m_s, r.vel_e_m_s, r.vel_d_m_s)
    if not all(isinstance(x, int | float) and math.isfinite(x) for x in numbers):
        return f"{who}: position or velocity is not finite"
    if not (-90.0 <= r.lat_deg <= 90.0 and -180.0 <= r.lon_deg <= 180.0):
        return f"{who}: latitude/longitude out of range ({r.lat_deg}, {r.lon_deg})"
    if not (ALT_RANGE_M[0] <= r.alt_amsl_m <= ALT_RANGE_M[1]):
        return f"{who}: altitude {r.alt_amsl_m:g} m out of range"
    if math.hypot(r.vel_n_m_s, r.vel_e_m_s) > MAX_SPEED_H_M_S or abs(r.vel_d_m_s) > MAX_SPEED_V_M_S:
        return f"{who}: implausible velocity"
    if not isinstance(r.t_us, int) or r.t_us < 0 or r.t_us > now_us + MAX_FUTURE_US:
        return f"{who}: time {r.t_us} is not a past simulator time"
    return None


class TrackTable:
    """The tracks in force, about home. Pure: the caller gives the time and the reports."""

    def __init__(self, own_system_id: int, max_tracks: int = 50) -> None:
        self.own_system_id = own_system_id
        self.max_tracks = max_tracks  # PX4's ADSB_LIST_MAX upper bound
        self._reports: dict[TrackKey, TrafficReport] = {}
        self._tracks: dict[TrackKey, TrafficTrack] = {}
        self._frame: LocalNedFrame | None = None
        self.version = 0  # changes whenever the tracks in force change
        self._cached: tuple[int, tuple[TrafficTrack, ...]] = (-1, ())
        self._fixes: dict[TrackKey, _Fix] = {}

    def set_home(self, home: GeoPoint) -> None:
        """Home moved: every track is converted again about the new home."""
        if self._frame is not None and self._frame.home == home:
            return
        self._frame = LocalNedFrame(home)
        self._tracks = {key: self._track(report) for key, report in self._reports.items()}
        self._fixes.clear()  # about the old home
        self.version += 1

    def _track(self, r: TrafficReport) -> TrafficTrack:
        assert self._frame is not None
        pos = self._frame.ned_from_geodetic(r.lat_deg, r.lon_deg, r.alt_amsl_m)
        vel = (float(r.vel_n_m_s), float(r.vel_e_m_s), float(r.vel_d_m_s))
        next_pos = None
        if r.source is TrafficSource.UAV and r.has_next_waypoint:
            w = self._frame.ned_from_geodetic(r.next_lat_deg, r.next_lon_deg, r.next_alt_amsl_m)
            if math.dist(w, pos) <= MAX_INTENT_DISTANCE_M:
                next_pos = w
        return TrafficTrack(r.source, r.target_id, r.callsign, pos, vel, r.t_us, next_pos, r.flight_state,
                            float(r.h_acc_m), float(r.v_acc_m))  # fmt: skip

    def observe(self, key: TrackKey, t_us: int, pos_home_ned_m: Vec3, sigma_m: float) -> bool:
        """A fix of track ``key``: its position about home at ``t_us`` seen by this vehicle (1-sigma ``sigma_m``);
        False when there is no such track or the fix is not newer than its last one (nothing changes)."""
        track = self._tracks.get(key)
        if track is None:
            return False
        fix = self._fixes.get(key)
        if fix is not None and t_us <= fix.t_us:
            return False
        if fix is None or t_us - fix.t_us > FIX_RESTART_US:  # (re)start: this position, the report's velocity
            self._fixes[key] = _Fix(t_us, list(pos_home_ned_m), list(track.vel_ned_m_s), sigma_m)
            self.version += 1
            return True
        dt = (t_us - fix.t_us) * 1e-6  # > 0: an older or same-time fix returned above
        pos, vel = fix.pos, fix.vel
        for i in range(3):
            predicted = pos[i] + vel[i] * dt
            residual = pos_home_ned_m[i] - predicted
            pos[i] = predicted + FIX_ALPHA * residual
            vel[i] += FIX_BETA * residual / dt
        fix.t_us, fix.sigma_m = t_us, sigma_m
        self.version += 1
        return True

    def _fused(self, track: TrafficTrack) -> TrafficTrack:
        """The track flown on its fixes while they are not older than its report (see the module's docstring)."""
        fix = self._fixes.get(track.key)
        if fix is None or fix.t_us < track.t_us:
            return track
        p, v, s = fix.pos, fix.vel, fix.sigma_m
        return replace(track, pos_home_ned_m=(p[0], p[1], p[2]), vel_ned_m_s=(v[0], v[1], v[2]), t_us=fix.t_us,
                       h_acc_m=s, v_acc_m=s, reported_vel_ned_m_s=track.vel_ned_m_s)  # fmt: skip

    def update(self, now_us: int, reports: Iterable[object], max_age_s: float) -> tuple[list[str], list[TrafficTrack]]:
        """Take new reports and drop stale tracks; returns (rejections, dropped tracks)."""
        rejected: list[str] = []
        max_age_us = int(max_age_s * 1e6)
        for report in reports:
            problem = report_problem(report, now_us, self.own_system_id)
            if problem is None and now_us - report.t_us > max_age_us:  # type: ignore[attr-defined]
                problem = f"traffic report {report.target_id}: older than NAV_TRAFF_AGE_S"  # type: ignore[attr-defined]
            if problem is not None:
                rejected.append(problem)
                continue
            assert isinstance(report, TrafficReport)
            key = (report.source, report.target_id)
            old = self._reports.get(key)
            if old is not None and old.t_us >= report.t_us:
                continue  # not newer than what we hold
            if old is None and len(self._reports) >= self.max_tracks:
                rejected.append(f"traffic report {report.target_id}: track table full ({self.max_tracks})")
                continue
            self._reports[key] = report
            if self._frame is not None:
                self._tracks[key] = self._track(report)
                self.version += 1
        dropped = [t for k, t in self._tracks.items() if now_us - self._reports[k].t_us > max_age_us]
        for track in dropped:
            del self._tracks[track.key], self._reports[track.key]
            self.version += 1
        for key in [k for k, r in self._reports.items() if now_us - r.t_us > max_age_us]:
            del self._reports[key]  # stale before home was known
        for key in [k for k, f in self._fixes.items() if now_us - f.t_us > FIX_HOLD_US or k not in self._tracks]:
            del self._fixes[key]
            self.version += 1
        return rejected, dropped

    @property
    def has_tracks(self) -> bool:
        return bool(self._tracks)

    @property
    def tracks(self) -> tuple[TrafficTrack, ...]:
        """Tracks in force, in key order (deterministic)."""
        if self._cached[0] != self.version:
            self._cached = (self.version, tuple(self._fused(self._tracks[k]) for k in sorted(self._tracks)))
        return self._cached[1]
