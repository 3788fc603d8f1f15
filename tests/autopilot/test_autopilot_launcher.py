"""``quadsitl up``'s one launcher: a world without ``vehicles:`` is a fleet of one on instance 0's ports; a fleet's
ports follow PX4's table; one supervision rule ends the run for one vehicle and many, with one exit status."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

from autopilot.launch_commands import commands
from autopilot.launch_plan import LaunchPlan, plan_launch
from autopilot.launch_processes import RunOutcome, run_status, supervise
from autopilot.launcher import build_parser, main
from mavlink_bridge.wire.link import LinkUrlError


def _plan(tmp_path: Path, names: list[str] | None, *argv: str) -> LaunchPlan:
    world = tmp_path / "w.yaml"
    text = "home: {lat_deg: 47.3977, lon_deg: 8.5456, alt_m: 488}\n"
    for i, name in enumerate(names or []):
        text += ("" if i else "vehicles:\n") + f"  - {{name: {name}, home: {{north_m: 0, east_m: {i * 8}}}}}\n"
    world.write_text(text)
    return plan_launch(build_parser().parse_args(["--world", str(world), *argv]))


def _ports(plan: LaunchPlan) -> list[tuple[str, str, str, str, str]]:
    return [
        (plan.sim_listen(v), *(v.urls()[k] for k in ("gcs", "gcs_target", "api", "api_target"))) for v in plan.vehicles
    ]


def test_one_vehicle_flies_on_the_ports_of_a_fleets_first_vehicle(tmp_path: Path) -> None:
    for block in (0, 7):
        one = _plan(tmp_path, None, "--instance", str(block))
        fleet = _plan(tmp_path, ["alpha", "bravo"], "--instance", str(block))
        assert not one.fleet and fleet.fleet and [v.sys_id for v in fleet.vehicles] == [1, 2]
        assert _ports(one) == _ports(fleet)[:1]
        assert _ports(one)[0] == (
            f"udpin:127.0.0.1:{14560 + block}",
            f"udpin:127.0.0.1:{18570 + block}",
            f"udpout:127.0.0.1:{14550 + block}",
            f"udpin:127.0.0.1:{14580 + block}",
            f"udpout:127.0.0.1:{14540 + block}",
        )
    bravo = _ports(_plan(tmp_path, ["alpha", "bravo"], "--instance", "7"))[1]
    assert [int(url.rsplit(":", 1)[1]) for url in bravo] == [14568, 18578, 14557, 14588, 14548]


def test_pxs_api_port_stops_at_14549_and_21_vehicles_need_api_off(tmp_path: Path) -> None:
    names = [f"v{i}" for i in range(21)]
    with pytest.raises(LinkUrlError, match="fix: --api off"):
        _plan(tmp_path, names)
    twenty = _plan(tmp_path, names[:20])
    assert [v.urls()["api_target"] for v in twenty.vehicles][9:] == ["udpout:127.0.0.1:14549"] * 11
    assert len(_plan(tmp_path, names, "--api", "off").vehicles) == 21


ONE_URL_OPTIONS = [
    ["--sim", "udpout:127.0.0.1:1"],
    ["--gcs", "udpin:127.0.0.1:2"],
    ["--api", "udpin:127.0.0.1:3"],
    ["--api-target", "udpout:127.0.0.1:4"],
]


@pytest.mark.parametrize("option", ONE_URL_OPTIONS)
def test_a_fleet_refuses_one_url_for_every_vehicle_and_one_vehicle_takes_it_as_typed(
    tmp_path: Path, option: list[str]
) -> None:
    with pytest.raises(LinkUrlError, match="a fleet world gives each vehicle its own"):
        _plan(tmp_path, ["alpha", "bravo"], *option)
    one = _plan(tmp_path, None, *option)
    assert one.vehicles[0].urls()[option[0].removeprefix("--").replace("-", "_")] == option[1]


def test_a_fleet_of_one_named_vehicle_is_still_a_fleet(tmp_path: Path) -> None:
    plan = _plan(tmp_path, ["solo"], "--log-dir", "D")
    args = build_parser().parse_args(["--world", str(tmp_path / "w.yaml"), "--log-dir", "D"])
    _, [ap] = commands(args, plan)
    assert plan.fleet and ap[ap.index("--log-dir") + 1] == str(Path("D", "solo"))
    assert ap[ap.index("--fleet-vehicle") + 1] == "solo" and ap[ap.index("--sys-id") + 1] == "1"


def test_a_bad_fleet_option_is_one_line_and_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _plan(tmp_path, ["alpha", "bravo"])
    assert main(["--world", str(tmp_path / "w.yaml"), "--sim", "udpout:127.0.0.1:1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("quadsitl up: --sim: a fleet world") and "\n" not in err


def _child(code: str) -> list[str]:
    return [sys.executable, "-c", f"import signal, sys, time\n{code}"]


#: A child that runs until stopped and exits 0 on SIGTERM (as the simulator and the autopilot do).
RUNS = _child("signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))\ntime.sleep(60)")


def test_the_run_ends_when_every_autopilot_has_exited_and_the_last_ones_status_counts() -> None:
    t0 = time.monotonic()
    one = supervise(
        RUNS, [_child("time.sleep(0.5); sys.exit(3)")], ["the vehicle"]
    )  # one vehicle: its autopilot ends the run
    assert one == RunOutcome(sim_rc=0, autopilot_rcs=(3,), ended_by=0, left_early=frozenset())
    assert run_status(one) == 3
    two = supervise(
        RUNS, [_child("time.sleep(0.5); sys.exit(5)"), _child("time.sleep(2.0); sys.exit(0)")], ["alpha", "bravo"]
    )
    assert two.ended_by == 1 and two.left_early == frozenset({0}) and two.sim_rc == 0
    assert run_status(two) == 0  # alpha left while bravo flew on: not the run's outcome
    assert time.monotonic() - t0 < 30.0


def test_the_run_ends_when_the_simulator_exits_and_stops_every_autopilot(capsys: pytest.CaptureFixture[str]) -> None:
    outcome = supervise(_child("time.sleep(1.0); sys.exit(4)"), [RUNS, RUNS], ["alpha", "bravo"])
    assert outcome == RunOutcome(sim_rc=4, autopilot_rcs=(0, 0), ended_by=-1, left_early=frozenset())
    assert run_status(outcome) == 4
    assert "fly on" not in capsys.readouterr().out


@pytest.mark.parametrize(
    ("outcome", "status"),
    [
        (RunOutcome(0, (0,), None, frozenset()), 0),  # a signal, both clean
        (RunOutcome(3, (0,), None, frozenset()), 3),  # the simulator's status first
        (RunOutcome(0, (2,), None, frozenset()), 2),  # else the autopilot's
        (RunOutcome(0, (-9, 0), None, frozenset({0})), 0),  # an autopilot that left early does not count
        (RunOutcome(0, (-9,), 0, frozenset()), 137),  # killed by signal 9, as a shell says
        (RunOutcome(0, (0,), -1, frozenset()), 0),  # the simulator ended cleanly (--duration-s)
        (RunOutcome(3, (1,), 0, frozenset()), 1),  # the exit that ended the run, not the stop sent the other
    ],
)
def test_the_exit_status(outcome: RunOutcome, status: int) -> None:
    assert run_status(outcome) == status
