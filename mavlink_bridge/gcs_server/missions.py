"""Vehicle side of the MAVLink mission protocol (SPEC §8), for mission_type MISSION, FENCE and RALLY.

Upload: MISSION_COUNT -> MISSION_REQUEST_INT per item (re-requested after ``retry_s`` of
silence, given up after ``max_retries``) -> MISSION_ITEM_INT (or legacy MISSION_ITEM, then
MISSION_REQUEST is used) -> MISSION_ACK. The vehicle sees only complete lists:
``replace_mission`` is called once per finished upload and its result is the ACK; a
refused, cancelled or timed-out upload leaves the previous mission in force and says why
in a STATUSTEXT. Download: MISSION_REQUEST_LIST -> MISSION_COUNT -> MISSION_REQUEST(_INT)
-> items -> MISSION_ACK. Also MISSION_CLEAR_ALL and MISSION_SET_CURRENT.

A link may duplicate and reorder (issue 22): only a MISSION_ACK(OPERATION_CANCELLED) from the uploading GCS
cancels an upload (a late copy of a download's ACK does not); a late copy of an item of the upload that just ended
is ignored (its last item is answered with that upload's ACK again, the GCS may have missed it); any other item
outside a transfer is answered with MISSION_ACK(ERROR) so the GCS restarts instead of resending it unanswered.
Time is the wall clock (the GCS is a real-time peer); ``TransferTimeouts.scaled`` stretches it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.vehicle_api import MissionItem, MissionResult, MissionType, Severity, VehicleInterface
from mavlink_bridge.wire.mission_items import MissionItemEncodeError, item_from_msg, send_item

StatusTextSink = Callable[[Severity, str], None]


@dataclass(frozen=True, slots=True)
class TransferTimeouts:
    """Wall-clock pacing of a transfer: re-request after ``retry_s``, give up after ``max_retries``."""

    retry_s: float = 0.3
    max_retries: int = 10

    def scaled(self, factor: float) -> TransferTimeouts:
        return TransferTimeouts(self.retry_s * factor, self.max_retries)


@dataclass(slots=True)
class MissionProtocolStats:
    uploads_accepted: int = 0
    uploads_refused: int = 0
    uploads_failed: int = 0  # timed out or cancelled by the GCS
    downloads: int = 0
    items_received: int = 0
    items_sent: int = 0


@dataclass(slots=True)
class _Upload:
    partner: tuple[int, int]
    mission_type: MissionType
    count: int
    use_int: bool
    items: list[MissionItem] = field(default_factory=list)
    last_request_wall_s: float = 0.0
    retries: int = 0

    @property
    def next_seq(self) -> int:
        return len(self.items)


@dataclass(frozen=True, slots=True)
class _FinishedUpload:
    partner: tuple[int, int]
    mission_type: MissionType
    count: int
    result: MissionResult


def _partner(msg: mavlink2.MAVLink_message) -> tuple[int, int]:
    return (msg.get_srcSystem(), msg.get_srcComponent())


def _upload_type(raw: int) -> MissionType | None:
    """The mission type of an upload/download, or None if not one we store (ALL or unknown)."""
    try:
        mission_type = MissionType(raw)
    except ValueError:
        return None
    return None if mission_type is MissionType.ALL else mission_type


class MissionProtocol:
    """Mission transfers between one vehicle and its GCS peers; feed it messages and call ``tick``."""

    HANDLED = frozenset(
        {
            "MISSION_COUNT",
            "MISSION_ITEM_INT",
            "MISSION_ITEM",
            "MISSION_REQUEST_LIST",
            "MISSION_REQUEST_INT",
            "MISSION_REQUEST",
            "MISSION_ACK",
            "MISSION_CLEAR_ALL",
            "MISSION_SET_CURRENT",
        }
    )

    def __init__(
        self,
        mav: mavlink2.MAVLink,
        vehicle: VehicleInterface,
        statustext: StatusTextSink,
        *,
        timeouts: TransferTimeouts = TransferTimeouts(),
        max_items: int = 5000,
    ) -> None:
        self._mav = mav
        self._vehicle = vehicle
        self._statustext = statustext
        self.timeouts = timeouts
        self.max_items = max_items
        self.current_seq = 0  # set by the server from each telemetry snapshot
        self.stats = MissionProtocolStats()
        self._upload: _Upload | None = None
        self._finished: dict[MissionType, _FinishedUpload] = {}  # the last installed upload of each type
        self._download: dict[MissionType, list[MissionItem]] = {}

    @property
    def upload_in_progress(self) -> bool:
        return self._upload is not None

    def handle(self, msg: mavlink2.MAVLink_message, wall_time_s: float) -> None:
        kind = msg.get_type()
        if kind == "MISSION_COUNT":
            self._on_count(msg, wall_time_s)
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            self._on_item(msg, wall_time_s)
        elif kind == "MISSION_REQUEST_LIST":
            self._on_request_list(msg)
        elif kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            self._on_request(msg)
        elif kind == "MISSION_ACK":
            self._on_ack(msg)
        elif kind == "MISSION_CLEAR_ALL":
            self._on_clear(msg)
        elif kind == "MISSION_SET_CURRENT":
            self._on_set_current(msg)

    def tick(self, wall_time_s: float) -> None:
        """Re-request the awaited item after ``retry_s`` of silence; fail the upload after ``max_retries``."""
        up = self._upload
        if up is None or wall_time_s - up.last_request_wall_s < self.timeouts.retry_s:
            return
        up.retries += 1
        if up.retries > self.timeouts.max_retries:
            self._upload = None
            self.stats.uploads_failed += 1
            self._statustext(
                Severity.WARNING,
                f"{up.mission_type.name.lower()} upload timed out at item {up.next_seq}/{up.count}; previous kept",
            )
            self._ack(up.partner, MissionResult.ERROR, up.mission_type)
            return
        self._request(up, wall_time_s)

    # ---- upload ------------------------------------------------------------------------------------------
    def _on_count(self, msg: mavlink2.MAVLink_message, wall_time_s: float) -> None:
        partner = _partner(msg)
        mission_type = self._stored_type_or_refuse(msg, partner)
        if mission_type is None:
            return
        count = int(msg.count)
        up = self._upload
        if up is not None and (up.partner, up.mission_type, up.count) == (partner, mission_type, count):
            self._request(up, wall_time_s)  # duplicate or retried MISSION_COUNT: answer where we are
            return
        if up is not None and up.partner != partner:
            self._ack(partner, MissionResult.DENIED, mission_type)
            self._statustext(Severity.WARNING, "mission upload refused: another transfer is in progress")
            return
        self._upload = None
        self._finished.pop(mission_type, None)
        if count > self.max_items:
            self.stats.uploads_refused += 1
            self._statustext(Severity.WARNING, f"mission upload refused: {count} items > limit {self.max_items}")
            self._ack(partner, MissionResult.NO_SPACE, mission_type)
            return
        if count == 0:
            self._install(partner, mission_type, [])
            return
        self._upload = _Upload(partner, mission_type, count, use_int=True)
        self._request(self._upload, wall_time_s)

    def _on_item(self, msg: mavlink2.MAVLink_message, wall_time_s: float) -> None:
        partner = _partner(msg)
        mission_type = _upload_type(int(getattr(msg, "mission_type", 0)))
        seq = int(msg.seq)
        up = self._upload
        if up is None or up.partner != partner or up.mission_type != mission_type:
            self._on_item_outside_transfer(partner, mission_type, seq, int(getattr(msg, "mission_type", 0)))
            return
        if msg.get_type() == "MISSION_ITEM":
            up.use_int = False  # a float-item client (MAVProxy) gets MISSION_REQUEST from now on
        if seq != up.next_seq:
            return  # duplicate or reordered: the retry timer asks again for the one we need
        up.items.append(item_from_msg(msg))
        self.stats.items_received += 1
        up.retries = 0
        if up.next_seq == up.count:
            self._upload = None
            self._install(partner, up.mission_type, up.items)
        else:
            self._request(up, wall_time_s)

    def _on_item_outside_transfer(
        self, partner: tuple[int, int], mission_type: MissionType | None, seq: int, raw_type: int
    ) -> None:
        """A late copy of an item of the upload that just ended is ignored (the last one re-ACKed: the GCS resends
        it when our ACK was lost); any other item gets MISSION_ACK(ERROR) so the GCS starts its upload again."""
        done = self._finished.get(mission_type) if mission_type is not None else None
        if done is not None and done.partner == partner and 0 <= seq < done.count:
            if seq == done.count - 1:
                self._ack(partner, done.result, done.mission_type)
            return
        self._statustext(Severity.WARNING, f"mission item {seq} ignored: no upload in progress")
        self._ack(partner, MissionResult.ERROR, raw_type)

    def _install(self, partner: tuple[int, int], mission_type: MissionType, items: list[MissionItem]) -> None:
        result, reason = self._vehicle.replace_mission(mission_type, items)
        if result is MissionResult.ACCEPTED:
            self.stats.uploads_accepted += 1
            self._statustext(Severity.INFO, f"{mission_type.name.lower()} accepted: {len(items)} items")
        else:
            self.stats.uploads_refused += 1
            self._statustext(Severity.WARNING, f"{mission_type.name.lower()} refused: {reason}; previous kept")
        self._finished[mission_type] = _FinishedUpload(partner, mission_type, len(items), result)
        self._ack(partner, result, mission_type)

    def _request(self, up: _Upload, wall_time_s: float) -> None:
        up.last_request_wall_s = wall_time_s
        sys_id, comp_id = up.partner
        if up.use_int:
            self._mav.mission_request_int_send(sys_id, comp_id, up.next_seq, int(up.mission_type))
        else:
            self._mav.mission_request_send(sys_id, comp_id, up.next_seq, int(up.mission_type))

    def _on_ack(self, msg: mavlink2.MAVLink_message) -> None:
        """OPERATION_CANCELLED from the uploading GCS cancels its upload; any other ACK ends a download (the next
        list is read afresh) and never touches an upload: it may be a late copy of an earlier transfer's ACK."""
        up = self._upload
        mission_type = _upload_type(int(getattr(msg, "mission_type", 0)))
        cancels = int(msg.type) == int(MissionResult.OPERATION_CANCELLED)
        if up is None or not cancels or up.partner != _partner(msg) or up.mission_type != mission_type:
            if mission_type is not None:
                self._download.pop(mission_type, None)
            return
        self._upload = None
        self.stats.uploads_failed += 1
        self._statustext(Severity.WARNING, f"{up.mission_type.name.lower()} upload cancelled by the GCS; previous kept")

    # ---- download ----------------------------------------------------------------------------------------
    def _on_request_list(self, msg: mavlink2.MAVLink_message) -> None:
        partner = _partner(msg)
        mission_type = self._stored_type_or_refuse(msg, partner)
        if mission_type is None:
            return
        items = list(self._vehicle.mission_items(mission_type))
        self._download[mission_type] = items
        self.stats.downloads += 1
        self._mav.mission_count_send(partner[0], partner[1], len(items), int(mission_type))

    def _on_request(self, msg: mavlink2.MAVLink_message) -> None:
        partner = _partner(msg)
        mission_type = self._stored_type_or_refuse(msg, partner)
        if mission_type is None:
            return
        items = self._download.get(mission_type)
        if items is None:
            items = list(self._vehicle.mission_items(mission_type))
            self._download[mission_type] = items
        seq = int(msg.seq)
        if not 0 <= seq < len(items):
            self._ack(partner, MissionResult.INVALID_SEQUENCE, mission_type)
            return
        current = mission_type is MissionType.MISSION and seq == self.current_seq
        use_int = msg.get_type() == "MISSION_REQUEST_INT"
        try:
            send_item(
                self._mav,
                items[seq],
                seq=seq,
                target_system=partner[0],
                target_component=partner[1],
                use_int=use_int,
                current=current,
            )
        except MissionItemEncodeError as exc:
            self._statustext(Severity.ERROR, f"mission item {seq} cannot be sent: {exc}")
            self._ack(partner, MissionResult.ERROR, mission_type)
            return
        self.stats.items_sent += 1

    # ---- clear / set current -----------------------------------------------------------------------------
    def _on_clear(self, msg: mavlink2.MAVLink_message) -> None:
        partner = _partner(msg)
        raw_type = int(getattr(msg, "mission_type", 0))
        try:
            requested = MissionType(raw_type)
        except ValueError:
            self._ack(partner, MissionResult.UNSUPPORTED, raw_type)
            return
        types = (MissionType.MISSION, MissionType.FENCE) if requested is MissionType.ALL else (requested,)
        result = MissionResult.ACCEPTED
        for mission_type in types:
            one, reason = self._vehicle.replace_mission(mission_type, [])
            if one is not MissionResult.ACCEPTED:
                result = one
                self._statustext(Severity.WARNING, f"{mission_type.name.lower()} not cleared: {reason}")
        self._ack(partner, result, requested)

    def _on_set_current(self, msg: mavlink2.MAVLink_message) -> None:
        seq = int(msg.seq)
        if self._vehicle.set_current_mission_item(seq):
            self.current_seq = seq
            total = len(self._vehicle.mission_items(MissionType.MISSION))
            self._mav.mission_current_send(seq, total)
        else:
            self._statustext(Severity.WARNING, f"mission item {seq} cannot be made current")

    def _stored_type_or_refuse(self, msg: mavlink2.MAVLink_message, partner: tuple[int, int]) -> MissionType | None:
        """The message's mission type if it is one we store; otherwise answer UNSUPPORTED and return None."""
        raw_type = int(getattr(msg, "mission_type", 0))
        mission_type = _upload_type(raw_type)
        if mission_type is None:
            self._ack(partner, MissionResult.UNSUPPORTED, raw_type)
        return mission_type

    def _ack(self, partner: tuple[int, int], result: MissionResult, mission_type: int) -> None:
        self._mav.mission_ack_send(partner[0], partner[1], int(result), int(mission_type))
