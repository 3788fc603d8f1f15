"""Fleet worlds (SPEC §13): schema, one lockstep time for every vehicle, contacts, sensing, lost autopilots and
the simulated traffic receiver, over loopback with scripted autopilots (lockstep clients in threads)."""

from __future__ import annotations

import itertools
import math
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from mavlink_bridge.contract.traffic import (
    AdsbEmitterType,
    OwnPositionReport,
    TrafficReport,
    TrafficSource,
    UtmFlightState,
)
from mavlink_bridge.contract.wire import ActuatorCommand
from mavlink_bridge.lockstep import LockstepClient, LockstepFrame
from mavlink_bridge.lockstep.answer_kernel import A_ARMED, A_MOTORS
from sim.end_reason import EndReason
from sim.fleet import FleetSim, vehicle_seed
from sim.fleet_run import FleetRun, fleet_airframes
from sim.fleet_world import load_fleet
from sim.server import SimConfig, SimServer
from sim.summary_file import FleetSummary
from sim.vehicle_config import load_vehicle
from sim.world import WorldConfigError, load_world

FLEET_YAML = """\
name: pair
home: {lat_deg: 47.3977, lon_deg: 8.5456, alt_m: 488}
vehicles:
  - name: alpha
    home: {north_m: 0, east_m: 0}
    mission: [{takeoff: {alt_m: 10}}]
  - name: bravo
    vehicle: x500
    home: {north_m: 0, east_m: 8}
traffic:
  - callsign: HELI1
    icao: 0xA1B2C3
    emitter: rotorcraft
    path: [{north_m: -100, east_m: 60, alt_m: 40}, {north_m: 1500, east_m: 60, alt_m: 40}]
    speed_m_s: 40
    start_s: 0
  - callsign: FAR1
    icao: 0x00BEEF
    emitter: light
    path: [{north_m: 30000, east_m: 0, alt_m: 300}, {north_m: 30000, east_m: 9000, alt_m: 300}]
    speed_m_s: 50
"""


