"""Failsafes: edge-triggered events with the parameter's action, geofence geometry, battery model."""

from __future__ import annotations

import pytest
from autopilot_fakes import FRAME

from autopilot.geofence.fence import geofence_from_items
from autopilot.parameters.nav_decls import nav_param_specs
from autopilot.parameters.store import ParamStore
from autopilot.safety.failsafe import (
    BatteryModel,
    FailsafeAction,
    FailsafeInputs,
    FailsafeKind,
    FailsafeMonitor,
)
from mavlink_bridge.contract.vehicle_api import MissionItem, MissionType


def _inputs(**kw: object) -> FailsafeInputs:
    base = {
        "armed": True,
        "in_air": True,
        "gcs_heartbeat_age_s": 0.5,
        "offboard_setpoint_age_s": None,
        "battery_remaining": 0.9,
        "pos_ned_m": (0.0, 0.0, -10.0),
        "home_ned_m": (0.0, 0.0, 0.0),
    }
    base.update(kw)
    return FailsafeInputs(**base)  # type: ignore[arg-type]


def _fence_item(seq: int, cmd: int, n: float, e: float, p1: float) -> MissionItem:
    geo = FRAME.geodetic_from_ned(n, e, 0.0)
    return MissionItem(seq, cmd, 5, p1, 0, 0, 0, geo.lat_deg, geo.lon_deg, 0.0, True, MissionType.FENCE)


def test_gcs_loss_triggers_once_with_the_parameter_action_and_clears() -> None:
    params = ParamStore(nav_param_specs())
    params.set("NAV_DLL_ACT", 3)
    mon = FailsafeMonitor(params)
    assert mon.update(_inputs()) == []
    events = mon.update(_inputs(gcs_heartbeat_age_s=11.0))
    assert [(e.kind, e.action) for e in events] == [(FailsafeKind.GCS_LOSS, FailsafeAction.RTL)]
    assert "no GCS heartbeat" in events[0].message
    assert mon.update(_inputs(gcs_heartbeat_age_s=12.0)) == []  # edge-triggered
    assert mon.update(_inputs(gcs_heartbeat_age_s=0.1)) == [] and not mon.active
    assert mon.update(_inputs(gcs_heartbeat_age_s=None)) == []  # no GCS ever heard: no loss


def test_nothing_triggers_on_the_ground() -> None:
    mon = FailsafeMonitor(ParamStore(nav_param_specs()))
    assert mon.update(_inputs(in_air=False, battery_remaining=0.01, gcs_heartbeat_age_s=99.0)) == []


def test_battery_low_warns_and_critical_takes_the_action() -> None:
    params = ParamStore(nav_param_specs())
    mon = FailsafeMonitor(params)
    (low,) = mon.update(_inputs(battery_remaining=0.12))
    assert low.kind is FailsafeKind.BATTERY_LOW and low.action is FailsafeAction.WARN
    (crit,) = mon.update(_inputs(battery_remaining=0.05))
    assert crit.kind is FailsafeKind.BATTERY_CRITICAL
    assert crit.action is FailsafeAction(round(params.get("COM_LOW_BAT_ACT")))


def test_geofence_breach_and_max_height_take_gf_action() -> None:
    items = [
        _fence_item(0, 5003, 0.0, 0.0, 100.0),  # inclusion circle r=100 about home
        _fence_item(1, 5004, 50.0, 0.0, 10.0),  # exclusion circle
        _fence_item(2, 5002, -40.0, -10.0, 4),  # exclusion square
        _fence_item(3, 5002, -40.0, 10.0, 4),
        _fence_item(4, 5002, -60.0, 10.0, 4),
        _fence_item(5, 5002, -60.0, -10.0, 4),
    ]
    fence = geofence_from_items(items, FRAME.home)
    params = ParamStore(nav_param_specs())
    params.set("GF_ACTION", 4)
    params.set("GF_MAX_VER_DIST", 50.0)
    mon = FailsafeMonitor(params)
    assert mon.update(_inputs(pos_ned_m=(-50.0, 15.0, -10.0), geofence=fence)) == []
    (event,) = mon.update(_inputs(pos_ned_m=(55.0, 0.0, -10.0), geofence=fence))
    assert event.kind is FailsafeKind.GEOFENCE and event.action is FailsafeAction.LAND
    assert mon.update(_inputs(pos_ned_m=(0.0, 0.0, -10.0), geofence=fence)) == []
    breach = mon.update(_inputs(pos_ned_m=(-50.0, 0.0, -10.0), geofence=fence))
    assert [e.kind for e in breach] == [FailsafeKind.GEOFENCE]
    assert mon.update(_inputs(pos_ned_m=(0.0, 0.0, -10.0), geofence=fence)) == []
    breach = mon.update(_inputs(pos_ned_m=(0.0, 120.0, -10.0), geofence=fence))
    assert [e.kind for e in breach] == [FailsafeKind.GEOFENCE]
    mon2 = FailsafeMonitor(params)
    (event,) = mon2.update(_inputs(pos_ned_m=(0.0, 0.0, -60.0)))
    assert "above home" in event.message


def test_battery_model_drains_with_thrust() -> None:
    bat = BatteryModel(hover_endurance_s=100.0)
    for _ in range(250 * 10):
        bat.update(1.0, 0.004)
    assert bat.remaining == pytest.approx(0.9, abs=1e-9)
    idle = BatteryModel(100.0)
    idle.update(0.0, 10.0)
    assert idle.remaining == 1.0 and idle.voltage_v == pytest.approx(16.8)
    assert bat.voltage_v < 16.8
