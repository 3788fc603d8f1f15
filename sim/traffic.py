"""Scripted manned traffic and the simulated transponder receiver of each vehicle (SPEC §13).

``ScriptedTraffic`` flies each ``traffic:`` aircraft kinematically: it appears at the first point of its path at
``start_s``, follows the polyline at constant ``speed_m_s`` and is gone after the last point (no dynamics, no
wind: a manned aircraft as an ADS-B receiver sees it).

``TrafficReceiver`` decides what each vehicle's receiver reports at a control step: every other vehicle (as a
UAV report, from the truth, as that vehicle's own UTM broadcast would say) and every airborne scripted aircraft
(a MANNED report), once a second per target, within ``range_m`` (3D) of the receiver, never the receiver's own
vehicle. Targets are staggered over the second (target k is due at step ``k * control_hz // targets`` of each
second) so the reports of a big fleet do not all land in one frame; the receiver's own HEARTBEAT is due at step
0 of each second. Everything is a function of the step number and the states: deterministic at any speed.
"""

from __future__ import annotations

import numpy as np

from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.traffic import AdsbEmitterType, TrafficReport, TrafficSource
from sim.fleet_world import ScriptedAircraft

#: Default reporting range of the simulated receiver (m, 3D): far beyond any NMAC volume and a quad's horizon.
DEFAULT_TRAFFIC_RANGE_M = 10_000.0


class ScriptedTraffic:
    """Positions and velocities (NED about the world's home) of the scripted aircraft at a sim time."""

    def __init__(self, aircraft: tuple[ScriptedAircraft, ...]) -> None:
        self.aircraft = aircraft
        self._points: list[np.ndarray] = []  # (k, 3) NED per aircraft
        self._dist_m: list[np.ndarray] = []  # (k,) cumulative path length
        for a in aircraft:
            pts = np.array([(p.north_m, p.east_m, -p.alt_m) for p in a.path], dtype=np.float64)
            self._points.append(pts)
            self._dist_m.append(np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))))

    def __len__(self) -> int:
        return len(self.aircraft)

    def state(self, k: int, t_s: float) -> tuple[np.ndarray, np.ndarray] | None:
        """(pos_ned (3,), vel_ned (3,)) of aircraft ``k`` at ``t_s``; None before its start or after its end."""
        a = self.aircraft[k]
        s = (t_s - a.start_s) * a.speed_m_s
        dist = self._dist_m[k]
        if s < 0.0 or s > dist[-1]:
            return None
        pts = self._points[k]
        seg = min(int(np.searchsorted(dist, s, side="right")) - 1, len(pts) - 2)
        length = dist[seg + 1] - dist[seg]
        direction = (pts[seg + 1] - pts[seg]) / length if length > 0.0 else np.zeros(3)
        return pts[seg] + direction * (s - dist[seg]), direction * a.speed_m_s

    def positions(self, t_s: float) -> np.ndarray:
        """(m, 3) positions at ``t_s`` (NaN rows for aircraft not flying)."""
        out = np.full((len(self.aircraft), 3), np.nan)
        for k in range(len(self.aircraft)):
            st = self.state(k, t_s)
            if st is not None:
                out[k] = st[0]
        return out


#: The near mid-air collision volume (FAA/ICAO): inside 500 ft horizontally and 100 ft vertically at once.
NMAC_HOR_M = 152.4
NMAC_VER_M = 30.48
#: A vehicle lower than this above the ground (m) is on its pad, not in flight (a take-off held under traffic
#: hovers a few centimetres up; the autopilot parks traffic below 1.5 m the same way).
IN_FLIGHT_MIN_AGL_M = 1.5