def _write(tmp_path: Path, text: str, name: str = "fleet.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# ---- schema ---------------------------------------------------------------------------------------------
def test_fleet_keys_parse_about_the_worlds_home(tmp_path: Path) -> None:
    fleet = load_fleet(_write(tmp_path, FLEET_YAML))
    assert [(v.name, v.sys_id, v.home_east_m) for v in fleet.vehicles] == [("alpha", 1, 0.0), ("bravo", 2, 8.0)]
    assert fleet.vehicles[0].mission == ({"takeoff": {"alt_m": 10}},)
    heli = fleet.traffic[0]
    assert (heli.callsign, heli.icao, heli.speed_m_s) == ("HELI1", 0xA1B2C3, 40)
    assert heli.emitter is AdsbEmitterType.ROTOCRAFT
    assert load_world(_write(tmp_path, FLEET_YAML)).home.alt_amsl_m == 488  # the world part is unchanged


def test_a_file_without_fleet_keys_is_one_vehicle(tmp_path: Path) -> None:
    fleet = load_fleet(Path("missions/delivery.yaml"))
    assert not fleet.is_fleet and fleet.traffic == ()


@pytest.mark.parametrize(
    ("old", "new", "line", "words"),
    [
        ("east_m: 8}", "lat_deg: 47.4}", 9, "vehicles[1].home: give either"),
        ("north_m: 0, east_m: 8}", "north_m: zero, east_m: 8}", 9, "vehicles[1].home.north_m: expected a finite"),
        ("    home: {north_m: 0, east_m: 8}", "    hme: {north_m: 0, east_m: 8}", 7, "vehicles[1]: missing"),
        ("icao: 0xA1B2C3", "icao: 0x1000000", 12, "traffic[0].icao: expected a 24-bit"),
        ("emitter: rotorcraft", "emitter: rotorcrafts", 13, "traffic[0].emitter: unknown ADS-B emitter"),
    ],
)
def test_fleet_errors_name_file_line_and_field(tmp_path: Path, old: str, new: str, line: int, words: str) -> None:
    path = _write(tmp_path, FLEET_YAML.replace(old, new, 1))
    with pytest.raises(WorldConfigError) as err:
        load_fleet(path)
    assert str(err.value).startswith(f"{path}:{line}: {words}"), str(err.value)


def test_duplicate_names_and_vehicles_in_contact_are_refused(tmp_path: Path) -> None:
    with pytest.raises(WorldConfigError, match="used twice"):
        load_fleet(_write(tmp_path, FLEET_YAML.replace("name: bravo", "name: alpha")))
    path = _write(tmp_path, FLEET_YAML.replace("east_m: 8}", "east_m: 0.5}"))
    with pytest.raises(ValueError, match="starts in contact"):
        _fleet_sim(path)


# ---- physics without sockets -----------------------------------------------------------------------------
def _fleet_sim(path: Path, seed: int = 0) -> FleetSim:
    fleet = load_fleet(path)
    x500 = load_vehicle("x500")
    return FleetSim(load_world(path), fleet, tuple(x500 for _ in fleet.vehicles), seed=seed)


def test_per_vehicle_seeds_do_not_depend_on_the_fleet_size() -> None:
    assert [vehicle_seed(7, i) for i in range(3)] == [vehicle_seed(7, i) for i in range(5)][:3]
    assert len({vehicle_seed(7, i) for i in range(5)}) == 5


def test_contact_between_two_vehicles_is_a_collision_for_both(tmp_path: Path) -> None:
    sim = _fleet_sim(_write(tmp_path, FLEET_YAML))
    batch = sim.batches[0]
    batch.state[:, 2] = -5.0  # both in the air, bravo drifts into alpha
    batch.state[1, 1] = 0.8
    batch.state[1, 4] = -3.0
    for _ in range(50):
        sim.step()
    assert sim.end_reason.tolist() == [EndReason.COLLISION, EndReason.COLLISION]
    assert sim.contacts_of(0) == [1] and sim.contacts_of(1) == [0]


def test_volume_separation_counts_airborne_pairs_in_the_volumes_measure(tmp_path: Path) -> None:
    """``min_volume_sep_m`` = max(horizontal, 2 x vertical) between centres while both fly: parked is not
    counted, 6 m beside and 4 m above is inside the 10 m / 5 m volume (8 m), 6 m beside and 6 m above is not."""
    sim = _fleet_sim(_write(tmp_path, FLEET_YAML.replace("east_m: 8}", "east_m: 6}")))
    sim.step()  # both on their pads, 6 m apart: parked traffic
    assert np.isinf(sim.min_volume_sep_m).all() and sim.min_separation_m[0] < 6.0
    batch = sim.batches[0]
    batch.state[:, 2] = (-20.0, -26.0)  # 6 m beside, 6 m above: outside (12 m in the measure)
    sim.step()
    assert sim.min_volume_sep_m == pytest.approx([12.0, 12.0], abs=0.01)
    batch.state[:, 2] = (-20.0, -24.0)  # 4 m above: inside (8 m)
    sim.step()
    assert sim.min_volume_sep_m == pytest.approx([8.0, 8.0], abs=0.01)


def test_obstacle_sensor_sees_the_other_vehicle(tmp_path: Path) -> None:
    sim = _fleet_sim(_write(tmp_path, FLEET_YAML.replace("east_m: 8}", "east_m: 6}")))
    batch = sim.batches[0]
    batch.state[:, 2] = -5.0
    sim.gather()
    # alpha (yaw 0, looking north) sees nothing; turned east it sees bravo 6 m away (obstacle id = instance 1)
    assert sim.detect(0) == ()
    half = math.sqrt(0.5)
    batch.state[0, 6:10] = (half, 0.0, 0.0, half)  # yaw +90 deg: looking east
    (seen,) = sim.detect(0)
    assert seen.obstacle_id == 1
    assert seen.pos_frd_m[0] == pytest.approx(6.0 - sim.radius_m[1], abs=0.2)  # its near surface


# ---- the lockstep over loopback ---------------------------------------------------------------------------
class ScriptedAutopilot(threading.Thread):
    """A lockstep client answering every frame with fixed motors, until ``stop_after`` frames (then silent); with a
    ``sys_id`` it sends its own UTM report (its truth, as if its estimate) with the answer of every 250th frame from
    frame ``sys_id - 1`` on (1 Hz at 250 Hz)."""

    def __init__(
        self, address: tuple[str, int], motors: float, stop_after: int | None = None, sys_id: int | None = None
    ) -> None:
        super().__init__(daemon=True)
        self.client = LockstepClient(f"udpout:{address[0]}:{address[1]}", heartbeat_period_s=0.02)
        self.motors = motors
        self.stop_after = stop_after
        self.sys_id = sys_id
        self.frames: list[LockstepFrame] = []
        self.traffic: list[TrafficReport] = []
        self.traffic_at_us: list[int] = []  # the frame time each report arrived with
        self.sent: list[OwnPositionReport] = []
        self.hold = threading.Event()
        self.hold.set()
        self.done = threading.Event()

    def run(self) -> None:
        while not self.done.is_set():
            frame = self.client.next_frame(0.05)
            if frame is None:
                continue
            self.hold.wait()
            self.frames.append(frame)
            self.traffic.extend(frame.traffic)
            self.traffic_at_us += [frame.time_us] * len(frame.traffic)
            if self.stop_after is not None and len(self.frames) >= self.stop_after:
                break
            m = self.motors
            own = None
            if self.sys_id is not None and len(self.frames) % 250 == self.sys_id - 1:
                t = frame.truth
                own = OwnPositionReport(frame.time_us, self.sys_id, t.lat_deg, t.lon_deg, t.alt_amsl_m,
                                        *t.vel_ned_m_s, UtmFlightState.GROUND, 1.0)  # fmt: skip
                self.sent.append(own)
            self.client.answer(ActuatorCommand(frame.sensor.time_us, (m, m, m, m), m > 0.0, False), own)
        self.client.close()


def _run_fleet(path: Path, autopilots: list[dict], duration_s: float, **config: object) -> tuple[FleetSummary, list]:
    server = SimServer(
        SimConfig(
            listen_url="udpin:127.0.0.1:0",
            world_path=path,
            duration_s=duration_s,
            **{"start_timeout_s": 20.0, "autopilot_timeout_s": 10.0, **config},  # type: ignore[arg-type]
        )
    )
    pilots = [
        ScriptedAutopilot(addr, **{"sys_id": i + 1, **kw})
        for i, (addr, kw) in enumerate(zip(server.local_addresses, autopilots, strict=True))
    ]
    for p in pilots:
        p.start()
    try:
        summary = server.run()
    finally:
        for p in pilots:
            p.done.set()
            p.join(5.0)
    return summary, pilots


def test_time_advances_only_when_every_autopilot_answered(tmp_path: Path) -> None:
    path = _write(tmp_path, FLEET_YAML)
    server = SimServer(SimConfig(listen_url="udpin:127.0.0.1:0", world_path=path, duration_s=0.2))
    alpha, bravo = (ScriptedAutopilot(a, 0.0) for a in server.local_addresses)
    bravo.hold.clear()  # bravo computes slowly
    for p in (alpha, bravo):
        p.start()
    runner = threading.Thread(target=lambda: result.append(server.run()), daemon=True)
    result: list[FleetSummary] = []
    runner.start()
    deadline = time.monotonic() + 120.0  # the first frame: compiled kernels load (or compile) first
    while not alpha.frames and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.3)
    assert len(alpha.frames) == 1 and len(bravo.frames) == 0  # alpha answered frame 0; time waits for bravo
    bravo.hold.set()
    runner.join(20.0)
    for p in (alpha, bravo):
        p.done.set()
    assert result[0].end_reason == "COMPLETED" and result[0].frames == 50
    assert [v.frames for v in result[0].vehicles] == [50, 50]
    assert [f.sensor.time_us for f in alpha.frames] == [f.sensor.time_us for f in bravo.frames]


