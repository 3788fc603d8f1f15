"""Traffic reports on the wire (SPEC §13): what a MAVLink tool reads from the simulator's receiver, and back."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.traffic import (
    AdsbEmitterType,
    OwnPositionReport,
    TrafficReport,
    TrafficSource,
    UtmFlightState,
)
from mavlink_bridge.wire.codec import Decoder, Encoder, Heartbeat
from mavlink_bridge.wire.traffic_codec import (
    MAV_COMP_ID_ADSB,
    MAV_TYPE_ADSB,
    UTM_FLAGS_SIM,
    uas_id_bytes,
    utm_problem,
)

HELI = TrafficReport(
    TrafficSource.MANNED, 0xA1B2C3, "HELI1", AdsbEmitterType.ROTOCRAFT, 47.3977, 8.5456, 528.0, -30.0, 0.0, -2.0, 0
)
QUAD = TrafficReport(TrafficSource.UAV, 3, "", AdsbEmitterType.UAV, 47.3978, 8.5457, 498.5, 1.0, -2.0, 0.5, 12_000)


def _parse(data: bytes) -> list:
    mav = mavlink2.MAVLink(None)
    return mav.parse_buffer(data) or []


def test_adsb_vehicle_has_cdeg_heading_from_north_and_the_simulated_flag() -> None:
    (msg,) = _parse(Encoder(2, MAV_COMP_ID_ADSB).traffic(HELI))
    assert msg.get_type() == "ADSB_VEHICLE" and msg.get_srcComponent() == MAV_COMP_ID_ADSB
    assert msg.heading == 18000  # flying south: 180 deg, 0 = north
    assert msg.hor_velocity == 3000 and msg.ver_velocity == 200  # cm/s, vertical positive up
    assert msg.flags & mavlink2.ADSB_FLAGS_SIMULATED
    valid = mavlink2.ADSB_FLAGS_VALID_COORDS | mavlink2.ADSB_FLAGS_VALID_ALTITUDE | mavlink2.ADSB_FLAGS_VALID_HEADING
    assert msg.flags & valid == valid
    assert (msg.ICAO_address, msg.callsign, msg.emitter_type) == (0xA1B2C3, "HELI1", 7)
    assert msg.altitude == 528000 and msg.lat == 473977000


def test_utm_global_position_carries_the_senders_system_id_and_ned_velocity() -> None:
    (msg,) = _parse(Encoder(1, MAV_COMP_ID_ADSB).traffic(QUAD))
    assert msg.get_type() == "UTM_GLOBAL_POSITION"
    assert bytes(msg.uas_id)[-4:] == (3).to_bytes(4, "big")
    assert (msg.vx, msg.vy, msg.vz, msg.time) == (100, -200, 50, 12_000)


def test_reports_decode_back_into_traffic_reports() -> None:
    encoder = Encoder(1, MAV_COMP_ID_ADSB)
    datagram = encoder.heartbeat(Heartbeat(MAV_TYPE_ADSB, 8, 0, 0, 4)) + encoder.traffic(HELI) + encoder.traffic(QUAD)
    beat, heli, quad = Decoder().decode(datagram)
    assert isinstance(beat, Heartbeat) and beat.mav_type == MAV_TYPE_ADSB
    assert quad == QUAD
    assert heli.target_id == HELI.target_id and heli.callsign == "HELI1" and heli.t_us == 0  # stamped by the client
    assert (heli.vel_n_m_s, heli.vel_e_m_s, heli.vel_d_m_s) == pytest.approx((-30.0, 0.0, -2.0), abs=1e-9)
    assert heli.lat_deg == pytest.approx(HELI.lat_deg, abs=1e-7) and heli.alt_amsl_m == pytest.approx(528.0)


def test_adsb_without_valid_coordinates_is_dropped() -> None:
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=MAV_COMP_ID_ADSB)
    msg = mavlink2.MAVLink_adsb_vehicle_message(1, 0, 0, 0, 0, 0, 0, 0, b"X", 0, 0, 0, 0)
    decoder = Decoder()
    assert decoder.decode(msg.pack(mav)) == [] and decoder.stats.ignored == 1


OWN = OwnPositionReport(
    t_us=40_000_000,
    sys_id=2,
    lat_deg=47.3979,
    lon_deg=8.5458,
    alt_amsl_m=503.25,
    vel_n_m_s=4.0,
    vel_e_m_s=-1.5,
    vel_d_m_s=-0.75,
    flight_state=UtmFlightState.AIRBORNE,
    update_rate_hz=1.0,
    h_acc_m=0.8,
    v_acc_m=1.2,
    vel_acc_m_s=0.3,
    next_lat_deg=47.3990,
    next_lon_deg=8.5470,
    next_alt_amsl_m=510.0,
)


def test_an_own_report_reads_in_pymavlink_as_utm_global_position_with_intent() -> None:
    (msg,) = _parse(Encoder(2, 1).own_position(OWN))
    assert msg.get_type() == "UTM_GLOBAL_POSITION"
    assert (msg.next_lat, msg.next_lon, msg.next_alt) == (473990000, 85470000, 510000)
    assert msg.flags & mavlink2.UTM_DATA_AVAIL_FLAGS_NEXT_WAYPOINT_AVAILABLE
    assert msg.flight_state == mavlink2.UTM_FLIGHT_STATE_AIRBORNE and msg.update_rate == 100  # cs
    assert (msg.h_acc, msg.v_acc, msg.vel_acc) == (800, 1200, 30)  # mm, mm, cm/s
    assert bytes(msg.uas_id)[-4:] == (2).to_bytes(4, "big")


def test_an_own_report_decodes_into_a_traffic_report_with_its_intent() -> None:
    (r,) = Decoder().decode(Encoder(2, 1).own_position(OWN))
    assert (r.source, r.target_id, r.t_us, r.flight_state) == (TrafficSource.UAV, 2, OWN.t_us, UtmFlightState.AIRBORNE)
    assert (r.next_lat_deg, r.next_lon_deg, r.next_alt_amsl_m) == pytest.approx((47.399, 8.547, 510.0), abs=1e-7)
    assert r.has_next_waypoint and r.update_rate_hz == pytest.approx(1.0)
    assert (r.h_acc_m, r.v_acc_m) == pytest.approx((0.8, 1.2))
    assert (r.vel_n_m_s, r.vel_e_m_s, r.vel_d_m_s) == pytest.approx((4.0, -1.5, -0.75))
    # relayed by the simulator (TrafficReport -> UTM_GLOBAL_POSITION), it reads back the same
    (again,) = Decoder().decode(Encoder(1, MAV_COMP_ID_ADSB).traffic(r))
    assert again == r


def test_an_own_report_without_intent_or_accuracy_says_unknown() -> None:
    bare = replace(OWN, next_lat_deg=math.nan, h_acc_m=math.nan, v_acc_m=math.nan, update_rate_hz=math.nan)
    (msg,) = _parse(Encoder(2, 1).own_position(bare))
    assert not msg.flags & mavlink2.UTM_DATA_AVAIL_FLAGS_NEXT_WAYPOINT_AVAILABLE
    assert (msg.h_acc, msg.v_acc, msg.update_rate) == (0xFFFF, 0xFFFF, 0)
    (r,) = Decoder().decode(Encoder(2, 1).own_position(bare))
    assert not r.has_next_waypoint and math.isnan(r.h_acc_m) and math.isnan(r.update_rate_hz)


def _utm(**fields: object) -> bytes:
    mav = mavlink2.MAVLink(None, srcSystem=3, srcComponent=1)
    base = dict(
        time=1, uas_id=list(uas_id_bytes(3)), lat=473977000, lon=85456000, alt=500000, relative_alt=0, vx=0, vy=0,
        vz=0, h_acc=0, v_acc=0, vel_acc=0, next_lat=0, next_lon=0, next_alt=0, update_rate=0, flight_state=3,
        flags=UTM_FLAGS_SIM,
    )  # fmt: skip
    base.update(fields)
    return mavlink2.MAVLink_utm_global_position_message(**base).pack(mav)


@pytest.mark.parametrize(
    ("fields", "why"),
    [
        ({"flags": 0}, "not flagged available"),
        ({"lat": 95 * 10**7}, "out of range"),
        ({"lon": -181 * 10**7}, "out of range"),
    ],
)
def test_malformed_utm_reports_are_dropped_with_a_reason(fields: dict, why: str) -> None:
    data = _utm(**fields)
    decoder = Decoder()
    assert decoder.decode(data) == [] and decoder.stats.ignored == 1
    problem = utm_problem(data[10:] + bytes(64), 0)  # the payload, zero-padded as the decoder pads it
    assert problem is not None and why in problem and "\n" not in problem


def test_a_bad_next_waypoint_is_dropped_alone_and_unknown_states_read_unknown() -> None:
    flags = UTM_FLAGS_SIM | mavlink2.UTM_DATA_AVAIL_FLAGS_NEXT_WAYPOINT_AVAILABLE
    (r,) = Decoder().decode(_utm(flags=flags, next_lat=99 * 10**7, flight_state=77))
    assert not r.has_next_waypoint and r.flight_state is UtmFlightState.UNKNOWN
    assert r.lat_deg == pytest.approx(47.3977)


def test_truncated_or_garbled_utm_bytes_never_raise() -> None:
    data = _utm()
    decoder = Decoder()
    for cut in range(len(data)):
        decoder.decode(data[:cut])
    assert decoder.decode(bytes(b ^ 0x5A for b in data)) == []
