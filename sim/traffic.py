"""Scripted manned traffic and the simulated transponder receiver of each vehicle (SPEC §13).

``ScriptedTraffic`` flies each ``traffic:`` aircraft kinematically: it appears at the first point of its path at
``start_s``, follows the polyline at constant ``speed_m_s`` and is gone after the last point (no dynamics, no
wind: a manned aircraft as an ADS-B receiver sees it).

``TrafficReceiver`` decides what each vehicle's receiver reports at a control step. It never reports the truth:

- **Other vehicles** (UTM_GLOBAL_POSITION): only what their autopilots sent (``uplink``: each autopilot's own
  report, its estimate and intent), relayed as a UTM service would: ``utm_latency_s`` after it was sent, to every
  other vehicle within ``utm_range_m`` (3D, of the reported position) of it. A vehicle whose autopilot sends
  nothing (dead) is not reported; what it sent before is still delivered.
- **Manned aircraft** (ADSB_VEHICLE), once a second per aircraft as a 1090ES/UAT receiver passes them on: the
  position and velocity the aircraft broadcast ``adsb_latency_s`` ago (uncompensated latency: the report is stamped
  when it arrives), with its navigation source's error (a first-order Gauss-Markov process per aircraft, correlation
  time ``adsb_error_tau_s``, 95 % bounds of its NACp/NACv), each report received with probability
  ``adsb_reception`` (per receiver), within ``adsb_range_m`` (3D) of the receiver. Aircraft are staggered over the
  second (aircraft k at step ``k * control_hz // aircraft``); the receiver's own HEARTBEAT is at step 0 of each
  second.

Everything is a function of the step number, the states, the uplinked reports and the world's seed (every aircraft
and receiver has its own seeded stream): deterministic at any speed. ``TrafficLinkConfig`` holds the link's
numbers and where each default comes from (docs/traffic.md).
"""

from __future__ import annotations

import logging
import math
from collections import deque

import numpy as np

from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.traffic import TrafficReport, TrafficSource
from sim.fleet_world import ScriptedAircraft
from sim.traffic_link import DEFAULT_TRAFFIC_RANGE_M, TrafficLinkConfig

log = logging.getLogger(__name__)
__all__ = ["DEFAULT_TRAFFIC_RANGE_M", "MannedProximity", "ScriptedTraffic", "TrafficLinkConfig", "TrafficReceiver"]
_SEED_TAG_ERROR = 0xAD5B
_SEED_TAG_RECEPTION = 0x1090


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


class AdsbSource:
    """One aircraft's broadcast errors: position a Gauss-Markov process (stationary from the first report),
    velocity white, both at the NACp/NACv sigmas; its own seeded stream."""

    def __init__(self, config: TrafficLinkConfig, seed: int, index: int) -> None:
        self._rng = random_stream(seed, _SEED_TAG_ERROR, index)
        sh, sv, svh, svv = config.adsb_sigmas
        self._pos_sigma = np.array((sh, sh, sv))
        self._vel_sigma = np.array((svh, svh, svv))
        tau = config.adsb_error_tau_s
        self._a = math.exp(-1.0 / tau) if tau > 0.0 else 0.0  # one report a second
        self._pos_error: np.ndarray | None = None

    def next_errors(self) -> tuple[np.ndarray, np.ndarray]:
        """(position error NED m, velocity error NED m/s) of the next 1 Hz report."""
        draw = self._rng.standard_normal(6)
        if self._pos_error is None:
            self._pos_error = self._pos_sigma * draw[:3]
        else:
            a = self._a
            self._pos_error = a * self._pos_error + math.sqrt(1.0 - a * a) * self._pos_sigma * draw[:3]
        return self._pos_error, self._vel_sigma * draw[3:]