def test_same_world_and_seed_give_the_same_per_vehicle_hashes(tmp_path: Path) -> None:
    gusty = FLEET_YAML + "world: {wind: {gust_m_s: 2.0}}\n"
    path = _write(tmp_path, gusty)
    pilots = [{"motors": 0.75}, {"motors": 0.72}]  # both lift off into the gusts
    runs = [_run_fleet(path, pilots, 1.0, seed=3)[0] for _ in range(2)]
    hashes = [[v.truth_sha256 for v in run.vehicles] for run in runs]
    assert hashes[0] == hashes[1] and hashes[0][0] != hashes[0][1]
    lossy = _run_fleet(path, pilots, 1.0, seed=3, loss_fraction=0.1)[0]  # each link re-sends on its own
    assert [v.truth_sha256 for v in lossy.vehicles] == hashes[0] and min(v.resends for v in lossy.vehicles) > 0
    other_seed = _run_fleet(path, pilots, 1.0, seed=4)[0]
    assert other_seed.vehicles[0].truth_sha256 != hashes[0][0]
    # a third vehicle shifts neither stream of the first two
    third = gusty.replace("traffic:", "  - name: charlie\n    home: {north_m: 20, east_m: 0}\ntraffic:")
    bigger = _run_fleet(_write(tmp_path, third, "three.yaml"), [*pilots, {"motors": 0.7}], 1.0, seed=3)[0]
    assert [v.truth_sha256 for v in bigger.vehicles][:2] == hashes[0]


