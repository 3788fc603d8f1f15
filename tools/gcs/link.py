"""How the ground-station script reaches its vehicles: one socket for one vehicle or a fleet, a client per system id
once each has been heard; and the script's progress lines and its one error type.

Every vehicle's GCS link sends to the one ground-station port (PX4: 14550+N), so one
:class:`~mavlink_bridge.gcs_client.fleet_link.FleetLink` serves one vehicle and many alike. A ``udpout:`` URL talks
first: each vehicle is addressed there until it answers.
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Iterator, Sequence

from mavlink_bridge.gcs_client.client import GcsClient
from mavlink_bridge.gcs_client.fleet_link import FleetLink
from mavlink_bridge.wire.link import resolve_url

DEFAULT_CONNECT = "udpin:127.0.0.1:14550"


class GcsScriptError(Exception):
    """A request that did not succeed; the message is the one line printed on stderr."""


def say(text: str) -> None:
    """Progress for the person at the terminal (stderr: stdout holds only the result)."""
    print(f"gcs: {text}", file=sys.stderr, flush=True)


def connect_url(url: str | None, instance: int) -> str:
    """The link to use: ``url`` exactly as typed, else the default GCS port shifted by ``instance`` (like
    ``quadsitl --instance N``, which shifts default ports only)."""
    return resolve_url(url, DEFAULT_CONNECT, instance)


@contextlib.contextmanager
def vehicle_clients(
    url: str, sys_ids: Sequence[int], *, signing_key: bytes | None, step_timeout_s: float, wait_s: float
) -> Iterator[tuple[FleetLink, list[GcsClient]]]:
    """The link and one client per system id in ``sys_ids``, once every one has been heard (GcsScriptError naming
    the silent ones after ``wait_s``)."""
    with FleetLink(url, signing_key=signing_key) as link:
        if link.link.peer is not None:  # udpout: talk first, to the one address given
            for sys_id in sys_ids:
                link.addresses.setdefault(sys_id, link.link.peer)
        clients = [link.client(sys_id, timeout_s=step_timeout_s) for sys_id in sys_ids]
        _wait_to_hear(link, clients, url, wait_s)
        yield link, clients


def _wait_to_hear(link: FleetLink, clients: list[GcsClient], url: str, wait_s: float) -> None:
    deadline = time.monotonic() + wait_s
    said = False
    while missing := [c.target_system for c in clients if c.target_system not in link.last_heard_s]:
        now = time.monotonic()
        if now >= deadline:
            raise GcsScriptError(_not_heard(url, wait_s, missing, len(clients)))
        if not said and now > deadline - wait_s + 1.0:
            ids = [c.target_system for c in clients]
            if len(clients) == 1:
                say(f"waiting for a vehicle on {url} (up to {wait_s:g} s; is quadsitl up running?)")
            else:
                say(f"waiting for {len(clients)} vehicles (system ids {ids[0]}..{ids[-1]}) on {url}")
            said = True
        for client in clients:  # keeps each one's GCS HEARTBEAT going (a udpout: link needs it to be answered)
            client.pump(0.1 / len(clients))


def _not_heard(url: str, wait_s: float, missing: list[int], count: int) -> str:
    if count == 1:
        return (
            f"no vehicle heard on {url} within {wait_s:g} s; fix: start one (quadsitl up), "
            "or pass the --instance N or --connect URL it runs with"
        )
    return (
        f"no vehicle with system id {missing} heard on {url} within {wait_s:g} s; fix: start the fleet "
        "(quadsitl up --world FILE) with the same --instance"
    )
