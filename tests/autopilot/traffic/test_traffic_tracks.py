"""The track table: geodetic reports about home, aged out, extrapolated; garbage refused with a reason."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from traffic_kinematic import FRAME, HOME, report

from autopilot.traffic.tracks import TrackTable
from mavlink_bridge.contract.frames import GeoPoint
from mavlink_bridge.contract.traffic import TrafficSource, UtmFlightState


def _table() -> TrackTable:
    table = TrackTable(own_system_id=1)
    table.set_home(HOME)
    return table


def test_report_lands_about_home_and_is_extrapolated() -> None:
    table = _table()
    rejected, dropped = table.update(2_000_000, [report(TrafficSource.UAV, 2, np.array((120.0, -40.0, -30.0)),
                                                        np.array((3.0, 4.0, -1.0)), 1_000_000)], 5.0)  # fmt: skip
    assert rejected == [] and dropped == []
    (track,) = table.tracks
    assert track.pos_home_ned_m == pytest.approx((120.0, -40.0, -30.0), abs=1e-3)
    assert track.position_at(3_000_000) == pytest.approx((126.0, -32.0, -32.0), abs=1e-3)
    assert track.name == "UAV 2"


def test_home_change_reconverts_tracks() -> None:
    table = _table()
    table.update(0, [report(TrafficSource.MANNED, 0xA1B2C3, np.array((0.0, 0.0, -40.0)), np.zeros(3), 0)], 5.0)
    moved = FRAME.geodetic_from_ned(10.0, 0.0, 0.0)
    table.set_home(GeoPoint(moved.lat_deg, moved.lon_deg, HOME.alt_amsl_m))
    assert table.tracks[0].pos_home_ned_m[0] == pytest.approx(-10.0, abs=1e-3)
    assert table.tracks[0].name == "ICAO A1B2C3"


def test_stale_tracks_are_dropped_and_older_reports_ignored() -> None:
    table = _table()
    table.update(0, [report(TrafficSource.UAV, 2, np.zeros(3), np.zeros(3), 0)], 5.0)
    table.update(1_000_000, [report(TrafficSource.UAV, 2, np.array((5.0, 0, 0)), np.zeros(3), 1_000_000)], 5.0)
    table.update(1_100_000, [report(TrafficSource.UAV, 2, np.array((9.0, 0, 0)), np.zeros(3), 500_000)], 5.0)
    assert table.tracks[0].pos_home_ned_m[0] == pytest.approx(5.0, abs=1e-3)  # the older one did not win
    _, dropped = table.update(6_000_001, [], 5.0)
    assert [t.target_id for t in dropped] == [2] and table.tracks == ()
    rejected, _ = table.update(20_000_000, [report(TrafficSource.UAV, 3, np.zeros(3), np.zeros(3), 1_000_000)], 5.0)
    assert rejected == ["traffic report 3: older than NAV_TRAFF_AGE_S"] and table.tracks == ()


GOOD = report(TrafficSource.UAV, 2, np.array((10.0, 0.0, -20.0)), np.zeros(3), 1_000_000)


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        ({"lat_deg": math.nan}, "not finite"),
        ({"vel_e_m_s": math.inf}, "not finite"),
        ({"lat_deg": 123.0}, "out of range"),
        ({"alt_amsl_m": 1e6}, "altitude"),
        ({"vel_n_m_s": 900.0}, "implausible velocity"),
        ({"t_us": 9_000_000}, "not a past simulator time"),
        ({"target_id": 1}, "this vehicle itself"),
        ({"target_id": -4}, "non-negative"),
    ],
)
def test_garbage_is_refused_with_one_line_and_changes_nothing(change, reason) -> None:  # type: ignore[no-untyped-def]
    table = _table()
    rejected, _ = table.update(2_000_000, [dataclasses.replace(GOOD, **change)], 5.0)
    assert len(rejected) == 1 and reason in rejected[0] and "\n" not in rejected[0]
    assert table.tracks == ()


def test_non_report_objects_are_refused() -> None:
    rejected, _ = _table().update(0, ["ADSB_VEHICLE", None], 5.0)
    assert rejected == ["not a TrafficReport: str", "not a TrafficReport: NoneType"]


def test_table_is_bounded() -> None:
    table = TrackTable(own_system_id=1, max_tracks=2)
    table.set_home(HOME)
    reports = [report(TrafficSource.UAV, i, np.zeros(3), np.zeros(3), 0) for i in (2, 3, 4)]
    rejected, _ = table.update(0, reports, 5.0)
    assert rejected == ["traffic report 4: track table full (2)"]
    assert [t.target_id for t in table.tracks] == [2, 3]


def _intent_track(pos: tuple, vel: tuple, next_pos: tuple | None) -> object:
    """The track a UTM report with a next waypoint (about home) makes, through the table."""
    r = report(TrafficSource.UAV, 2, np.array(pos), np.array(vel), 1_000_000)
    if next_pos is not None:
        w = FRAME.geodetic_from_ned(*next_pos)
        r = dataclasses.replace(r, next_lat_deg=w.lat_deg, next_lon_deg=w.lon_deg, next_alt_amsl_m=w.alt_amsl_m,
                                flight_state=UtmFlightState.AIRBORNE, h_acc_m=0.5, v_acc_m=0.8)  # fmt: skip
    table = _table()
    table.update(1_000_000, [r], 5.0)
    (track,) = table.tracks
    return track


def test_predict_flies_toward_the_next_waypoint_at_the_reported_speed_then_holds() -> None:
    # level at 15 m going north at 5 m/s; its next waypoint is 20 m north and 10 m up: a climb it has not begun
    track = _intent_track((0.0, 0.0, -15.0), (5.0, 0.0, 0.0), (20.0, 0.0, -25.0))
    assert track.next_pos_home_ned_m == pytest.approx((20.0, 0.0, -25.0), abs=1e-3)
    assert track.flight_state is UtmFlightState.AIRBORNE and (track.h_acc_m, track.v_acc_m) == (0.5, 0.8)
    pos, vel = track.predict(3_000_000)  # 2 s: 10 m along the 22.36 m leg
    along = np.array((20.0, 0.0, -10.0)) / math.hypot(20.0, 10.0)
    assert pos == pytest.approx(tuple(np.array((0.0, 0.0, -15.0)) + 10.0 * along), abs=1e-3)
    assert vel == pytest.approx(tuple(5.0 * along), abs=1e-6)
    assert pos[2] < -15.0 - 4.0  # the climb is predicted; constant velocity says it stays level
    assert track.position_at(3_000_000)[2] == pytest.approx(-15.0, abs=1e-3)
    pos, vel = track.predict(11_000_000)  # 10 s: past the waypoint (4.5 s away): holds there
    assert pos == pytest.approx((20.0, 0.0, -25.0), abs=1e-3) and vel == (0.0, 0.0, 0.0)


def test_predict_turns_toward_a_waypoint_off_the_current_course() -> None:
    # going north, the next waypoint is due east: the turn shows in the prediction, not in position_at
    track = _intent_track((0.0, 0.0, -15.0), (4.0, 0.0, 0.0), (0.0, 40.0, -15.0))
    pos, vel = track.predict(2_000_000)
    assert pos == pytest.approx((0.0, 4.0, -15.0), abs=1e-3) and vel == pytest.approx((0.0, 4.0, 0.0), abs=1e-6)
    assert track.position_at(2_000_000) == pytest.approx((4.0, 0.0, -15.0), abs=1e-3)


def test_predict_without_intent_is_constant_velocity() -> None:
    track = _intent_track((10.0, 5.0, -20.0), (3.0, -1.0, 0.5), None)
    assert track.next_pos_home_ned_m is None and math.isnan(track.h_acc_m)
    for t_us in (500_000, 1_000_000, 4_000_000):
        pos, vel = track.predict(t_us)
        assert pos == track.position_at(t_us) and vel == (3.0, -1.0, 0.5)


def test_predict_of_a_standing_vehicle_or_a_manned_report_ignores_intent() -> None:
    standing = _intent_track((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, -15.0))  # on its pad, about to climb
    pos, vel = standing.predict(5_000_000)
    assert pos == pytest.approx((0.0, 0.0, 0.0), abs=1e-6) and vel == (0.0, 0.0, 0.0)
    r = report(TrafficSource.MANNED, 0xA1B2C3, np.array((0.0, 0.0, -40.0)), np.array((30.0, 0.0, 0.0)), 1_000_000)
    w = FRAME.geodetic_from_ned(0.0, 500.0, -40.0)
    table = _table()
    table.update(1_000_000, [dataclasses.replace(r, next_lat_deg=w.lat_deg, next_lon_deg=w.lon_deg,
                                                 next_alt_amsl_m=w.alt_amsl_m)], 5.0)  # fmt: skip
    assert table.tracks[0].next_pos_home_ned_m is None  # ADS-B carries no intent: none is believed
