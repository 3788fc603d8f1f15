"""A fleet recording opens with the fleet's layout and draws each vehicle's separation volume (no SITL).

The simulator's world part carries the one blueprint (the autopilots' parts none), under the fleet's application id;
every per-vehicle panel of that layout names a path an autopilot of the fleet writes. Each autopilot draws its own
NAV_TRAFF_U_HOR x NAV_TRAFF_U_VER cylinder under ``vehicles/<name>/separation_volume``, red while in conflict.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from rerun.chunk import RrdReader

from autopilot.telemetry import make_listener
from autopilot.telemetry.recording_reader import RecordingReadError, read_layout, read_recording
from autopilot.telemetry.separation_volume import COLOR_CLEAR, COLOR_CONFLICT
from autopilot.telemetry.sinks import FLEET_APPLICATION_ID
from autopilot.traffic.param_decls import SeparationVolume
from mavlink_bridge.contract.traffic import AdsbEmitterType
from sim.fleet_world import ScriptedAircraft, TrafficWaypoint
from sim.traffic import ScriptedTraffic
from sim.world_layout import FLEET_APPLICATION_ID as SIM_FLEET_APPLICATION_ID
from sim.world_layout import FLEET_PANELS, VEHICLE_PANELS, framing
from sim.world_recording import WorldRecorder
from tools.benchmarks.telemetry import synthetic_records

NAMES = ["alpha", "bravo", "charlie"]
N_STEPS = 1000  # 4 s at 250 Hz
CONFLICT_FROM, CONFLICT_TO = 400, 600  # steps with a traffic conflict


def _rgba(packed: int) -> tuple[int, int, int, int]:
    return ((packed >> 24) & 255, (packed >> 16) & 255, (packed >> 8) & 255, packed & 255)


def _rgba_of(color: tuple[int, ...]) -> tuple[int, int, int, int]:
    return (*color[:3], color[3] if len(color) > 3 else 255)  # type: ignore[return-value]


@pytest.fixture(scope="module")
def world_rrd(tmp_path_factory: pytest.TempPathFactory) -> Path:
    heli = ScriptedAircraft(
        "HELI1",
        0xA1B2C3,
        AdsbEmitterType(7),
        (TrafficWaypoint(-300.0, 60.0, 40.0), TrafficWaypoint(300.0, 60.0, 40.0)),
        40.0,
        0.0,
    )
    path = tmp_path_factory.mktemp("fleet") / "flight_world.rrd"
    recorder = WorldRecorder(NAMES, ScriptedTraffic((heli,)), path, "fleet-id")
    for t_us in range(0, 4_000_000, 50_000):
        recorder.sample(t_us, np.array([[0.0, 0.0, -5.0], [0.0, 8.0, -5.0], [-5.0, 40.0, -10.0]]))
    return recorder.write()


@pytest.fixture(scope="module")
def alpha_rrd(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Autopilot ``alpha`` of the fleet, with NAV_TRAFF_U_HOR 12 m / U_VER 4 m and a conflict in the middle."""
    path = tmp_path_factory.mktemp("fleet") / "flight_alpha.rrd"
    telemetry = make_listener(f"save:{path}", fleet_name="alpha", recording_id="fleet-id", rate_3d_hz=25.0)
    assert telemetry is not None
    conflict = SimpleNamespace(conflicts=("HELI1",))
    clear = SimpleNamespace(conflicts=())
    for k, record in enumerate(synthetic_records(N_STEPS, with_planner=False)):
        decision = conflict if CONFLICT_FROM <= k < CONFLICT_TO else clear
        volume = SeparationVolume(12.0, 4.0)
        telemetry.on_step(dataclasses.replace(record, traffic_decision=decision, uav_separation=volume))
    telemetry.close()
    return path


