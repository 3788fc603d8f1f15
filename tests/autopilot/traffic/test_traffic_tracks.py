"""The track table: geodetic reports about home, aged out, extrapolated; garbage refused with a reason."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from traffic_kinematic import FRAME, HOME, report

from autopilot.traffic.tracks import TrackTable
from mavlink_bridge.contract.frames import GeoPoint
from mavlink_bridge.contract.traffic import TrafficSource


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
