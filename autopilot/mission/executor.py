"""The vehicle-agnostic mission executor (SPEC §8; ArduPilot ``AP_Mission`` style, STYLE §5).

Items are data; the executor is a pure state machine stepped with the sim time and the
vehicle's local NED state (about ``home``). Each :meth:`MissionExecutor.step` returns an
:class:`ExecutorOutput`: the :class:`NavTarget` the setpoint generator should fly, the items
reached during the step (MISSION_ITEM_REACHED), one-shot :class:`MissionAction` s (gripper),
and the MISSION_CURRENT values (``current_seq``, ``state``).

Semantics:

- NAV_TAKEOFF climbs at the current (or given) horizontal position; done within
  ``alt_accept_m`` of the altitude (a vehicle already higher is done at once).
- NAV_WAYPOINT is reached inside the acceptance radius (param2, else ``accept_radius_m``)
  horizontally and ``alt_accept_m`` vertically, then holds param1 seconds. With no hold and
  a following waypoint the target is pass-through and carries ``next_pos_ned_m`` (lookahead
  through DO items and DO_JUMPs) so the setpoint generator can blend corners.
- NAV_LOITER_TIME flies to its position (lat = lon = 0: where it starts) and holds param1 s;
  NAV_DELAY holds where it starts for param1 s.
- NAV_LAND descends at its position (lat = lon = 0: current) until the vehicle reports landed.
- NAV_RETURN_TO_LAUNCH climbs to ``rtl_alt_m`` if lower, flies home at that altitude, lands.
- DO_CHANGE_SPEED (param2 > 0 sets, -2 restores the default, -1 keeps), DO_GRIPPER (an action)
  and DO_JUMP (param1 target, param2 repeats, -1 forever) complete in the step they start.
- Pause holds where the vehicle is and freezes hold timers; resume continues the same item.
  Once complete the target holds where the mission ended (IDLE when landed); with no mission
  or before start the target is None (the commander decides what to fly).
- A mission replaced while ACTIVE or PAUSED continues the item being flown when the new list
  has the identical item at the same seq (no restart), else at the first identical item,
  else restarts at seq 0 (a takeoff below the current altitude then completes at once).
  Jump counters restart with every new mission.

Route and skipping (issue 6, obstacle avoidance; SPEC §7-§8):

- :meth:`MissionExecutor.route_ahead` lists the positional items (NAV_WAYPOINT, NAV_LOITER_TIME with a
  position) from the current one on, in execution order (DO items passed over, pending DO_JUMPs followed
  with their counters as they stand), up to a path length: the route the avoidance planner checks.
- :meth:`MissionExecutor.skip_to` moves on to a later item of that order when a detour bypassed the
  items in between (or they lie inside an obstacle). Skipped positional items are reported as *bypassed*
  (``ExecutorOutput.bypassed``, in order, in the next step's output), never as reached: the vehicle flew
  around them (issue 13, honest progress). Only positional route items are skipped: DO items on the way are
  *executed* (and reported reached), never dropped (a DO_GRIPPER between skipped waypoints still fires,
  DO_CHANGE_SPEED applies, DO_JUMP counts and is followed), and takeoff, land, RTL, delay and position-less
  loiters are never skipped over (``skip_to`` refuses).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import replace

from autopilot.mission.executor_types import (
    ActionKind,
    ExecutorConfig,
    ExecutorOutput,
    MissionAction,
    MissionRoute,
    NavKind,
    NavTarget,
    VehicleSample,
)
from autopilot.mission.nav_target import ItemPhase as _Phase
from autopilot.mission.nav_target import phase_target
from autopilot.mission.plan import DEFAULT_HOME_TOL, HomeTolerance, is_wpl_home_line, item_position_ned, items_match
from autopilot.mission.plan import uses_current_position as _at_current_position
from autopilot.mission.route_ahead import DO_ITEMS as _DO_ITEMS
from autopilot.mission.route_ahead import SKIPPABLE as _SKIPPABLE
from autopilot.mission.route_ahead import execution_order, next_position, route_through
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame, Vec3
from mavlink_bridge.contract.mav_enums import GripperAction, MavCmd, MissionState
from mavlink_bridge.contract.vehicle_api import MissionItem

_NAN = float("nan")


def _hdist(a: Sequence[float], b: Sequence[float]) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


class MissionExecutor:
    """Steps a MISSION item list; see the module docstring for the semantics."""

    def __init__(self, home: GeoPoint, config: ExecutorConfig | None = None) -> None:
        self._frame = LocalNedFrame(home)
        self._home_tol = DEFAULT_HOME_TOL  # how far a WPL home line may lie from home
        self.config = config or ExecutorConfig()
        self._items: list[MissionItem] = []
        self._pos_ned: list[Vec3 | None] = []
        self._jumps_done: list[int] = []
        self._state = MissionState.NO_MISSION
        self._cur = 0
        self._phase = _Phase.START
        self._goal: Vec3 = (0.0, 0.0, 0.0)
        self._hold_start_us = 0
        self._hold_s = 0.0
        self._jump_to = -1
        self._speed_override: float | None = None
        self._target: NavTarget | None = None
        self._paused_at_us = 0
        self._hold_pos: Vec3 | None = None
        self._skipped: list[int] = []  # skip_to's reached items and actions, reported by the next step
        self._skip_actions: list[MissionAction] = []
        self._route_key: tuple[int, int, float, int] | None = None
        self._route: MissionRoute | None = None
        self._version = 0  # bumped when items or their positions change (route cache)

    # ------------------------------------------------------------------ queries

    @property
    def state(self) -> MissionState:
        return self._state

    @property
    def current_seq(self) -> int:
        """MISSION_CURRENT.seq: the item being flown (the last item once complete)."""
        return self._cur

    @property
    def items(self) -> list[MissionItem]:
        return list(self._items)

    @property
    def speed_m_s(self) -> float:
        return self._speed_override if self._speed_override is not None else self.config.cruise_speed_m_s

    # ------------------------------------------------------------------ commands

    def configure(self, config: ExecutorConfig) -> None:
        """New settings (parameters changed in flight); the current target is rebuilt."""
        self.config = config
        self._target = None

    def set_home(self, home: GeoPoint, home_tol: HomeTolerance = DEFAULT_HOME_TOL) -> None:
        """Move the local NED origin (positions of the items are recomputed); ``home_tol``: see ``is_wpl_home_line``."""
        self._frame, self._home_tol = LocalNedFrame(home), home_tol
        self._pos_ned = [self._item_pos(it) for it in self._items]
        self._target = None
        self._version += 1

    def _item_pos(self, item: MissionItem) -> Vec3 | None:
        if item.command not in (MavCmd.NAV_WAYPOINT, MavCmd.NAV_LOITER_TIME, MavCmd.NAV_TAKEOFF, MavCmd.NAV_LAND):
            return None
        if _at_current_position(item):
            return None
        return item_position_ned(item, self._frame)

    def set_mission(self, items: Sequence[MissionItem]) -> int:
        """Install a validated item list; returns the seq that will be flown next (policy in the module doc)."""
        old, old_cur, old_phase = self._items, self._cur, self._phase
        self._items = list(items)
        self._pos_ned = [self._item_pos(it) for it in self._items]
        self._jumps_done = [0] * len(self._items)
        self._target = None
        self._version += 1
        flying = self._state in (MissionState.ACTIVE, MissionState.PAUSED)
        if not self._items:
            self._cur, self._phase = 0, _Phase.START
            self._state = MissionState.NO_MISSION
            return 0
        if not flying:
            self._cur, self._phase = 0, _Phase.START
            self._state = MissionState.NOT_STARTED
            return 0
        current = old[old_cur] if old_cur < len(old) else None
        if current is not None and old_cur < len(self._items) and items_match([self._items[old_cur]], [current]):
            self._cur, self._phase = old_cur, old_phase
            return self._cur
        same = [
            k
            for k, it in enumerate(self._items)
            if current is not None and items_match([replace(it, seq=0)], [replace(current, seq=0)])
        ]
        self._cur = same[0] if same else 0
        self._phase = _Phase.START
        return self._cur

    def start(self, time_us: int, seq: int | None = None) -> bool:
        """MISSION_START: run from ``seq`` (default: the current item, or 0 after completion). False if impossible."""
        if not self._items:
            return False
        if seq is None:
            seq = 0 if self._state == MissionState.COMPLETE else self._cur
        if not 0 <= seq < len(self._items):
            return False
        if self._state in (MissionState.NOT_STARTED, MissionState.COMPLETE):
            self._jumps_done = [0] * len(self._items)
            self._speed_override = None
        if self._state == MissionState.PAUSED and seq == self._cur:
            return self.resume(time_us)
        self._cur, self._phase = seq, _Phase.START
        self._state = MissionState.ACTIVE
        self._target = None
        return True

    def set_current(self, seq: int) -> bool:
        """MISSION_SET_CURRENT: fly ``seq`` next (restarting that item). False when out of range."""
        if not 0 <= seq < len(self._items):
            return False
        self._cur, self._phase = seq, _Phase.START
        if self._state == MissionState.COMPLETE:
            self._state = MissionState.NOT_STARTED
        self._target = None
        return True

    def pause(self, time_us: int) -> bool:
        """Hold where the vehicle is; hold timers freeze. False unless ACTIVE."""
        if self._state != MissionState.ACTIVE:
            return False
        self._state = MissionState.PAUSED
        self._paused_at_us = time_us
        self._hold_pos = None
        self._target = None
        return True

    def resume(self, time_us: int) -> bool:
        """Continue the paused item (hold timers resume where they stopped). False unless PAUSED."""
        if self._state != MissionState.PAUSED:
            return False
        self._hold_start_us += time_us - self._paused_at_us
        self._state = MissionState.ACTIVE
        self._target = None
        return True

    def skip_to(self, seq: int, time_us: int) -> bool:
        """Skip from the current item to ``seq`` (later in execution order); see the module docstring.

        The current item and every item before ``seq`` are reported reached (in order) by the next
        :meth:`step`; DO items on the way run (gripper actions stamped ``time_us``). False, and nothing
        changes, unless ACTIVE and ``seq`` follows within positional items and DO items only.
        """
        if self._state != MissionState.ACTIVE or not 0 <= seq < len(self._items) or seq == self._cur:
            return False
        jumps: dict[int, int] = {}
        walked: list[int] = []
        for k in self._execution_order(self._cur, jumps):
            if k == seq and walked:
                break
            item = self._items[k]
            if item.command not in _DO_ITEMS and (item.command not in _SKIPPABLE or self._pos_ned[k] is None):
                return False
            walked.append(k)
        else:
            return False
        for k in walked:
            item = self._items[k]
            if item.command == MavCmd.DO_CHANGE_SPEED:
                if item.param2 > 0.0:
                    self._speed_override = item.param2
                elif item.param2 == -2.0:
                    self._speed_override = None
            elif item.command == MavCmd.DO_GRIPPER:
                kind = ActionKind.GRIPPER_RELEASE if item.param2 == GripperAction.RELEASE else ActionKind.GRIPPER_GRAB
                self._skip_actions.append(MissionAction(kind, k, time_us, int(item.param1) or 1))
        for k, done in jumps.items():
            self._jumps_done[k] = done
        self._skipped += walked
        self._cur, self._phase = seq, _Phase.START
        self._target = None
        return True

    def route_ahead(self, min_length_m: float, max_points: int) -> MissionRoute:
        """The current and following positional items (module docstring) until the path through them is at
        least ``min_length_m`` long or ``max_points`` are listed. Cached until the current item changes."""
        key = (self._cur, self._version, min_length_m, max_points)
        if key == self._route_key and self._route is not None:
            return self._route
        order: Iterable[int] = ()
        if self._items and self._state in (MissionState.ACTIVE, MissionState.PAUSED):
            order = self._execution_order(self._cur, {})
        self._route = route_through(self._items, self._pos_ned, order, min_length_m, max_points)
        self._route_key = key
        return self._route

    def _execution_order(self, start: int, jumps: dict[int, int]) -> Iterator[int]:
        """Item indices from ``start`` on as they would run (:func:`execution_order`)."""
        return execution_order(self._items, self._jumps_done, start, jumps)

    # ------------------------------------------------------------------ stepping

    def step(self, sample: VehicleSample) -> ExecutorOutput:
        """Advance with the vehicle state at ``sample.time_us``; returns the target and this step's events."""
        reached: list[int] = []
        actions: list[MissionAction] = []
        bypassed: tuple[int, ...] = ()
        if self._skipped or self._skip_actions:
            items = self._items
            reached += [k for k in self._skipped if items[k].command in _DO_ITEMS]  # they ran
            bypassed = tuple(k for k in self._skipped if items[k].command not in _DO_ITEMS)
            actions += self._skip_actions
            self._skipped, self._skip_actions = [], []
        if self._state == MissionState.ACTIVE:
            for _ in range(len(self._items) + 1):  # DO items and instant completions chain within one step
                if self._phase == _Phase.START:
                    self._begin(sample)
                if not self._advance(sample, actions):
                    break
                reached.append(self._cur)
                nxt = self._jump_to if self._jump_to >= 0 else self._cur + 1
                self._jump_to = -1
                if nxt >= len(self._items):
                    self._state = MissionState.COMPLETE
                    self._hold_pos = sample.pos_ned_m
                    self._target = None
                    break
                self._cur, self._phase = nxt, _Phase.START
        if self._target is None:
            self._target = self._make_target(sample)
        return ExecutorOutput(
            self._state,
            self._cur,
            self._target,
            tuple(reached) if reached else (),
            tuple(actions) if actions else (),
            self.speed_m_s,
            bypassed,
        )

    def _begin(self, s: VehicleSample) -> None:
        item = self._items[self._cur]
        cmd = item.command
        pos = self._pos_ned[self._cur]
        p = s.pos_ned_m
        self._target = None
        if cmd == MavCmd.NAV_TAKEOFF:
            n, e = (pos[0], pos[1]) if pos is not None else (p[0], p[1])
            self._goal, self._phase = (n, e, -item.z_alt_m), _Phase.CLIMB
        elif cmd == MavCmd.NAV_WAYPOINT:
            assert pos is not None
            self._goal, self._phase, self._hold_s = pos, _Phase.APPROACH, item.param1
        elif cmd == MavCmd.NAV_LOITER_TIME:
            self._goal = pos if pos is not None else p
            self._phase, self._hold_s = _Phase.APPROACH, item.param1
        elif cmd == MavCmd.NAV_DELAY:
            self._goal, self._phase, self._hold_s, self._hold_start_us = p, _Phase.HOLD, item.param1, s.time_us
        elif cmd == MavCmd.NAV_LAND:
            n, e = (pos[0], pos[1]) if pos is not None else (p[0], p[1])
            self._goal, self._phase = (n, e, 0.0), _Phase.DESCEND
        elif cmd == MavCmd.NAV_RETURN_TO_LAUNCH:
            alt = -p[2]
            if s.landed and _hdist(p, (0.0, 0.0)) <= self.config.accept_radius_m:
                self._goal, self._phase = (0.0, 0.0, 0.0), _Phase.DESCEND
            elif alt < self.config.rtl_alt_m - self.config.alt_accept_m:
                self._goal, self._phase = (p[0], p[1], -self.config.rtl_alt_m), _Phase.CLIMB
            else:
                self._goal, self._phase = (0.0, 0.0, min(p[2], -self.config.rtl_alt_m)), _Phase.RETURN
        else:
            self._phase = _Phase.HOLD  # DO items complete in _advance

    def _accept_radius(self, item: MissionItem) -> float:
        if item.command == MavCmd.NAV_WAYPOINT and item.param2 > 0.0:
            return item.param2
        return self.config.accept_radius_m

    def _advance(self, s: VehicleSample, actions: list[MissionAction]) -> bool:
        """Run the current item's phases as far as this sample allows; True when the item is complete."""
        item = self._items[self._cur]
        cmd = item.command
        if is_wpl_home_line(self._cur, item, self._frame.home, self._home_tol):
            return True  # MAVProxy's home entry: acknowledged, never flown to
        if cmd == MavCmd.DO_CHANGE_SPEED:
            if item.param2 > 0.0:
                self._speed_override = item.param2
            elif item.param2 == -2.0:
                self._speed_override = None
            return True
        if cmd == MavCmd.DO_GRIPPER:
            kind = ActionKind.GRIPPER_RELEASE if item.param2 == GripperAction.RELEASE else ActionKind.GRIPPER_GRAB
            actions.append(MissionAction(kind, self._cur, s.time_us, int(item.param1) or 1))
            return True
        if cmd == MavCmd.DO_JUMP:
            repeat = int(item.param2)
            if repeat < 0 or self._jumps_done[self._cur] < repeat:
                self._jumps_done[self._cur] += 1
                self._jump_to = int(item.param1)
            return True
        p, cfg, rtl = s.pos_ned_m, self.config, cmd == MavCmd.NAV_RETURN_TO_LAUNCH
        while True:
            phase = self._phase
            if phase == _Phase.CLIMB:
                if -p[2] < -self._goal[2] - cfg.alt_accept_m:
                    return False
                if not rtl:
                    return True
                self._goal, self._phase = (0.0, 0.0, self._goal[2]), _Phase.RETURN
            elif phase == _Phase.RETURN:
                if _hdist(p, self._goal) > cfg.accept_radius_m:
                    return False
                self._goal, self._phase = (0.0, 0.0, 0.0), _Phase.DESCEND
            elif phase == _Phase.APPROACH:
                if _hdist(p, self._goal) > self._accept_radius(item) or abs(p[2] - self._goal[2]) > cfg.alt_accept_m:
                    return False
                if self._hold_s <= 0.0:
                    return True
                self._phase, self._hold_start_us = _Phase.HOLD, s.time_us
            elif phase == _Phase.HOLD:
                return s.time_us - self._hold_start_us >= round(self._hold_s * 1e6)
            elif phase == _Phase.DESCEND:
                return s.landed
            else:
                return False
            self._target = None

    def _make_target(self, s: VehicleSample) -> NavTarget | None:
        speed, acc = self.speed_m_s, self.config.accept_radius_m
        if self._state in (MissionState.PAUSED, MissionState.COMPLETE):
            if self._hold_pos is None:
                self._hold_pos = s.pos_ned_m
            kind = NavKind.IDLE if s.landed else NavKind.LOITER
            return NavTarget(kind, -1, self._hold_pos, _NAN, speed, acc)
        if self._state != MissionState.ACTIVE:
            return None
        item = self._items[self._cur]
        lookahead = None
        if self._phase == _Phase.APPROACH and self._hold_s <= 0.0 and item.command == MavCmd.NAV_WAYPOINT:
            lookahead = next_position(self._items, self._pos_ned, self._execution_order(self._cur + 1, {}))
        radius = self._accept_radius(item)
        return phase_target(self._phase, item, self._cur, self._goal, speed, acc, radius, lookahead, s.landed)