def test_the_world_part_carries_the_fleet_layout_under_the_fleets_application_id(world_rrd: Path) -> None:
    layout = read_layout(world_rrd)
    assert layout.application_id == FLEET_APPLICATION_ID == SIM_FLEET_APPLICATION_ID
    assert read_recording(world_rrd).application_id == FLEET_APPLICATION_ID
    assert set(layout.containers) == {"fleet", *NAMES}  # tabs: the fleet, then one per vehicle
    world = layout.view("fleet world (NED)")
    assert (world.origin, world.kind) == ("/", "3D")
    assert "- /plots/**" in world.contents and "+ /**" in world.contents
    assert {f"- /vehicles/{n}/home/ticks/**" for n in NAMES} <= set(world.contents)  # no overlaid per-vehicle grids
    sep = layout.view("separation per pair: horizontal, vertical (m)")
    assert (sep.origin, sep.kind) == ("/separation", "TimeSeries")
    for name in NAMES:
        mine = sorted(v.origin for v in layout.views if v.origin.startswith(f"/plots/{name}/"))
        assert mine == sorted(f"/plots/{name}/{path}" for path, _ in VEHICLE_PANELS)
    for _, title in FLEET_PANELS:
        view = layout.view(title)
        assert len(view.contents) == len(NAMES)  # every vehicle's series in one plot
    events = layout.view("events, every vehicle")
    assert events.kind == "TextLog" and events.contents == tuple(f"+ /plots/{n}/log" for n in NAMES)


def test_the_3d_views_are_framed_on_where_the_vehicles_flew() -> None:
    centre, span = framing(np.array([[0.0, 0.0, -5.0], [0.0, 100.0, -15.0]]))
    assert centre == (0.0, 50.0, -10.0) and span == pytest.approx(130.0)
    assert framing(np.zeros((0, 3))) == ((0.0, 0.0, -10.0), 60.0)


def test_an_autopilot_part_has_no_layout_and_writes_every_path_the_layout_plots(alpha_rrd: Path) -> None:
    assert len(RrdReader(alpha_rrd).blueprints()) == 0  # the world part's layout is the only one
    with pytest.raises(RecordingReadError, match="0 blueprints"):
        read_layout(alpha_rrd)
    rec = read_recording(alpha_rrd)
    assert rec.application_id == FLEET_APPLICATION_ID
    for path, _ in (*VEHICLE_PANELS, *FLEET_PANELS):
        assert any(e == f"plots/alpha/{path}" or e.startswith(f"plots/alpha/{path}/") for e in rec.entities), path
    assert "plots/alpha/log" in rec.entities


def test_each_vehicle_draws_its_own_separation_volume_sized_by_its_params_red_in_conflict(alpha_rrd: Path) -> None:
    rec = read_recording(alpha_rrd)
    entity = "vehicles/alpha/separation_volume"
    radii, lengths, colors = (rec.rows(entity, f"Cylinders3D:{c}") for c in ("radii", "lengths", "colors"))
    assert [r for _, r in radii] == [[12.0]] * 3  # clear, conflict, clear: logged on change only
    assert [r for _, r in lengths] == [[8.0]] * 3  # twice NAV_TRAFF_U_VER
    assert [_rgba(c[0]) for _, c in colors] == [_rgba_of(COLOR_CLEAR), _rgba_of(COLOR_CONFLICT), _rgba_of(COLOR_CLEAR)]
    t_conflict, t_clear = (1_000_000 + k * 4_000 for k in (CONFLICT_FROM, CONFLICT_TO))
    assert colors[1][0] == pytest.approx(t_conflict, abs=40_000)  # at the first 3D sample of the conflict
    assert colors[2][0] == pytest.approx(t_clear, abs=40_000)
    centre = rec.translations(entity)
    pose = rec.translations("vehicles/alpha/vehicle")
    np.testing.assert_array_equal(centre.t_us, pose.t_us)  # follows the vehicle at the 3D rate
    np.testing.assert_allclose(centre.values, pose.values)
    assert "Transform3D:quaternion" not in rec.components(entity)  # upright: the attitude is not applied
