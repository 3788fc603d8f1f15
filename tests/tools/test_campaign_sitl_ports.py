"""A ``mode: sitl`` case whose loopback port was taken between choosing and binding it is flown again on new ports
(tools.campaign.sitl_flight): once a clean-clone CI run's replay lost its simulator's port that way ("UDP port
47914 on 127.0.0.1 is already in use") and reported a truth-hash mismatch for a flight that never started."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from tools.campaign import sitl_flight

TAKEN = {"error": "sim exited 2: quadsitl sim: UDP port 47914 on 127.0.0.1 is already in use (another quadsitl "
         "instance?); run this one with --instance N to shift every default port by N"}  # fmt: skip
FLOWN = {"error": "", "sim": {"end_reason": "LANDED"}}


def _fake(monkeypatch: pytest.MonkeyPatch, outcomes: list[dict[str, Any]]) -> list[int]:
    calls: list[int] = []

    def fly(case_dir: Path, case: dict[str, Any], rerun: str | None) -> dict[str, Any]:
        calls.append(len(calls))
        return outcomes[min(len(calls) - 1, len(outcomes) - 1)]

    monkeypatch.setattr(sitl_flight, "_fly_one_on_free_ports", fly)
    return calls


def test_a_taken_port_is_chosen_again_and_the_case_flown(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    calls = _fake(monkeypatch, [TAKEN, {"error": "OSError: [Errno 98] Address already in use"}, FLOWN])
    assert sitl_flight._fly_one(tmp_path, {}, None) == FLOWN and len(calls) == 3


def test_it_gives_up_after_its_tries_and_never_retries_another_error(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    calls = _fake(monkeypatch, [TAKEN])
    assert sitl_flight._fly_one(tmp_path, {}, None) == TAKEN and len(calls) == sitl_flight.PORT_TRIES
    calls = _fake(monkeypatch, [{"error": "autopilot exited 2 during the flight: boom"}, FLOWN])
    assert sitl_flight._fly_one(tmp_path, {}, None)["error"].startswith("autopilot exited") and len(calls) == 1
