"""The ground station's mission protocol: upload, download, clear and set-current, with retries."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from mavlink_bridge.contract.vehicle_api import MissionItem, MissionResult, MissionType
from mavlink_bridge.gcs_client.errors import MissionDownloadError, MissionUploadError
from mavlink_bridge.gcs_client.session import GcsSession, Msg
from mavlink_bridge.wire.mission_items import MissionItemEncodeError, item_from_msg, send_item, xy_to_int


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
        retries = 0
        max_retries = max(1, round(self.timeout_s / self.retry_s))
        while True:
            msg = self._wait(
                self._mission_reply_matcher(mtype, ("MISSION_REQUEST_INT", "MISSION_REQUEST")), self.retry_s
            )
            if msg is None:
                retries += 1
                if retries > max_retries:
                    self.mav.mission_ack_send(ts, tc, int(MissionResult.OPERATION_CANCELLED), mtype)
                    raise MissionUploadError(MissionResult.OPERATION_CANCELLED, "the vehicle stopped answering")
                resend()
                continue
            retries = 0
            if msg.get_type() == "MISSION_ACK":
                result = _mission_result(msg.type)
                if result is MissionResult.ACCEPTED:
                    if sent_last:
                        return
                    continue  # a stale ACK of an earlier transfer
                raise MissionUploadError(result, self._reason(serial, result.name))
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
        items: list[MissionItem] = []
        for seq in range(int(reply.count)):

            def is_item(msg: Msg, seq: int = seq) -> Msg | None:
                kind = msg.get_type()
                if kind == "MISSION_ACK" and int(getattr(msg, "mission_type", 0)) == mtype:
                    if msg.type == int(MissionResult.ACCEPTED):
                        return None  # a late or duplicated ACK of an earlier upload: not about this download
                    raise MissionDownloadError(f"download refused at item {seq}: {_mission_result(msg.type).name}")
                if kind == "MISSION_ITEM_INT" and int(msg.seq) == seq and int(msg.mission_type) == mtype:
                    return msg
                return None

            msg = self._exchange(
                lambda seq=seq: self.mav.mission_request_int_send(ts, tc, seq, mtype), is_item, f"mission item {seq}"
            )
            items.append(item_from_msg(msg))
        self.mav.mission_ack_send(ts, tc, int(MissionResult.ACCEPTED), mtype)
        return items

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
