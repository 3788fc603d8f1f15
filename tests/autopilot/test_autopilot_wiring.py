"""Runner wiring (in-process closed loop): controller parameters live in flight, payload mass, fences -> planner."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from autopilot_fakes import command
from autopilot_loop import SimLoop

from autopilot.control.airframe import load_airframe
from autopilot.control.param_decls import controller_param_specs, shipped_gains
from autopilot.geofence.fence import circle_fence_items, polygon_fence_items
from autopilot.param_schema import all_param_specs, make_param_store
from autopilot.runner import Autopilot, AutopilotConfig
from mavlink_bridge.contract.vehicle_api import CommandResult, MissionResult, MissionType
from mavlink_bridge.contract.wire import ObstacleDetection, ObstacleShape

Z, ROLL = 2, 3  # CHANNELS order in the diagnostics: x, y, z, roll, pitch, yaw


def test_schema_holds_every_controller_param_and_the_payload_mass() -> None:
    names = {s.name for s in all_param_specs()}
    assert {s.name for s in controller_param_specs()} <= names
    assert "PLD_MASS_KG" in names
    assert make_param_store(payload_nominal_kg=1.0).get("PLD_MASS_KG") == 1.0
    assert load_airframe("delivery650").payload_nominal_kg == 1.0
    assert load_airframe("x500").payload_nominal_kg == 0.0
    assert Autopilot(AutopilotConfig(vehicle="delivery650", avoidance=False)).params.get("PLD_MASS_KG") == 1.0


def test_params_file_sets_gains_and_limits(tmp_path: Path) -> None:
    path = tmp_path / "params.yaml"
    path.write_text("NV_Z_P_K1: 6.5\nNV_ROLL_DLT2: 1.5\nMPC_TILTMAX_DEG: 25\n")
    ap = Autopilot(AutopilotConfig(vehicle="x500", params_file=str(path), avoidance=False))
    assert ap.control.gains.z.k1[0] == 6.5 and ap.control.gains.roll.delta2 == 1.5
    assert ap.control.controller is not None and ap.control.controller.limits.tilt_max_rad == pytest.approx(
        math.radians(25.0)
    )


def test_gain_change_in_flight_shows_in_the_diagnostics_next_step() -> None:
    loop = SimLoop("x500")
    loop.take_off(10.0, settle_s=2.0)
    vehicle, diag = loop.vehicle, loop.ap.control.controller.diagnostics  # type: ignore[union-attr]
    shipped = shipped_gains("x500")  # the defaults: a variable gain, k_p(|e|) between its k1 and k2
    for col, ch in ((Z, shipped.z), (ROLL, shipped.roll)):
        assert min(ch.k1[0], ch.k2[0]) - 1e-9 <= diag.kp[0, col] <= max(ch.k1[0], ch.k2[0]) + 1e-9
    for name, value in (("NV_Z_P_K1", 7.0), ("NV_Z_P_K2", 7.0), ("NV_ROLL_P_K1", 11.0), ("NV_ROLL_P_K2", 11.0)):
        assert vehicle.param_set(name, value) == (True, value, "")
    controller = loop.ap.control.controller
    loop.step()
    assert loop.ap.control.controller is controller  # gains change live: same cascade, integrators kept
    diag = controller.diagnostics  # type: ignore[union-attr]
    assert diag.kp[0, Z] == 7.0 and diag.kp[0, ROLL] == 11.0
    ok, value, reason = vehicle.param_set("NV_Z_P_K1", 1000.0)
    assert not ok and value == 7.0 and "outside" in reason
    ok, _, _ = vehicle.param_set("NV_ROLL_DLT2", -1.0)
    assert not ok and loop.ap.control.gains.roll.delta2 > 0.0
    loop.step()
    assert diag.kp[0, Z] == 7.0
    loop.run_s(2.0)
    assert loop.alt_m == pytest.approx(10.0, abs=0.2)  # still hovering with the new gains


def test_limit_change_in_flight_keeps_the_integrators_no_jump() -> None:
    # delivery650 without its parcel: the controller believes 3.5 kg and flies 2.5 kg, so the altitude
    # integrator holds a large offset that a restarted cascade would lose (a thrust jump).
    loop = SimLoop("delivery650", payload_kg=0.0)
    loop.take_off(10.0, settle_s=6.0)
    before = loop.step().motor_cmd
    alt0 = loop.alt_m
    integrator_sum = float(np.abs(loop.ap.control.controller._work[0, :]).sum())  # type: ignore[union-attr]
    assert integrator_sum > 0.0
    assert loop.vehicle.param_set("MPC_TILTMAX_DEG", 30.0)[0]
    assert loop.ap.control.controller is not None and loop.ap.control.controller.limits.tilt_max_rad == pytest.approx(
        math.radians(30)
    )
    after = loop.step().motor_cmd
    assert max(abs(a - b) for a, b in zip(after, before, strict=True)) < 0.01
    alts: list[float] = []
    loop.run_s(2.0, lambda: alts.append(loop.alt_m))
    assert max(abs(a - alt0) for a in alts) < 0.1


def _release_excursion_m(payload_param_kg: float) -> float:
    loop = SimLoop("delivery650", payload_kg=1.0)
    assert loop.vehicle.param_set("PLD_MASS_KG", payload_param_kg)[0]
    loop.take_off(10.0, settle_s=6.0)
    mass = loop.ap.control.controller.mass_kg[0]  # type: ignore[union-attr]
    assert mass == pytest.approx(3.5)
    assert loop.vehicle.handle_command(command(211, 1.0, 0.0)) is CommandResult.ACCEPTED  # DO_GRIPPER release
    alts: list[float] = []
    loop.run_s(6.0, lambda: alts.append(loop.alt_m))
    assert loop.sim.payload_kg == 0.0
    assert loop.ap.control.controller.mass_kg[0] == pytest.approx(3.5 - payload_param_kg)  # type: ignore[union-attr]
    return max(abs(a - 10.0) for a in alts)


def test_payload_release_excursion_is_smaller_when_the_cascade_is_told_the_mass() -> None:
    told = _release_excursion_m(1.0)  # PLD_MASS_KG = delivery650's payload_nominal_kg
    not_told = _release_excursion_m(0.0)
    assert told < 0.5 * not_told, (told, not_told)


def _fenced_decision(fence_items) -> str:  # type: ignore[no-untyped-def]
    """Upload a FENCE through the vehicle interface, then let the runner's planner meet a column on the route."""
    loop = SimLoop("x500")
    loop.run_s(0.5)
    frame = loop.ap.estimator.local_frame
    assert frame is not None
    items = fence_items(frame)
    assert loop.vehicle.replace_mission(MissionType.FENCE, items) == (MissionResult.ACCEPTED, "")
    planner = loop.ap.navigator.planner
    assert planner is not None
    det = ObstacleDetection(0, 7, (22.0, 1.0, 0.0), 3.0, ObstacleShape.CYLINDER)  # column ahead, slightly right
    texts: list[str] = []
    for k in range(5):
        t_us = 1_000_000 + 40_000 * k
        det_k = ObstacleDetection(t_us, det.obstacle_id, det.pos_frd_m, det.radius_m, det.shape)
        out = planner.update(
            t_us, (0.0, 0.0, -10.0), (5.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), (det_k,), (80.0, 0.0, -10.0)
        )
        texts += [d.text for d in out.decisions]
    assert texts, "the planner saw no threat"
    return texts[0]


def test_no_fence_goes_left_of_a_column_on_the_right() -> None:
    assert "going LEFT" in _fenced_decision(lambda frame: [])


def test_uploaded_exclusion_zone_rules_the_left_detour_out() -> None:
    def items(frame):  # type: ignore[no-untyped-def]
        g = frame.geodetic_from_ned(25.0, -6.5, 0.0)
        return circle_fence_items(0, g.lat_deg, g.lon_deg, 3.0, inclusion=False)

    text = _fenced_decision(items)
    assert "going RIGHT" in text and "left ruled out: fence" in text


def test_uploaded_inclusion_fence_is_never_left_by_a_detour() -> None:
    def items(frame):  # type: ignore[no-untyped-def]
        corners = [(-20.0, -2.5), (-20.0, 40.0), (120.0, 40.0), (120.0, -2.5)]  # west edge 2.5 m left of the route
        geo = [frame.geodetic_from_ned(n, e, 0.0) for n, e in corners]
        return polygon_fence_items(0, [(g.lat_deg, g.lon_deg) for g in geo], inclusion=True)

    text = _fenced_decision(items)
    assert "going RIGHT" in text and "left ruled out: fence" in text