class TrafficReceiver:
    """What each vehicle's simulated receiver reports at a control step (see the module docstring)."""

    def __init__(
        self,
        home: GeoPoint,
        sys_ids: tuple[int, ...],
        traffic: ScriptedTraffic,
        control_hz: int,
        config: TrafficLinkConfig | None = None,
        seed: int = 0,
    ) -> None:
        config = config or TrafficLinkConfig()
        problem = config.problem()
        if problem is not None:
            raise ValueError(f"traffic link: {problem}")
        self.config = config
        self._frame = LocalNedFrame(home)
        self.sys_ids = sys_ids
        self.traffic = traffic
        self.control_hz = control_hz
        self.control_us = 1_000_000 // control_hz
        n, m = len(sys_ids), len(traffic)
        #: step within each second at which aircraft k is reported
        self._due_step = [k * control_hz // max(m, 1) for k in range(m)]
        self._sources = [AdsbSource(config, seed, k) for k in range(m)]
        self._reception = [
            [random_stream(seed, _SEED_TAG_RECEPTION, i, k) for k in range(m)] for i in range(n)
        ]  # per receiver and aircraft
        self._utm_latency_us = round(config.utm_latency_s * 1e6)
        self._adsb_latency_s = config.adsb_latency_s
        #: UTM reports in flight: (deliver at µs, sender index, report, reported position NED about the world home)
        self._relay: deque[tuple[int, int, TrafficReport, np.ndarray]] = deque()
        self.utm_received = np.zeros(n, dtype=np.int64)  # own reports taken from each vehicle
        self.utm_rejected = np.zeros(n, dtype=np.int64)  # and refused (with a logged reason)
        self.adsb_dropped = np.zeros(n, dtype=np.int64)  # ADS-B reports each receiver missed (reception)

    def heartbeat_due(self, step: int) -> bool:
        """True when the receivers send their 1 Hz HEARTBEAT (MAV_TYPE_ADSB) with this step's frame."""
        return step % self.control_hz == 0

    def uplink(self, i: int, t_us: int, reports: tuple[object, ...] | list[object]) -> None:
        """Vehicle ``i``'s own reports that came with its answer to the frame at ``t_us`` (UTM_GLOBAL_POSITION
        decoded): queued for the others ``utm_latency_s`` later; one that is not its own, finite and of a past time
        is refused (counted, the first logged in one line)."""
        for r in reports:
            problem = self._uplink_problem(i, t_us, r)
            if problem is not None:
                if not self.utm_rejected[i]:
                    log.warning("traffic: vehicle %d's own report refused: %s", self.sys_ids[i], problem)
                self.utm_rejected[i] += 1
                continue
            assert isinstance(r, TrafficReport)
            pos = np.array(self._frame.ned_from_geodetic(r.lat_deg, r.lon_deg, r.alt_amsl_m))
            self._relay.append((t_us + self._utm_latency_us, i, r, pos))
            self.utm_received[i] += 1

    def _uplink_problem(self, i: int, t_us: int, r: object) -> str | None:
        if not isinstance(r, TrafficReport) or r.source is not TrafficSource.UAV:
            return f"not a UAV report: {r!r:.80}"
        if r.target_id != self.sys_ids[i]:
            return f"it claims MAV_SYS_ID {r.target_id}"
        numbers = (r.lat_deg, r.lon_deg, r.alt_amsl_m, r.vel_n_m_s, r.vel_e_m_s, r.vel_d_m_s)
        if not all(math.isfinite(x) for x in numbers):
            return "position or velocity is not finite"
        if not 0 <= r.t_us <= t_us:
            return f"time {r.t_us} us is not a past simulator time (now {t_us} us)"
        return None

    def reports(self, step: int, t_us: int, pos_ned: np.ndarray, receiving: np.ndarray) -> list[list[TrafficReport]]:
        """Per vehicle, the reports due at ``step`` (time ``t_us``); ``pos_ned`` (n, 3) truth of the vehicles,
        ``receiving`` (n,) bool: vehicles whose autopilot is alive (the others get no frame)."""
        n = len(self.sys_ids)
        out: list[list[TrafficReport]] = [[] for _ in range(n)]
        relay = self._relay
        utm_range = self.config.utm_range_m
        while relay and relay[0][0] <= t_us:
            _, sender, report, at = relay.popleft()
            gap_m = np.linalg.norm(pos_ned - at, axis=1)
            for i in range(n):
                if i != sender and receiving[i] and gap_m[i] <= utm_range:
                    out[i].append(report)
        phase = step % self.control_hz
        for k, due in enumerate(self._due_step):
            if due == phase:
                self._adsb(k, t_us, pos_ned, receiving, out)
        return out

    def _adsb(
        self, k: int, t_us: int, pos_ned: np.ndarray, receiving: np.ndarray, out: list[list[TrafficReport]]
    ) -> None:
        """Aircraft ``k``'s report of this second into ``out`` (every stream draws whether it is heard or not)."""
        st = self.traffic.state(k, t_us * 1e-6 - self._adsb_latency_s)
        if st is None:
            return
        pos_error, vel_error = self._sources[k].next_errors()
        target_pos, target_vel = st[0] + pos_error, st[1] + vel_error
        a = self.traffic.aircraft[k]
        geo = self._frame.geodetic_from_ned(float(target_pos[0]), float(target_pos[1]), float(target_pos[2]))
        vn, ve, vd = (float(v) for v in target_vel)
        report = TrafficReport(TrafficSource.MANNED, a.icao, a.callsign, a.emitter, geo.lat_deg, geo.lon_deg,
                               geo.alt_amsl_m, vn, ve, vd, t_us)  # fmt: skip
        gap_m = np.linalg.norm(pos_ned - st[0], axis=1)
        reception = self.config.adsb_reception
        for i, streams in enumerate(self._reception):
            heard = streams[k].random() < reception
            if not (receiving[i] and gap_m[i] <= self.config.adsb_range_m):
                continue
            if heard:
                out[i].append(report)
            else:
                self.adsb_dropped[i] += 1


def random_stream(seed: int, *tags: int) -> np.random.Generator:
    """A seeded stream of its own for ``tags`` (independent of every other stream of the run)."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed & (2**64 - 1), *tags])))
