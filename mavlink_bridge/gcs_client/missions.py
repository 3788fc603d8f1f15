"""The ground station's mission protocol: upload, download, clear and set-current, with retries.

MAVLink transfers carry no transfer id, so over a link that duplicates and reorders a MISSION_ACK may belong to an
earlier transfer. An ACCEPTED ACK ends an upload only after its last item was sent; an error ACK ends a transfer
only when the vehicle repeats it for the message sent again (a stray copy is followed by the awaited answer). An
upload the vehicle no longer knows (ERROR: it timed out or never saw the count) is restarted from MISSION_COUNT.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from mavlink_bridge.contract.vehicle_api import MissionItem, MissionResult, MissionType
from mavlink_bridge.gcs_client.errors import MissionDownloadError, MissionUploadError
from mavlink_bridge.gcs_client.session import GcsSession, Msg
from mavlink_bridge.wire.mission_items import MissionItemEncodeError, item_from_msg, send_item, xy_to_int

#: Uploads started again from MISSION_COUNT after the vehicle answered ERROR twice (it has no transfer of ours).
UPLOAD_RESTARTS = 2


class GcsMissions(GcsSession):
    """The MAVLink mission microservice, GCS side."""

    def upload_mission(self, items: list[MissionItem], mission_type: MissionType = MissionType.MISSION) -> None:
        """Upload ``items`` (renumbered 0..n-1) as ``mission_type``; MissionUploadError if not accepted."""
        items = [replace(item, seq=i, mission_type=mission_type) for i, item in enumerate(items)]
        for item in items:
            try:
                xy_to_int(item.x_lat_deg, item.frame, "x/lat")
            except MissionItemEncodeError as exc:
                raise MissionUploadError(MissionResult.INVALID_PARAM5_X, f"item {item.seq}: {exc}") from exc
            try:
                xy_to_int(item.y_lon_deg, item.frame, "y/lon")
            except MissionItemEncodeError as exc:
                raise MissionUploadError(MissionResult.INVALID_PARAM6_Y, f"item {item.seq}: {exc}") from exc
        serial = self.statustext_serial
        count = len(items)
        mtype = int(mission_type)
        ts, tc = self.target_system, self.target_component

        def send_count() -> None:
            self.mav.mission_count_send(ts, tc, count, mtype)

        resend: Callable[[], None] = send_count
        resend()
        sent_last = count == 0
        retries = restarts = 0
        doubted: MissionResult | None = None  # an error ACK to confirm: the last message was sent again
        max_retries = max(1, round(self.timeout_s / self.retry_s))
        while True:
            msg = self._wait(
                self._mission_reply_matcher(mtype, ("MISSION_REQUEST_INT", "MISSION_REQUEST")), self.retry_s
            )
            if msg is None and doubted is None:
                retries += 1
                if retries > max_retries:
                    self.mav.mission_ack_send(ts, tc, int(MissionResult.OPERATION_CANCELLED), mtype)
                    raise MissionUploadError(MissionResult.OPERATION_CANCELLED, "the vehicle stopped answering")
                resend()
                continue
            retries = 0
            if msg is not None and msg.get_type() == "MISSION_ACK" and msg.type == int(MissionResult.ACCEPTED):
                if sent_last:
                    return
                continue  # a stale ACK of an earlier transfer
            if msg is None or msg.get_type() == "MISSION_ACK":
                result = _mission_result(msg.type) if msg is not None else doubted
                assert result is not None
                if doubted is None:  # maybe a stray copy of an earlier transfer's ACK: ask again
                    doubted = result
                    resend()
                    continue
                # confirmed: repeated, or no request came back for the message sent again (PX4 stays silent)
                if result is MissionResult.ERROR and restarts < UPLOAD_RESTARTS:
                    restarts += 1  # the vehicle has no upload of ours (it timed out): start again
                    doubted, sent_last, resend = None, count == 0, send_count
                    resend()
                    continue
                raise MissionUploadError(result, self._reason(serial, result.name))
            doubted = None
            seq = int(msg.seq)
            if not 0 <= seq < count:
                continue
            use_int = msg.get_type() == "MISSION_REQUEST_INT"

            def send_item_seq(seq: int = seq, use_int: bool = use_int) -> None:
                send_item(self.mav, items[seq], seq=seq, target_system=ts, target_component=tc, use_int=use_int)

            resend = send_item_seq
            resend()
            sent_last = sent_last or seq == count - 1

    def download_mission(self, mission_type: MissionType = MissionType.MISSION) -> list[MissionItem]:
        """The vehicle's current ``mission_type`` list."""
        mtype = int(mission_type)
        ts, tc = self.target_system, self.target_component

        def is_count(msg: Msg) -> Msg | None:
            if msg.get_type() == "MISSION_COUNT" and int(getattr(msg, "mission_type", 0)) == mtype:
                return msg
            return None

        reply = self._exchange(lambda: self.mav.mission_request_list_send(ts, tc, mtype), is_count, "MISSION_COUNT")
        items = [self._download_item(seq, mtype) for seq in range(int(reply.count))]
        self.mav.mission_ack_send(ts, tc, int(MissionResult.ACCEPTED), mtype)
        return items

    def _download_item(self, seq: int, mtype: int) -> MissionItem:
        """Item ``seq``; an error ACK is believed (MissionDownloadError) when the vehicle repeats it for the item
        asked again; an ACCEPTED ACK is a late copy of an earlier upload's and is not about this download."""
        ts, tc = self.target_system, self.target_component

        def is_item(msg: Msg) -> Msg | None:
            kind = msg.get_type()
            if kind == "MISSION_ACK" and int(getattr(msg, "mission_type", 0)) == mtype:
                return msg if msg.type != int(MissionResult.ACCEPTED) else None
            if kind == "MISSION_ITEM_INT" and int(msg.seq) == seq and int(msg.mission_type) == mtype:
                return msg
            return None

        doubted = False
        while True:
            msg = self._exchange(
                lambda: self.mav.mission_request_int_send(ts, tc, seq, mtype), is_item, f"mission item {seq}"
            )
            if msg.get_type() != "MISSION_ACK":
                return item_from_msg(msg)
            if doubted:
                raise MissionDownloadError(f"download refused at item {seq}: {_mission_result(msg.type).name}")
            doubted = True

    def clear_mission(self, mission_type: MissionType = MissionType.MISSION) -> None:
        """MISSION_CLEAR_ALL; MissionUploadError if the vehicle refuses."""
        mtype = int(mission_type)
        serial = self.statustext_serial
        ts, tc = self.target_system, self.target_component
        ack = self._exchange(
            lambda: self.mav.mission_clear_all_send(ts, tc, mtype),
            self._mission_reply_matcher(mtype, ()),
            "MISSION_ACK",
        )
        result = _mission_result(ack.type)
        if result is not MissionResult.ACCEPTED:
            raise MissionUploadError(result, self._reason(serial, result.name))

    def set_current_item(self, seq: int) -> None:
        """MISSION_SET_CURRENT; waits for MISSION_CURRENT to report ``seq``."""
        ts, tc = self.target_system, self.target_component

        def is_current(msg: Msg) -> Msg | None:
            return msg if msg.get_type() == "MISSION_CURRENT" and int(msg.seq) == seq else None

        self._exchange(lambda: self.mav.mission_set_current_send(ts, tc, seq), is_current, "MISSION_CURRENT")

    def _mission_reply_matcher(self, mtype: int, kinds: tuple[str, ...]) -> Callable[[Msg], Msg | None]:
        def match(msg: Msg) -> Msg | None:
            kind = msg.get_type()
            wanted = (kind == "MISSION_ACK" or kind in kinds) and int(getattr(msg, "mission_type", 0)) == mtype
            if wanted and int(getattr(msg, "target_system", 0)) in (0, self.mav.srcSystem):
                return msg
            return None

        return match


def _mission_result(raw: int) -> MissionResult:
    try:
        return MissionResult(int(raw))
    except ValueError:
        return MissionResult.ERROR
