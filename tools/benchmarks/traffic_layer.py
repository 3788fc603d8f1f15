"""Per-step cost of one vehicle's traffic layer with N-1 other vehicles in range (issue 28, SPEC §13).

One autopilot's traffic code as the runner calls it, on a ring of N vehicles flying to the antipodes (every track
in range and closing: the worst case for the reactive layer), with the track table refreshed at 1 Hz per track:

- ``traffic_reactive_us_per_step_nN``: ``TrafficGuard.step`` (what ``TrafficLink.bound`` runs) per control step
  (250 Hz): the reactive solve at the navigator's 50 Hz (ORCA planes of every track and the compiled solve) and
  the velocity reference between;
- ``traffic_strategic_us_per_step_nN``: ``TrafficAvoidance.update`` (track table, conflicts, the Bézier detour
  planning) at its 5 Hz re-check, per control step;
- ``traffic_fusion_us_per_step_nN``: ``TrafficLink.fuse`` (what ``Navigator.sense`` runs) per control step: at the
  obstacle sensor's 10 Hz, the detections of the other vehicles within the camera's 25 m (at most 6, as the
  sensor's object slots) gated onto their tracks and filtered as fixes;
- ``traffic_layer_us_per_step_nN``: the three together, the figure to compare with an autopilot step.

Wall time of the measured calls only (``time.perf_counter``), after a warm-up; N = 8 and 32 (``--quick``: 8).
"""

from __future__ import annotations

import math
import time

from autopilot.estimation import VehicleState
from autopilot.navigation.home_frame import HomeFrame
from autopilot.navigation.traffic_link import TrafficLink
from autopilot.param_schema import make_param_store
from autopilot.traffic import AvoidLimits, OwnShip
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.traffic import AdsbEmitterType, TrafficReport, TrafficSource
from mavlink_bridge.contract.vehicle_api import FlightMode
from mavlink_bridge.contract.wire import ObstacleDetection, ObstacleShape
from tools.benchmarks import BenchResult

HOME = GeoPoint(47.3977, 8.5456, 488.0)
CONTROL_HZ = 250
RADIUS_M = 60.0
SPEED_M_S = 6.0
SECONDS = 20.0
SENSOR_HZ = 10
CAMERA_RANGE_M = 25.0
SENSOR_SLOTS = 6
VEHICLE_RADIUS_M = 0.37  # an x500's collision sphere


def _ring(n: int, t_s: float) -> list[tuple[int, float, float, float, float]]:
    """Vehicles 2..n of the ring at ``t_s``: (system id, north, east, v north, v east); each flies straight to its
    antipode at SPEED_M_S."""
    out = []
    for i in range(1, n):
        a = 2.0 * math.pi * i / n
        vn, ve = -math.cos(a) * SPEED_M_S, -math.sin(a) * SPEED_M_S
        out.append((i + 1, RADIUS_M * math.cos(a) + vn * t_s, RADIUS_M * math.sin(a) + ve * t_s, vn, ve))
    return out


def ring_reports(n: int, t_s: float, frame: LocalNedFrame) -> list[TrafficReport]:
    """Vehicles 2..n of the ring at ``t_s`` (each flies straight to its antipode at SPEED_M_S), as received."""
    out = []
    for sys_id, pn, pe, vn, ve in _ring(n, t_s):
        g = frame.geodetic_from_ned(pn, pe, -15.0)
        out.append(TrafficReport(TrafficSource.UAV, sys_id, "", AdsbEmitterType.UAV, g.lat_deg, g.lon_deg,
                                 g.alt_amsl_m, vn, ve, 0.0, round(t_s * 1e6)))  # fmt: skip
    return out


