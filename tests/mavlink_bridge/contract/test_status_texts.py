"""The status-text words both sides parse: what the autopilot writes is what the tools recognise."""

from __future__ import annotations

from mavlink_bridge.contract.status_texts import (
    bypassed_seq,
    bypassed_text,
    failsafe_in,
    failsafe_text,
    first_failsafe,
    is_bypassed,
    is_failsafe,
    is_geofence_breach,
    reached_text,
)


def test_the_texts_are_recognised_by_their_prefixes() -> None:
    breach = failsafe_text("geofence breach", "outside the uploaded geofence")
    assert breach == "Failsafe: geofence breach: outside the uploaded geofence"
    assert is_failsafe(breach) and is_geofence_breach(breach) and not is_bypassed(breach)
    lost = failsafe_text("position lost (no GPS for 2.0 s)", "still dead reckoning")
    assert is_failsafe(lost) and not is_geofence_breach(lost)
    bypass = bypassed_text(4, "it lies inside obstacle 7's safety volume")
    assert is_bypassed(bypass) and not is_failsafe(bypass) and bypassed_seq(bypass) == 4
    assert bypassed_seq(reached_text(4)) is None and reached_text(4) == "Reached item 4"
    assert first_failsafe(["Reached item 1", bypass, lost, breach]) == lost and first_failsafe([bypass]) == ""
    assert failsafe_in(f"failsafe during the mission: {breach}") == breach and failsafe_in("timeout") == ""
