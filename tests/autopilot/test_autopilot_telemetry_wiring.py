"""What the runner hands its telemetry listener: uploads, battery, planner output, texts without a frame; CLI wiring."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from autopilot_fakes import command
from autopilot_loop import SimLoop

from autopilot import launcher
from autopilot.geofence.fence import circle_fence_items
from autopilot.io_loop import Links, run_loop
from autopilot.launch_commands import commands
from autopilot.launch_plan import plan_launch
from autopilot.runner import Autopilot, AutopilotConfig
from autopilot.telemetry import entities as ent
from autopilot.telemetry import make_listener
from autopilot.telemetry.recording_reader import read_recording
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.vehicle_api import CommandResult, MissionItem, MissionResult, MissionType, Severity
from sim.world import load_world

COLUMN = {"cylinder": {"north_m": 25, "east_m": 1.0, "radius_m": 3, "height_m": 30}}


def _wp(seq: int, cmd: int, frame: LocalNedFrame, n: float, e: float, alt: float) -> MissionItem:
    g = frame.geodetic_from_ned(n, e, 0.0)
    return MissionItem(seq, cmd, 6, 0.0, 0.0, 0.0, math.nan, g.lat_deg, g.lon_deg, alt)


def test_avoidance_flight_recording_has_route_fence_detour_obstacles_battery_and_decisions(tmp_path: Path) -> None:
    rrd = tmp_path / "flight.rrd"
    loop = SimLoop("x500", world=load_world({"obstacles": [COLUMN]}))
    loop.ap.listener = make_listener(f"save:{rrd}", vehicle="x500", safety_radius_m=loop.ap.params.get("CA_RSAFE_M"))
    assert loop.vehicle.param_set("CA_RSAFE_M", 2.5)[0]
    assert loop.ap.listener.safety_radius_m == 2.5  # type: ignore[union-attr]  # drawn spheres follow R_safe
    loop.run_s(0.5)
    f = loop.ap.estimator.local_frame
    assert f is not None
    mission = [_wp(0, 22, f, 0.0, 0.0, 10.0), _wp(1, 16, f, 50.0, 0.0, 10.0), _wp(2, 21, f, 50.0, 0.0, 0.0)]
    home = f.home
    g = f.geodetic_from_ned(0.0, -40.0, 0.0)
    fence = circle_fence_items(0, g.lat_deg, g.lon_deg, 5.0, inclusion=False)
    assert loop.vehicle.replace_mission(MissionType.MISSION, mission)[0] is MissionResult.ACCEPTED
    assert loop.vehicle.replace_mission(MissionType.FENCE, fence)[0] is MissionResult.ACCEPTED
    assert home is not None
    assert loop.vehicle.handle_command(command(400, 1.0)) is CommandResult.ACCEPTED
    assert loop.vehicle.handle_command(command(300, 0, 0)) is CommandResult.ACCEPTED
    assert loop.run_until(lambda: 1 in loop.ap.progress.reached_seqs, 60.0), loop.texts
    loop.ap.listener.close()  # type: ignore[union-attr]

    r = read_recording(rrd)
    entities = set(r.entities)
    for path in (ent.ROUTE, ent.FENCE, ent.DETOUR, ent.OBSTACLES_SENSED, ent.OBSTACLES_SAFETY):
        assert path in entities, (path, sorted(entities))
    assert ent.OBSTACLES_TRUE not in entities  # nothing but detections reach the recording without --rerun-world
    route = r.static_component(ent.ROUTE, "Points3D:positions")
    assert len(route) >= 2
    battery = r.scalars(ent.BATTERY_REMAINING).values[:, 0]
    assert np.all(np.isfinite(battery)) and battery[0] == 100.0 and battery[-1] < 100.0
    assert np.all(np.isfinite(r.scalars(ent.BATTERY_VOLTAGE).values))
    log = [text for _, _, text in r.text_log()]
    assert any(text.startswith("avoid: obstacle") for text in log), log
    assert any("Geofence: 1 items" in text for text in log)


class _Recorder:
    """A listener that keeps what it is told."""

    def __init__(self) -> None:
        self.steps: list[object] = []
        self.events: list[tuple[str, Severity, int | None]] = []
        self.missions: list[int] = []
        self.fences: list[int] = []

    def on_step(self, record: object) -> None:
        self.steps.append(record)

    def on_event(self, text: str, severity: Severity = Severity.INFO, time_us: int | None = None) -> None:
        self.events.append((text, severity, time_us))

    def on_mission(self, items, home) -> None:  # type: ignore[no-untyped-def]
        self.missions.append(len(items))

    def on_fence(self, zones) -> None:  # type: ignore[no-untyped-def]
        self.fences.append(len(zones))


class _SilentSim:
    """A lockstep client whose simulator is paused: connected, never a frame, never lost."""

    connected = True
    sim_lost = False

    def next_frame(self, timeout_s: float) -> None:
        return None

    def answer(self, command: object) -> None:
        raise AssertionError("no frame, no answer")


def test_texts_reach_the_listener_even_when_no_frame_arrives() -> None:
    recorder = _Recorder()
    ap = Autopilot(AutopilotConfig(vehicle="x500", avoidance=False), listener=recorder)
    assert ap.handle_command(command(400, 1.0)) is CommandResult.TEMPORARILY_REJECTED  # says why, between frames
    calls = iter(range(3))
    run_loop(ap, Links(_SilentSim()), lambda: next(calls, None) is None)
    assert recorder.steps == []
    assert [e[0] for e in recorder.events] == ["Arming denied: no vehicle state yet"]
    assert recorder.events[0][1] is Severity.WARNING


def test_uploads_are_handed_to_the_listener() -> None:
    recorder = _Recorder()
    loop = SimLoop("x500", listener=recorder)
    loop.run_s(0.3)
    f = loop.ap.estimator.local_frame
    assert f is not None
    g = f.geodetic_from_ned(30.0, 0.0, 0.0)
    fence = circle_fence_items(0, g.lat_deg, g.lon_deg, 5.0, inclusion=False)
    assert loop.vehicle.replace_mission(MissionType.FENCE, fence)[0] is MissionResult.ACCEPTED
    assert (
        loop.vehicle.replace_mission(MissionType.MISSION, [_wp(0, 22, f, 0.0, 0.0, 5.0)])[0] is MissionResult.ACCEPTED
    )
    bad = [MissionItem(0, 16, 6, x_lat_deg=123.0, y_lon_deg=8.0, z_alt_m=5.0)]
    assert loop.vehicle.replace_mission(MissionType.MISSION, bad)[0] is not MissionResult.ACCEPTED
    assert recorder.fences == [1] and recorder.missions == [1]  # refused uploads are not drawn
    assert all(math.isfinite(s.battery_voltage_v) for s in recorder.steps)  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("argv", "expect"),
    [
        (["--world", "missions/x.yaml", "--rerun", "save:a.rrd"], ["--rerun-world", "missions/x.yaml"]),
        (
            ["--world", "m.yaml", "--rerun-world", "other.yaml", "--rerun", "save:a.rrd"],
            ["--rerun-world", "other.yaml"],
        ),
        (["--signing-key", "secret", "--require-signing"], ["--signing-key", "secret", "--require-signing"]),
    ],
)
def test_up_passes_the_world_to_the_recording_and_signing_to_the_autopilot(argv: list[str], expect: list[str]) -> None:
    _sim, ap = _up_commands(argv)
    i = ap.index(expect[0])
    assert ap[i : i + len(expect)] == expect


def test_up_without_a_recording_draws_no_world() -> None:
    _sim, ap = _up_commands(["--world", "m.yaml"])
    assert "--rerun-world" not in ap


def test_up_gives_both_processes_the_same_lockstep_spin() -> None:
    sim, ap = _up_commands(["--lockstep-spin-us", "0"])
    for argv in (sim, ap):
        assert float(argv[argv.index("--lockstep-spin-us") + 1]) == 0.0
    with pytest.raises(SystemExit):
        launcher.build_parser().parse_args(["--lockstep-spin-us", "-1"])


def _up_commands(argv: list[str]) -> tuple[list[str], list[str]]:
    """``quadsitl up``'s simulator and (one) autopilot command lines for ``argv``."""
    args = launcher.build_parser().parse_args(argv)
    sim, [ap] = commands(args, plan_launch(args))
    return sim, ap
