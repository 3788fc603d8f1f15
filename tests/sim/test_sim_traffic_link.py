"""The receivers stop reporting truth (SPEC §13): the UTM relay (latency, range, only what was sent) and the ADS-B
link (NACp/NACv noise, latency, reception), seeded and deterministic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.traffic import AdsbEmitterType, TrafficReport, TrafficSource, UtmFlightState
from sim.fleet_world import ScriptedAircraft, TrafficWaypoint, WorldConfigError, fleet_of
from sim.traffic import ScriptedTraffic, TrafficReceiver
from sim.traffic_link import NACP_EPU_M, NACP_VEPU_M, TrafficLinkConfig

HOME = GeoPoint(47.3977, 8.5456, 488.0)
FRAME = LocalNedFrame(HOME)
HZ = 250
STEP_US = 1_000_000 // HZ


def _own(sys_id: int, t_us: int, ned: tuple[float, float, float]) -> TrafficReport:
    geo = FRAME.geodetic_from_ned(*ned)
    return TrafficReport(TrafficSource.UAV, sys_id, "", AdsbEmitterType.UAV, geo.lat_deg, geo.lon_deg,
                         geo.alt_amsl_m, 1.0, 0.0, 0.0, t_us, flight_state=UtmFlightState.AIRBORNE,
                         update_rate_hz=1.0)  # fmt: skip


def _heli(speed_m_s: float = 40.0, alt_m: float = 40.0) -> ScriptedAircraft:
    path = (TrafficWaypoint(-2000.0, 60.0, alt_m), TrafficWaypoint(200_000.0, 60.0, alt_m))
    return ScriptedAircraft("HELI1", 0xA1B2C3, AdsbEmitterType.ROTOCRAFT, path, speed_m_s, 0.0)


def _receiver(n: int, aircraft: tuple = (), seed: int = 7, **link: float) -> TrafficReceiver:
    return TrafficReceiver(HOME, tuple(range(1, n + 1)), ScriptedTraffic(aircraft), HZ, TrafficLinkConfig(**link), seed)


def _run(rx: TrafficReceiver, pos: np.ndarray, steps: range) -> list[tuple[int, int, TrafficReport]]:
    """(step, receiver, report) of every report delivered over ``steps``."""
    out = []
    alive = np.ones(len(pos), dtype=bool)
    for step in steps:
        for i, reports in enumerate(rx.reports(step, step * STEP_US, pos, alive)):
            out += [(step, i, r) for r in reports]
    return out


def test_an_own_report_reaches_the_others_the_latency_later_and_only_them() -> None:
    rx = _receiver(3, utm_latency_s=0.8)
    pos = np.array([(0.0, 0.0, -10.0), (30.0, 0.0, -10.0), (0.0, 40.0, -10.0)])
    sent = _own(2, 100 * STEP_US, (30.0, 0.0, -10.0))
    rx.uplink(1, 100 * STEP_US, [sent])
    got = _run(rx, pos, range(0, 500))
    assert [(step, i) for step, i, _ in got] == [(300, 0), (300, 2)]  # 0.8 s = 200 steps later, never to itself
    assert all(r is sent for _, _, r in got)  # relayed as sent: its estimate and intent, not the truth


def test_the_relay_ends_at_its_range_and_refuses_reports_that_are_not_the_senders() -> None:
    rx = _receiver(2, utm_range_m=100.0, utm_latency_s=0.0)
    pos = np.array([(0.0, 0.0, -10.0), (0.0, 0.0, -10.0)])
    rx.uplink(1, 0, [_own(2, 0, (120.0, 0.0, -10.0))])  # reported 120 m from vehicle 0
    rx.uplink(1, 0, [_own(2, 0, (90.0, 0.0, -10.0))])  # 90 m: inside
    rx.uplink(1, 0, [_own(1, 0, (10.0, 0.0, -10.0))])  # claims vehicle 0's id
    rx.uplink(1, 0, [_own(2, STEP_US, (10.0, 0.0, -10.0))])  # stamped in the future
    got = _run(rx, pos, range(0, 2))
    assert len(got) == 1 and got[0][2].lat_deg == pytest.approx(FRAME.geodetic_from_ned(90.0, 0.0, -10.0).lat_deg)
    assert list(rx.utm_received) == [0, 2] and list(rx.utm_rejected) == [0, 2]


def test_adsb_position_noise_matches_the_nacp_bound_and_is_seeded() -> None:
    """Over many seeded aircraft (white errors here: tau 0), ~95 % of the horizontal errors fall inside NACp's EPU
    and of the vertical ones inside its vertical bound; the velocity errors inside NACv's."""
    for nacp in (9, 10):
        rx = _receiver(1, tuple(_heli() for _ in range(40)), adsb_nacp=nacp, adsb_error_tau_s=0.0,
                       adsb_latency_s=0.0, adsb_reception=1.0)  # fmt: skip
        far = np.array([(0.0, 0.0, 0.0)])
        h, v, speed = [], [], []
        for step, _, r in _run(rx, far, range(0, 30 * HZ)):
            truth = rx.traffic.state(0, step * STEP_US * 1e-6)
            assert truth is not None
            ned = np.array(FRAME.ned_from_geodetic(r.lat_deg, r.lon_deg, r.alt_amsl_m))
            h.append(math.hypot(*(ned - truth[0])[:2]))
            v.append(abs(ned[2] - truth[0][2]))
            speed.append(math.hypot(r.vel_n_m_s - 40.0, r.vel_e_m_s))
        assert len(h) == 40 * 30
        assert np.mean(np.array(h) < NACP_EPU_M[nacp]) == pytest.approx(0.95, abs=0.02)
        assert np.mean(np.array(v) < NACP_VEPU_M[nacp]) == pytest.approx(0.95, abs=0.02)
        assert np.mean(np.array(speed) < 3.0) == pytest.approx(0.95, abs=0.02)  # NACv 2
        assert np.median(h) > NACP_EPU_M[nacp] / 4  # noisy: not the truth


