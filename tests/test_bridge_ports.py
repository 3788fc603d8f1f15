"""Exclusive ports and link URLs: a taken port fails with one line naming it, ``--instance`` shifts defaults only."""

from __future__ import annotations

import socket

import pytest

from autopilot import launcher
from autopilot.cli import build_parser as autopilot_parser
from autopilot.cli import link_urls
from autopilot.launch_commands import commands
from autopilot.launch_plan import plan_launch
from mavlink_bridge.wire.link import PortInUseError, UdpLink, check_ports_free, resolve_url
from sim.cli import build_parser as sim_parser
from sim.cli import config_from_args


def test_a_listening_port_is_never_shared() -> None:
    with UdpLink.from_url("udpin:127.0.0.1:0") as first:
        port = first.local_address[1]
        with pytest.raises(PortInUseError) as info:
            UdpLink.from_url(f"udpin:127.0.0.1:{port}")
        message = str(info.value)
        assert f"UDP port {port}" in message and "--instance N" in message and "\n" not in message
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as thief:  # address reuse asked for by the other side
            thief.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            if hasattr(socket, "SO_REUSEPORT"):
                thief.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
            with pytest.raises(OSError):
                thief.bind(("127.0.0.1", port))
        with pytest.raises(PortInUseError):
            check_ports_free(["udpout:127.0.0.1:9", "off", f"udp:127.0.0.1:{port}"])
    check_ports_free([f"udp:127.0.0.1:{port}"])  # free again once closed


def test_instance_shifts_default_ports_only() -> None:
    assert resolve_url(None, "udpin:127.0.0.1:18570", 11) == "udpin:127.0.0.1:18581"
    assert resolve_url("udpout:127.0.0.1:24561", "udpout:127.0.0.1:14550", 11) == "udpout:127.0.0.1:24561"
    args = autopilot_parser().parse_args(["--instance", "11", "--gcs-target", "udpout:127.0.0.1:24561", "--api", "off"])
    urls = link_urls(args)
    assert urls["gcs_target"] == "udpout:127.0.0.1:24561"  # as typed
    assert urls["gcs"] == "udpin:127.0.0.1:18581" and urls["sim"] == "udpout:127.0.0.1:14571"  # defaults shifted
    assert urls["api"] == "off"
    assert config_from_args(sim_parser().parse_args(["--instance", "4"])).listen_url == "udpin:127.0.0.1:14564"
    typed = sim_parser().parse_args(["--instance", "4", "--listen", "udp:127.0.0.1:15000"])
    assert config_from_args(typed).listen_url == "udpin:127.0.0.1:15000"


def test_up_passes_typed_urls_as_typed_and_lets_each_process_shift_its_defaults() -> None:
    args = launcher.build_parser().parse_args(["--instance", "11", "--gcs", "udpout:127.0.0.1:24561"])
    sim_cmd, [ap_cmd] = commands(args, plan_launch(args))
    assert "--listen" not in sim_cmd and sim_cmd[sim_cmd.index("--instance") + 1] == "11"
    assert ap_cmd[ap_cmd.index("--gcs") + 1] == "udpout:127.0.0.1:24561"
    assert "--sim" not in ap_cmd and "--api" not in ap_cmd and ap_cmd[ap_cmd.index("--instance") + 1] == "11"
    listen = launcher.build_parser().parse_args(["--listen", "udp:127.0.0.1:15000", "--sim-loss", "0.1"])
    sim_cmd, [ap_cmd] = commands(listen, plan_launch(listen))
    assert ap_cmd[ap_cmd.index("--sim") + 1] == "udpout:127.0.0.1:15000"
    assert sim_cmd[sim_cmd.index("--sim-loss") + 1] == "0.1"
    expected = ["udpin:127.0.0.1:14571", "udpout:127.0.0.1:24561", "udpin:127.0.0.1:14591"]
    assert plan_launch(args).listen_urls() == expected
    with pytest.raises(SystemExit):
        launcher.build_parser().parse_args(["--sim-loss", "1.5"])


def test_up_on_a_taken_port_fails_at_once_naming_it(capsys: pytest.CaptureFixture[str]) -> None:
    with UdpLink.from_url("udpin:127.0.0.1:0") as taken:
        port = taken.local_address[1]
        rc = launcher.main(["--listen", f"udp:127.0.0.1:{port}", "--gcs", "off", "--api", "off"])
    assert rc == launcher.EXIT_USAGE
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"UDP port {port}" in err and "--instance N" in err