def ring_detections(n: int, t_s: float, own: tuple[float, float, float]) -> tuple[ObstacleDetection, ...]:
    """The other vehicles within the camera's range at ``t_s`` as its detections (nearest surface point; the
    vehicle levelled, nose north: body FRD = NED), the nearest SENSOR_SLOTS."""
    seen = []
    for sys_id, pn, pe, _, _ in _ring(n, t_s):
        rel = (pn - own[0], pe - own[1], 0.0)
        d = math.hypot(rel[0], rel[1])
        if 1e-6 < d <= CAMERA_RANGE_M:
            f = (d - VEHICLE_RADIUS_M) / d
            surface = (rel[0] * f, rel[1] * f, 0.0)
            seen.append((d, ObstacleDetection(round(t_s * 1e6), 100 + sys_id, surface, VEHICLE_RADIUS_M,
                                              ObstacleShape.SPHERE)))  # fmt: skip
    return tuple(det for _, det in sorted(seen, key=lambda x: x[0])[:SENSOR_SLOTS])


def own_state(t_us: int, own: tuple[float, float, float], vel: tuple[float, float, float]) -> VehicleState:
    return VehicleState(t_us, own, vel, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, 0.0, 0.0, HOME.lat_deg,
                        HOME.lon_deg, HOME.alt_amsl_m, 3, 10, 0.5, 0.8, True)  # fmt: skip


def measure(n: int, seconds: float = SECONDS) -> dict[str, float]:
    """µs per control step of the reactive and the strategic layer and the fusion of vehicle 1 among ``n``."""
    params = make_param_store()
    link = TrafficLink(params, 1)
    frame = LocalNedFrame(HOME)
    home = HomeFrame(HOME, (0.0, 0.0, 0.0), 0.5, 0.8)
    link.avoidance.set_home(HOME)
    limits = AvoidLimits(params.get("CA_VMAX_M_S"), params.get("CA_AMAX_M_S2"), -120.0, -2.0)
    dt_s = 1.0 / CONTROL_HZ
    reactive_s = strategic_s = fusion_s = 0.0
    steps = round(seconds * CONTROL_HZ)
    warm = CONTROL_HZ
    for k in range(steps + warm):
        t_s = k * dt_s
        t_us = round(t_s * 1e6)
        own = (RADIUS_M - SPEED_M_S * t_s, 0.0, -15.0)
        vel = (-SPEED_M_S, 0.0, 0.0)
        due = [r for r in ring_reports(n, math.floor(t_s), frame) if k % CONTROL_HZ == (r.target_id * 7) % CONTROL_HZ]
        detections = ring_detections(n, t_s, own) if k % (CONTROL_HZ // SENSOR_HZ) == 0 else ()
        state = own_state(t_us, own, vel)
        tf = time.perf_counter()
        link.fuse(state, home, detections)
        t0 = time.perf_counter()
        if due or k % (CONTROL_HZ // 5) == 0:
            link.avoidance.update(OwnShip(t_us, own, vel, ((-RADIUS_M, 0.0, -15.0),), SPEED_M_S, 1), due,
                                  limits)  # fmt: skip
        t1 = time.perf_counter()
        link.guard.step(t_us, dt_s, home, own, vel, own, vel, FlightMode.AUTO_MISSION, False, link.avoidance.table,
                        link.avoidance.params)  # fmt: skip
        t2 = time.perf_counter()
        if k >= warm:
            fusion_s += t0 - tf
            strategic_s += t1 - t0
            reactive_s += t2 - t1
    us = 1e6 / steps
    return {"reactive_us": reactive_s * us, "strategic_us": strategic_s * us, "fusion_us": fusion_s * us}


def run(quick: bool) -> list[BenchResult]:
    out: list[BenchResult] = []
    for n in (8,) if quick else (8, 32):
        m = measure(n, 5.0 if quick else SECONDS)
        note = f"{n - 1} tracks in range, ring swap"
        out.append(BenchResult(f"traffic_reactive_us_per_step_n{n}", m["reactive_us"], note=note))
        out.append(BenchResult(f"traffic_strategic_us_per_step_n{n}", m["strategic_us"], note=note))
        out.append(BenchResult(f"traffic_fusion_us_per_step_n{n}", m["fusion_us"], note=note))
        total = m["reactive_us"] + m["strategic_us"] + m["fusion_us"]
        out.append(BenchResult(f"traffic_layer_us_per_step_n{n}", total, note=note))
    return out


if __name__ == "__main__":
    for r in run(quick=False):
        print(f"{r.key:40s} {r.value:10.1f}  {r.note}")
