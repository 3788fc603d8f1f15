"""Per-step cost of one vehicle's traffic layer with N-1 other vehicles in range (issue 28, SPEC §13).

One autopilot's traffic code as the runner calls it, on a ring of N vehicles flying to the antipodes (every track
in range and closing: the worst case for the reactive layer), with the track table refreshed at 1 Hz per track:

- ``traffic_reactive_us_per_step_nN``: ``TrafficGuard.step`` (what ``TrafficLink.bound`` runs) per control step
  (250 Hz): the reactive solve at the navigator's 50 Hz (ORCA planes of every track and the compiled solve) and
  the velocity reference between;
- ``traffic_strategic_us_per_step_nN``: ``TrafficAvoidance.update`` (track table, conflicts, the Bézier detour
  planning) at its 5 Hz re-check, per control step;
- ``traffic_layer_us_per_step_nN``: the two together, the figure to compare with an autopilot step.

Wall time of the measured calls only (``time.perf_counter``), after a warm-up; N = 8 and 32 (``--quick``: 8).
"""

from __future__ import annotations

import math
import time

from autopilot.navigation.home_frame import HomeFrame
from autopilot.navigation.traffic_link import TrafficLink
from autopilot.param_schema import make_param_store
from autopilot.traffic import AvoidLimits, OwnShip
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.traffic import AdsbEmitterType, TrafficReport, TrafficSource
from mavlink_bridge.contract.vehicle_api import FlightMode
from tools.benchmarks import BenchResult

HOME = GeoPoint(47.3977, 8.5456, 488.0)
CONTROL_HZ = 250
RADIUS_M = 60.0
SPEED_M_S = 6.0
SECONDS = 20.0


def _reports(n: int, t_s: float, frame: LocalNedFrame) -> list[TrafficReport]:
    """Vehicles 2..n of the ring at ``t_s`` (each flies straight to its antipode at SPEED_M_S), as received."""
    out = []
    for i in range(1, n):
        a = 2.0 * math.pi * i / n
        vn, ve = -math.cos(a) * SPEED_M_S, -math.sin(a) * SPEED_M_S
        pn, pe = RADIUS_M * math.cos(a) + vn * t_s, RADIUS_M * math.sin(a) + ve * t_s
        g = frame.geodetic_from_ned(pn, pe, -15.0)
        out.append(TrafficReport(TrafficSource.UAV, i + 1, "", AdsbEmitterType.UAV, g.lat_deg, g.lon_deg,
                                 g.alt_amsl_m, vn, ve, 0.0, round(t_s * 1e6)))  # fmt: skip
    return out


def measure(n: int, seconds: float = SECONDS) -> dict[str, float]:
    """µs per control step of the reactive and the strategic layer of vehicle 1 among ``n``."""
    params = make_param_store()
    link = TrafficLink(params, 1)
    frame = LocalNedFrame(HOME)
    home = HomeFrame(HOME, (0.0, 0.0, 0.0), 0.5, 0.8)
    link.avoidance.set_home(HOME)
    limits = AvoidLimits(params.get("CA_VMAX_M_S"), params.get("CA_AMAX_M_S2"), -120.0, -2.0)
    dt_s = 1.0 / CONTROL_HZ
    reactive_s = strategic_s = 0.0
    steps = round(seconds * CONTROL_HZ)
    warm = CONTROL_HZ
    for k in range(steps + warm):
        t_s = k * dt_s
        t_us = round(t_s * 1e6)
        own = (RADIUS_M - SPEED_M_S * t_s, 0.0, -15.0)
        vel = (-SPEED_M_S, 0.0, 0.0)
        reports = [r for r in _reports(n, math.floor(t_s), frame) if k % CONTROL_HZ == (r.target_id * 7) % CONTROL_HZ]
        t0 = time.perf_counter()
        if reports or k % (CONTROL_HZ // 5) == 0:
            link.avoidance.update(OwnShip(t_us, own, vel, ((-RADIUS_M, 0.0, -15.0),), SPEED_M_S, 1), reports,
                                  limits)  # fmt: skip
        t1 = time.perf_counter()
        link.guard.step(t_us, dt_s, home, own, vel, own, vel, FlightMode.AUTO_MISSION, False, link.avoidance.table,
                        link.avoidance.params)  # fmt: skip
        t2 = time.perf_counter()
        if k >= warm:
            strategic_s += t1 - t0
            reactive_s += t2 - t1
    return {"reactive_us": reactive_s / steps * 1e6, "strategic_us": strategic_s / steps * 1e6}


def run(quick: bool) -> list[BenchResult]:
    out: list[BenchResult] = []
    for n in (8,) if quick else (8, 32):
        m = measure(n, 5.0 if quick else SECONDS)
        note = f"{n - 1} tracks in range, ring swap"
        out.append(BenchResult(f"traffic_reactive_us_per_step_n{n}", m["reactive_us"], note=note))
        out.append(BenchResult(f"traffic_strategic_us_per_step_n{n}", m["strategic_us"], note=note))
        out.append(BenchResult(f"traffic_layer_us_per_step_n{n}", m["reactive_us"] + m["strategic_us"], note=note))
    return out


if __name__ == "__main__":
    for r in run(quick=False):
        print(f"{r.key:40s} {r.value:10.1f}  {r.note}")
