"""SYS_STATUS health bits GCS clients rely on: pre-arm checks (MAVSDK ``is_armable``) and geofence (MAVProxy)."""

from __future__ import annotations

from autopilot_fakes import set_context
from test_autopilot_runner import Loop

from autopilot.safety.failsafe import FailsafeKind

PREARM_CHECK = 0x10000000
GEOFENCE = 0x100000
GPS = 0x20


def test_prearm_bit_follows_the_arming_checks_and_geofence_bit_follows_breaches() -> None:
    loop = Loop()
    loop.step()
    snap = loop.ap.snapshot()
    assert snap.sensors_present & PREARM_CHECK and snap.sensors_present & GEOFENCE
    assert loop.run_until(lambda: loop.ap.commander.arming_refusal(loop.ap.state) is None, 30.0)
    loop.step()
    snap = loop.ap.snapshot()
    assert snap.sensors_health & PREARM_CHECK and snap.sensors_health & GPS
    assert snap.sensors_health & GEOFENCE
    set_context(loop.ap.commander, failsafe_reasons=frozenset({FailsafeKind.GEOFENCE.value}))
    snap = loop.ap.snapshot()
    assert not snap.sensors_health & GEOFENCE
    assert not snap.sensors_health & PREARM_CHECK  # a failsafe also blocks arming