class MannedProximity:
    """Per vehicle, against every scripted aircraft in the air: the closest 3D approach and the sim time of the
    first NMAC (the truth the encounter Monte Carlo counts; the vehicles never see it). An NMAC is an event
    between aircraft in flight: a vehicle on the ground (standing, or held within ``IN_FLIGHT_MIN_AGL_M`` of its
    pad, under a low aircraft's path) is not
    counted, as the UAV separation measure does not count parked vehicles (``ground_nmac_at_s`` keeps when
    an aircraft passed that low over a vehicle on the ground, for the record)."""

    def __init__(self, traffic: ScriptedTraffic, n: int) -> None:
        self.traffic = traffic
        self.min_distance_m = np.full(n, np.inf)
        self.nmac_at_s: list[float | None] = [None] * n
        self.ground_nmac_at_s: list[float | None] = [None] * n

    def update(self, t_s: float, pos_ned: np.ndarray, on_ground: np.ndarray | None = None) -> None:
        """Fold the vehicles' positions ``pos_ned`` (n, 3) at ``t_s`` in; ``on_ground`` (n,) bool: standing
        on the ground (None: all airborne)."""
        if not len(self.traffic):
            return
        air = self.traffic.positions(t_s)
        air = air[~np.isnan(air[:, 0])]
        if not len(air):
            return
        d = pos_ned[:, None, :] - air[None, :, :]
        h_m, v_m = np.hypot(d[..., 0], d[..., 1]), np.abs(d[..., 2])
        np.minimum(self.min_distance_m, np.hypot(h_m, v_m).min(axis=1), out=self.min_distance_m)
        inside = ((h_m < NMAC_HOR_M) & (v_m < NMAC_VER_M)).any(axis=1)
        grounded = pos_ned[:, 2] > -IN_FLIGHT_MIN_AGL_M  # flat ground at home level (fleet worlds)
        if on_ground is not None:
            grounded |= np.asarray(on_ground, dtype=bool)
        for i in np.flatnonzero(inside):
            first = self.ground_nmac_at_s if grounded[i] else self.nmac_at_s
            if first[i] is None:
                first[i] = t_s


class TrafficReceiver:
    """What each vehicle's simulated receiver reports at a control step (see the module docstring)."""

    def __init__(
        self,
        home: GeoPoint,
        sys_ids: tuple[int, ...],
        traffic: ScriptedTraffic,
        control_hz: int,
        range_m: float = DEFAULT_TRAFFIC_RANGE_M,
    ) -> None:
        if not range_m > 0.0:
            raise ValueError(f"traffic range: expected a positive distance in metres, got {range_m}")
        self._frame = LocalNedFrame(home)
        self.sys_ids = sys_ids
        self.traffic = traffic
        self.control_hz = control_hz
        self.range_m = range_m
        targets = len(sys_ids) + len(traffic)
        #: step within each second at which target k (vehicles first, then aircraft) is reported
        self._due_step = [k * control_hz // max(targets, 1) for k in range(targets)]

    def heartbeat_due(self, step: int) -> bool:
        """True when the receivers send their 1 Hz HEARTBEAT (MAV_TYPE_ADSB) with this step's frame."""
        return step % self.control_hz == 0

    def reports(
        self, step: int, t_us: int, pos_ned: np.ndarray, vel_ned: np.ndarray, broadcasting: np.ndarray
    ) -> list[list[TrafficReport]]:
        """Per vehicle, the reports due at ``step`` (time ``t_us``); ``pos_ned``/``vel_ned`` (n, 3) truth of the
        vehicles, ``broadcasting`` (n,) bool: vehicles whose autopilot is alive (a dead one sends no UTM)."""
        n = len(self.sys_ids)
        out: list[list[TrafficReport]] = [[] for _ in range(n)]
        phase = step % self.control_hz
        for k, due in enumerate(self._due_step):
            if due != phase:
                continue
            if k < n:
                if not broadcasting[k]:
                    continue
                target_pos, target_vel = pos_ned[k], vel_ned[k]
                who = (TrafficSource.UAV, self.sys_ids[k], "", AdsbEmitterType.UAV)
            else:
                a = self.traffic.aircraft[k - n]
                st = self.traffic.state(k - n, t_us * 1e-6)
                if st is None:
                    continue
                target_pos, target_vel = st
                who = (TrafficSource.MANNED, a.icao, a.callsign, a.emitter)
            geo = self._frame.geodetic_from_ned(float(target_pos[0]), float(target_pos[1]), float(target_pos[2]))
            vn, ve, vd = (float(v) for v in target_vel)
            report = TrafficReport(*who, geo.lat_deg, geo.lon_deg, geo.alt_amsl_m, vn, ve, vd, t_us)
            gap_m = np.linalg.norm(pos_ned - target_pos, axis=1)
            for i in range(n):
                if i != k and gap_m[i] <= self.range_m:
                    out[i].append(report)
        return out