def test_the_socket_free_run_flies_the_servers_bits(tmp_path: Path) -> None:
    """``FleetRun`` stepped directly (the in-process campaign flight's way) gives the per-vehicle truth hashes the
    UDP server gives with the same answers: one implementation of a fleet step, two transports."""
    path = _write(tmp_path, FLEET_YAML + "world: {wind: {gust_m_s: 2.0}}\n")
    pilots = [{"motors": 0.75}, {"motors": 0.72}]
    over_udp = _run_fleet(path, pilots, 1.0, seed=3)[0]
    world, fleet = load_world(path), load_fleet(path)
    run = FleetRun(world, fleet, fleet_airframes(fleet, "x500"), seed=3)
    answers = [np.zeros(16) for _ in pilots]
    for answer, pilot in zip(answers, pilots, strict=True):
        answer[A_MOTORS : A_MOTORS + 4], answer[A_ARMED] = np.float32(pilot["motors"]), 1.0
    alive = np.ones(run.n, dtype=bool)
    while run.sim.t_s < 1.0 - 1e-9:
        assert [i for i, _ in run.frames(alive)] == [0, 1]
        for i, answer in enumerate(answers):
            run.apply(i, answer)
        run.advance()
        run.sim.record()
    assert [h.hexdigest() for h in run.sim.hashes] == [v.truth_sha256 for v in over_udp.vehicles]


def test_a_dead_autopilot_loses_its_vehicle_and_the_others_keep_flying(tmp_path: Path) -> None:
    path = _write(tmp_path, FLEET_YAML)
    summary, _ = _run_fleet(path, [{"motors": 0.8}, {"motors": 0.8, "stop_after": 250}], 4.0, autopilot_timeout_s=2.0)
    alpha, bravo = summary.vehicles
    assert summary.end_reason == "COMPLETED" and summary.sim_time_s == pytest.approx(4.0)
    assert alpha.autopilot_lost_at_s is None and alpha.frames == 1000 and alpha.final_pos_ned_m[2] < -5.0
    assert bravo.autopilot_lost_at_s == pytest.approx(1.0, abs=0.01)
    assert bravo.end_reason in ("GROUND_IMPACT", "AUTOPILOT_LOST")  # motors stopped in the air: it fell
    assert bravo.final_pos_ned_m[2] > -0.5


