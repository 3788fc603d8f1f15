"""MAVLink 2 endpoint of the GCS/API links on top of :class:`mavlink_bridge.wire.link.UdpLink`.

URL forms follow pymavlink connection strings (SPEC §3, §12). A ``udpin`` endpoint may be
given a default peer (``udpout:H:P``) that it sends to until someone talks to it (PX4's
"local 18570 -> 127.0.0.1:14550"); after that it replies to the last sender of a valid
(and, when signing is required, correctly signed) message, so garbage cannot hijack it.

:class:`MavlinkEndpoint` turns datagrams into decoded messages. Malformed, truncated or
random bytes, and packets refused by signing, are counted and dropped; it never raises
on input (SPEC §10).
"""

from __future__ import annotations

import socket
from collections.abc import Iterator
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.wire.link import LinkMode, LinkUrl, UdpLink
from mavlink_bridge.wire.signing import RejectReason, classify_bad_data, enable_signing


def open_link(url: str, default_peer_url: str | None = None) -> UdpLink:
    """A :class:`UdpLink` for ``url``; a ``udpin`` link sends to ``default_peer_url`` until someone talks to it."""
    link = UdpLink.from_url(url, follow_sender=False)
    if default_peer_url is not None and link.peer is None:
        default = LinkUrl.parse(default_peer_url)
        link.set_peer((socket.gethostbyname(default.host), default.port))
    return link


@dataclass(slots=True)
class LinkCounters:
    """What a MAVLink endpoint has seen (monotonic counters)."""

    datagrams_in: int = 0
    messages_in: int = 0
    malformed: int = 0
    unknown_message_ids: int = 0
    rejected_unsigned: int = 0
    rejected_bad_signature: int = 0


class _DatagramWriter:
    """The ``file`` pymavlink writes packed messages to."""

    def __init__(self, endpoint: UdpLink) -> None:
        self._endpoint = endpoint

    def write(self, data: bytes) -> None:
        self._endpoint.send(bytes(data))


class MavlinkEndpoint:
    """Decoded MAVLink 2 messages over a :class:`UdpLink`; ``mav`` packs and sends (``mav.xxx_send``)."""

    def __init__(
        self,
        url: str,
        *,
        system_id: int,
        component_id: int,
        default_peer_url: str | None = None,
        signing_key: bytes | None = None,
        require_signing: bool = False,
    ) -> None:
        self.link = open_link(url, default_peer_url)
        self._listening = self.link.url.mode is LinkMode.LISTEN
        self.mav = mavlink2.MAVLink(_DatagramWriter(self.link), srcSystem=system_id, srcComponent=component_id)
        self.mav.robust_parsing = True
        if require_signing and signing_key is None:
            raise ValueError("require_signing needs a signing_key")
        if signing_key is not None:
            enable_signing(self.mav, signing_key, require_incoming=require_signing)
        self.counters = LinkCounters()

    def receive(self, timeout_s: float = 0.0, max_datagrams: int = 256) -> Iterator[mavlink2.MAVLink_message]:
        """Yield the valid messages of up to ``max_datagrams`` waiting datagrams (waits ``timeout_s`` for the first)."""
        for i in range(max_datagrams):
            msgs = self.receive_datagram(timeout_s if i == 0 else 0.0)
            if msgs is None:
                return
            yield from msgs

    def receive_datagram(self, timeout_s: float = 0.0) -> list[mavlink2.MAVLink_message] | None:
        """The valid messages of one datagram (maybe none), or None if no datagram came within ``timeout_s``."""
        data = self.link.recv(timeout_s)
        if data is None:
            return None
        self.counters.datagrams_in += 1
        msgs = self._decode(data)
        if msgs and self._listening:
            self.link.set_peer(self.link.last_sender)  # only a valid (and, if required, signed) sender is followed
        return msgs

    def _decode(self, data: bytes) -> list[mavlink2.MAVLink_message]:
        mav = self.mav
        try:
            msgs = mav.parse_buffer(data) or []
        except Exception:  # the parser must never take the process down on hostile input
            msgs = []
            self.counters.malformed += 1
        # A datagram carries whole packets: drop any partial tail so it cannot corrupt the next one.
        mav.buf = bytearray()
        mav.buf_index = 0
        mav.expected_length = mavlink2.HEADER_LEN_V1 + 2
        mav.have_prefix_error = False
        good: list[mavlink2.MAVLink_message] = []
        for msg in msgs:
            if isinstance(msg, mavlink2.MAVLink_bad_data):
                reason = classify_bad_data(msg)
                if reason is RejectReason.UNSIGNED:
                    self.counters.rejected_unsigned += 1
                elif reason is RejectReason.BAD_SIGNATURE:
                    self.counters.rejected_bad_signature += 1
                else:
                    self.counters.malformed += 1
            elif isinstance(msg, mavlink2.MAVLink_unknown):
                self.counters.unknown_message_ids += 1
            else:
                self.counters.messages_in += 1
                good.append(msg)
        return good

    def close(self) -> None:
        self.link.close()