def test_adsb_errors_are_correlated_reports_late_and_some_are_lost() -> None:
    rx = _receiver(1, (_heli(),), adsb_latency_s=0.6, adsb_reception=0.8, adsb_range_m=1e6)
    got = _run(rx, np.zeros((1, 3)), range(0, 400 * HZ))
    assert 0.76 < len(got) / 399 < 0.84 and rx.adsb_dropped[0] == 399 - len(got)  # 80 %; at t = 0 none is 0.6 s old
    errors = []
    for step, _, r in got:
        late = rx.traffic.state(0, step * STEP_US * 1e-6 - 0.6)
        assert late is not None
        errors.append(np.array(FRAME.ned_from_geodetic(r.lat_deg, r.lon_deg, r.alt_amsl_m)) - late[0])
    e = np.array(errors)[:, 0]
    assert np.corrcoef(e[:-1], e[1:])[0, 1] > 0.8  # Gauss-Markov, tau 60 s: a slowly wandering error
    assert np.mean(np.abs(np.array(errors)[:, :2])) < 30.0  # about the position 0.6 s ago, not now (24 m ahead)


def test_same_seed_same_reports_other_seed_others() -> None:
    def reports(seed: int) -> list:
        rx = _receiver(2, (_heli(),), seed=seed)
        return [(s, i, r.lat_deg, r.alt_amsl_m) for s, i, r in _run(rx, np.zeros((2, 3)), range(0, 20 * HZ))]

    assert reports(3) == reports(3) and reports(3) != reports(4)


def test_world_traffic_link_keys_are_checked_with_the_fix() -> None:
    doc = {"vehicles": [{"name": "a", "home": {"north_m": 0, "east_m": 0}}], "traffic_link": {"adsb_nacp": 10}}
    assert fleet_of(doc).traffic_link == (("adsb_nacp", 10.0),)
    assert TrafficLinkConfig.with_overrides(fleet_of(doc).traffic_link).adsb_nacp == 10
    with pytest.raises(WorldConfigError, match="adsb_nacp: expected one of"):
        fleet_of({**doc, "traffic_link": {"adsb_nacp": 5}})
    with pytest.raises(WorldConfigError, match="unknown field"):
        fleet_of({**doc, "traffic_link": {"utm_latency": 1}})
