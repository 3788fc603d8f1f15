"""One ground-station port shared by a fleet: a :class:`GcsClient` per vehicle system id over one socket (SPEC §13).

PX4's multi-vehicle convention sends every vehicle's GCS link to one port (14550), so one ground station sees the
fleet by system id. :class:`FleetLink` owns that socket: a datagram read for any vehicle is decoded once and its
messages queued for the vehicle that sent them, and each vehicle is answered at the address it last sent from.
:meth:`FleetLink.client` gives the usual typed :class:`GcsClient` for one system id; the clients are single-threaded
and may be used in turn (nothing read for one vehicle is lost to another).
"""

from __future__ import annotations

import time
from collections import deque
from typing import Self

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.gcs_client.client import GcsClient
from mavlink_bridge.gcs_client.session import MAV_COMP_ID_MISSIONPLANNER
from mavlink_bridge.wire.gcs_link import MavlinkEndpoint
from mavlink_bridge.wire.link import Address, UdpLink
from mavlink_bridge.wire.signing import enable_signing

Msg = mavlink2.MAVLink_message
#: Messages kept per vehicle not yet read by its client (a client not pumped for long loses the oldest).
QUEUE_LIMIT = 20_000


class FleetLink:
    """One ``udpin:`` GCS socket shared by the clients of several vehicles (one per MAV_SYS_ID)."""

    def __init__(
        self,
        url: str,
        *,
        system_id: int = 255,
        component_id: int = MAV_COMP_ID_MISSIONPLANNER,
        signing_key: bytes | None = None,
    ) -> None:
        self._endpoint = MavlinkEndpoint(url, system_id=system_id, component_id=component_id, signing_key=signing_key)
        self._system_id, self._component_id, self._signing_key = system_id, component_id, signing_key
        self._queues: dict[int, deque[Msg]] = {}
        self.addresses: dict[int, Address] = {}  # where each vehicle last sent from (its GCS link's local port)
        self.last_heard_s: dict[int, float] = {}  # time.monotonic() of each vehicle's latest message
        self._clients: list[GcsClient] = []

    @property
    def systems_heard(self) -> list[int]:
        """The system ids heard so far, ascending."""
        return sorted(self.addresses)

    def poll(self, timeout_s: float) -> bool:
        """Read and route one datagram (waits up to ``timeout_s``); False when none came."""
        msgs = self._endpoint.receive_datagram(timeout_s)
        if msgs is None:
            return False
        sender, now = self._endpoint.link.last_sender, time.monotonic()
        for msg in msgs:
            sys_id = msg.get_srcSystem()
            if sender is not None:
                self.addresses[sys_id] = sender
            self.last_heard_s[sys_id] = now
            self._queues.setdefault(sys_id, deque(maxlen=QUEUE_LIMIT)).append(msg)
        return True

    def take(self, sys_id: int, timeout_s: float) -> list[Msg] | None:
        """Vehicle ``sys_id``'s queued messages, else those of the next datagram (maybe another vehicle's: then
        ``[]``); None when nothing came within ``timeout_s``."""
        queue = self._queues.get(sys_id)
        if not queue and not self.poll(timeout_s):
            return None
        queue = self._queues.get(sys_id)
        if not queue:
            return []
        msgs = list(queue)
        queue.clear()
        return msgs

    def client(self, sys_id: int, *, timeout_s: float = 5.0, retry_s: float = 0.3) -> GcsClient:
        """A :class:`GcsClient` for vehicle ``sys_id`` on this socket (closing it leaves the socket open)."""
        client = GcsClient(
            target_system=sys_id, timeout_s=timeout_s, retry_s=retry_s, endpoint=_VehicleChannel(self, sys_id)
        )
        self._clients.append(client)
        return client

    def packer(self, sys_id: int) -> mavlink2.MAVLink:
        """A MAVLink packer whose messages go to vehicle ``sys_id``'s address."""
        mav = mavlink2.MAVLink(_ToVehicle(self, sys_id), srcSystem=self._system_id, srcComponent=self._component_id)
        mav.robust_parsing = True
        if self._signing_key is not None:
            enable_signing(mav, self._signing_key, require_incoming=False)
        return mav

    @property
    def link(self) -> UdpLink:
        return self._endpoint.link

    def close(self) -> None:
        self._endpoint.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _ToVehicle:
    """The ``file`` a vehicle's packer writes to: the shared socket, to that vehicle's last address."""

    def __init__(self, fleet: FleetLink, sys_id: int) -> None:
        self._fleet, self._sys_id = fleet, sys_id

    def write(self, data: bytes) -> None:
        self._fleet.link.send_to(bytes(data), self._fleet.addresses.get(self._sys_id))


class _PeerView:
    """What a session reads of its link: ``peer``, the vehicle's address (None until it was heard)."""

    def __init__(self, fleet: FleetLink, sys_id: int) -> None:
        self._fleet, self._sys_id = fleet, sys_id

    @property
    def peer(self) -> Address | None:
        return self._fleet.addresses.get(self._sys_id)


class _VehicleChannel:
    """One vehicle's side of a :class:`FleetLink`, shaped as the session's :class:`MavlinkEndpoint`."""

    def __init__(self, fleet: FleetLink, sys_id: int) -> None:
        self._fleet, self._sys_id = fleet, sys_id
        self.mav = fleet.packer(sys_id)
        self.link = _PeerView(fleet, sys_id)

    def receive_datagram(self, timeout_s: float = 0.0) -> list[Msg] | None:
        return self._fleet.take(self._sys_id, timeout_s)

    def close(self) -> None:
        """The socket belongs to the :class:`FleetLink`."""