def test_receiver_relays_the_other_vehicles_own_reports_a_latency_later(tmp_path: Path) -> None:
    """Another vehicle is reported only as its autopilot reported itself, ``utm_latency_s`` after it sent it; manned
    traffic at 1 Hz (reception 1 here)."""
    path = _write(tmp_path, FLEET_YAML)
    link = (("adsb_reception", 1.0), ("adsb_latency_s", 0.0), ("utm_latency_s", 0.5))
    summary, (alpha, bravo) = _run_fleet(path, [{"motors": 0.0}, {"motors": 0.0}], 3.0, traffic_link=link)
    for me, other in ((alpha, bravo), (bravo, alpha)):
        uav = [(r, at) for r, at in zip(me.traffic, me.traffic_at_us, strict=True) if r.source is TrafficSource.UAV]
        manned = [r for r in me.traffic if r.source is TrafficSource.MANNED]
        due = [s for s in other.sent if s.t_us + 500_000 < 3_000_000]  # sent at 0, 1, 2 s (bravo), 0.996, 1.996 s
        assert len(due) >= 2 and [r for r, _ in uav] == [_relayed(s) for s in due]  # what it sent, never itself
        assert [at - r.t_us for r, at in uav] == [500_000] * len(due)  # 0.5 s later
        assert len(manned) == 3  # 1 Hz over 3 s; FAR1 (30 km) is out of range
        assert [b.t_us - a.t_us for a, b in itertools.pairwise(manned)] == [1_000_000, 1_000_000]
        heli = manned[-1]
        assert (heli.target_id, heli.callsign, heli.emitter) == (0xA1B2C3, "HELI1", AdsbEmitterType.ROTOCRAFT)
        assert heli.vel_n_m_s == pytest.approx(40.0, abs=8.0) and abs(heli.vel_e_m_s) < 8.0  # NACv 2: < 3 m/s 95 %
        assert me.client.traffic_receiver_t_us >= 2_000_000
    assert summary.vehicles[0].traffic_reports == 6


def _relayed(sent: OwnPositionReport) -> TrafficReport:
    """What a receiver decodes of an own report the simulator relayed (cm/s, degE7, mm on the wire)."""
    return TrafficReport(TrafficSource.UAV, sent.sys_id, "", AdsbEmitterType.UAV, round(sent.lat_deg * 1e7) / 1e7,
                         round(sent.lon_deg * 1e7) / 1e7, round(sent.alt_amsl_m * 1000) / 1000.0,
                         round(sent.vel_n_m_s * 100) / 100, round(sent.vel_e_m_s * 100) / 100,
                         round(sent.vel_d_m_s * 100) / 100, sent.t_us, flight_state=UtmFlightState.GROUND,
                         update_rate_hz=1.0)  # fmt: skip


def test_a_vehicle_whose_autopilot_sends_nothing_is_not_reported(tmp_path: Path) -> None:
    path = _write(tmp_path, FLEET_YAML)
    _, (alpha, _) = _run_fleet(path, [{"motors": 0.0}, {"motors": 0.0, "sys_id": None}], 3.0)
    assert not [r for r in alpha.traffic if r.source is TrafficSource.UAV]


def test_range_limit_drops_far_targets(tmp_path: Path) -> None:
    path = _write(tmp_path, FLEET_YAML)
    link = (("adsb_range_m", 5.0), ("utm_range_m", 5.0))
    _, (alpha, _) = _run_fleet(path, [{"motors": 0.0}, {"motors": 0.0}], 2.0, traffic_link=link)
    assert alpha.traffic == []  # bravo is 8 m away, the helicopter farther
    assert np.isfinite(alpha.frames[-1].truth.lat_deg)


def test_the_flights_are_over_once_every_vehicle_flew_and_is_disarmed_on_the_ground(tmp_path: Path) -> None:
    """``FleetRun.flights_over`` (``sim --end-when-landed``): not before arming, not while armed, not while a
    disarmed vehicle is still in the air; a vehicle that ended (crashed) does not hold the others back."""
    path = _write(tmp_path, FLEET_YAML)
    fleet = load_fleet(path)
    run = FleetRun(load_world(path), fleet, fleet_airframes(fleet, "x500"))
    armed, disarmed = np.zeros(16), np.zeros(16)
    armed[A_ARMED] = 1.0
    assert not run.flights_over()  # nobody armed yet: nothing has flown
    for i in (0, 1):
        run.apply(i, armed)
    assert not run.flights_over()
    run.apply(0, disarmed)
    assert not run.flights_over()  # bravo still armed
    run.apply(1, disarmed)
    assert run.sim.on_ground.all() and run.flights_over()
    run.sim.batches[0].state[1, 2] = -5.0  # bravo disarmed but in the air (falling): not over
    run.sim.gather()
    run.sim.batches[0].on_ground[1] = False
    assert not run.flights_over()
    run.sim.end(EndReason.GROUND_IMPACT, [1])  # it crashed: its flight is over
    assert run.flights_over()
