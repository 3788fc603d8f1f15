"""Traffic reports on the wire (SPEC §13): what a MAVLink tool reads from the simulator's receiver, and back."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.traffic import AdsbEmitterType, TrafficReport, TrafficSource
from mavlink_bridge.wire.codec import Decoder, Encoder, Heartbeat
from mavlink_bridge.wire.traffic_codec import MAV_COMP_ID_ADSB, MAV_TYPE_ADSB

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
