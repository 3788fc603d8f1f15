"""MISSION and FENCE uploads accepted whenever they arrive, checked against home once it is known (issue 13, 15).

QGroundControl and scripts sync both on connect, often before the vehicle's first position fix. PX4
stores them and checks the mission against home and the geofence when it can; so does
:class:`UploadStore`, with the checks that need no home done at once (issue 22): an upload is refused
at once, whatever the fix, when it is malformed or when an item given in a global frame lies inside an
exclusion zone or outside the inclusion zones (:func:`autopilot.mission.zone_check.zone_issue`, the
same reason before and after the fix). Otherwise it is accepted (the fence stored geodetically), and
once home is known the fence is made local and what needs home (MIS_DIST_MAX, GF_MAX_HOR_DIST, the
ceiling over home, local-frame items, routes: :func:`autopilot.mission.feasibility.check_feasibility`)
decides whether it may be flown; a mission failing then is reported and never started. An upload that
is refused, or a mission found infeasible later, comes with a STATUSTEXT-ready sentence naming the item.

Pure: no clock or I/O; the caller (the navigator) sends :attr:`UploadStore.texts` and sets
``mission_ready`` from :attr:`UploadStore.flyable`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from autopilot.geofence.fence import FenceError, GeoFence, Geofence, geo_fence_from_items
from autopilot.mission.feasibility import FeasibilityLimits, check_feasibility
from autopilot.mission.plan import DEFAULT_HOME_TOL, HomeTolerance
from autopilot.mission.validation import MissionIssue, MissionLimits, check_mission
from autopilot.mission.zone_check import zone_issue
from autopilot.planner.route_graph import KnownWorld
from mavlink_bridge.contract.frames import GeoPoint
from mavlink_bridge.contract.vehicle_api import MissionItem, MissionResult, MissionType, Severity


@dataclass(frozen=True, slots=True)
class UploadText:
    """A STATUSTEXT the store wants sent."""

    severity: Severity
    text: str


class UploadStore:
    """The accepted MISSION and FENCE item lists, the fence (geodetic and, once home is known, local) and
    whether the mission may be flown."""

    def __init__(self) -> None:
        self.mission: list[MissionItem] = []
        self.fence_items: list[MissionItem] = []
        self.geo_fence = GeoFence()
        self.fence = Geofence()  # about home; empty until home is known
        self.home: GeoPoint | None = None
        self.home_tol = DEFAULT_HOME_TOL  # how far a WPL home line may lie from home (the GPS accuracy at the fix)
        self.world: KnownWorld | None = None  # the fence inflated by the margin (route planning)
        self.mission_issue: str = ""  # why the accepted mission may not be flown (empty: it may)
        self.texts: list[UploadText] = []
        self._limits = FeasibilityLimits()
        self._mission_limits = MissionLimits()

    @property
    def flyable(self) -> bool:
        """A mission is stored, home is known and it passed the feasibility checks."""
        return bool(self.mission) and self.home is not None and not self.mission_issue

    def drain_texts(self) -> list[UploadText]:
        texts, self.texts = self.texts, []
        return texts

    def _say(self, text: str, severity: Severity = Severity.INFO) -> None:
        self.texts.append(UploadText(severity, text))

    def set_limits(self, limits: FeasibilityLimits, mission_limits: MissionLimits) -> None:
        """New limits (parameter changes): the fence world and the mission are checked again."""
        changed = limits != self._limits
        self._limits, self._mission_limits = limits, mission_limits
        if changed and self.home is not None:
            self._localise()
            self._recheck("with the new limits")

    def upload(self, mission_type: MissionType, items: Sequence[MissionItem]) -> tuple[MissionResult, str]:
        """Accept or refuse an upload; a refusal's reason names the item and is also queued as a STATUSTEXT."""
        if mission_type is MissionType.FENCE:
            return self._upload_fence(items)
        if mission_type is not MissionType.MISSION:
            return MissionResult.UNSUPPORTED, f"mission type {mission_type.name} is not supported"
        issue = self._mission_issue(items)
        if issue is not None:
            self._say(f"Mission refused: {issue.reason}", Severity.WARNING)
            return issue.result, issue.reason
        self.mission = list(items)
        self.mission_issue = ""
        pending = " (checked against home and the fence once home is known)" if self.home is None and items else ""
        self._say(f"Mission: {len(items)} items{pending}")
        return MissionResult.ACCEPTED, ""

    def _upload_fence(self, items: Sequence[MissionItem]) -> tuple[MissionResult, str]:
        issue = check_mission(items, self.home, self._mission_limits, self.home_tol) if items else None
        if issue is not None:
            self._say(f"Fence refused: fence {issue.reason}", Severity.WARNING)
            return issue.result, f"fence {issue.reason}"
        try:
            geo = geo_fence_from_items(items)
        except FenceError as exc:  # check_mission parses it too: kept for a clear message if they ever differ
            self._say(f"Fence refused: {exc}", Severity.WARNING)
            return MissionResult.INVALID, str(exc)
        self.fence_items, self.geo_fence = list(items), geo
        pending = " (placed once home is known)" if self.home is None and items else ""
        self._say(f"Geofence: {len(items)} items, {len(geo.zones)} zones{pending}")
        if self.home is not None:
            self._localise()
        if self.mission:
            self._recheck("with the new fence")
        return MissionResult.ACCEPTED, ""

    def set_home(self, home: GeoPoint, home_tol: HomeTolerance = DEFAULT_HOME_TOL) -> None:
        """Home is known (or moved): the fence is made local and the stored mission checked again."""
        self.home, self.home_tol = home, home_tol
        self._localise()
        if self.mission:
            self._recheck("from home")

    def _localise(self) -> None:
        assert self.home is not None
        self.fence = self.geo_fence.to_local(self.home)
        self.world = KnownWorld(self.fence, self._limits.margin_m) if self.fence.zones else None
        if self.fence.zones and self.fence.violates((0.0, 0.0, 0.0)):
            self._say("Geofence: home lies outside the fence (inside a no-fly zone or outside the inclusion zones)",
                      Severity.WARNING)  # fmt: skip

    def _mission_issue(self, items: Sequence[MissionItem]) -> MissionIssue | None:
        """Why ``items`` may not be flown: first what needs no home (the same answer whatever the fix), then, once
        home is known, what needs it."""
        issue = check_mission(items, None, self._mission_limits) or zone_issue(items, self.geo_fence)
        if issue is None and self.home is not None and items:
            issue = check_mission(items, self.home, self._mission_limits, self.home_tol) or check_feasibility(
                items, self.home, self.fence, self._limits, self.world, self.home_tol
            )
        return issue

    def _recheck(self, context: str) -> None:
        issue = self._mission_issue(self.mission)
        was = self.mission_issue
        self.mission_issue = issue.reason if issue is not None else ""
        if issue is not None and issue.reason != was:
            self._say(f"Mission not flyable {context}: {issue.reason}", Severity.WARNING)
        elif issue is None and was:
            self._say(f"Mission flyable {context}")
