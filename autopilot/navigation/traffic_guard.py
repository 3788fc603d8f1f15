"""The reactive layer in the control loop (SPEC §13): bounds the reference of every autonomous phase so that no
track comes inside its separation volume.

Every navigator step (50 Hz) the :class:`ReactiveLayer` is asked for the velocity to fly instead of the one the
reference would fly (its velocity plus a pull toward it); while it gives one, every control step flies a
reference about the vehicle at a velocity that moves toward it within the acceleration limit (PX4's velocity
control: the position error is zero, the velocity is the command). When the preferred velocity is admissible again
(after ``MIN_ENGAGED_US``), the setpoint generator goes on from that reference. Also here, because they concern the
column above the pad:

- the departure hold: on the pad (below ``GROUND_LOCK_AGL_M``) in a take-off, no climb (and no other motion)
  while a UAV is predicted through the climb-out column before the vehicle would be up (at ``MPC_TKO_SPEED``), or
  a manned aircraft within the look-ahead (``NAV_TRAFF_COLL_T``): once up, a multirotor cannot leave an NMAC volume
  150 m wide in the warning a pass gives, so it waits on the pad, where it is no hazard, for the aircraft to pass;
  it ends once the column has been clear ``DEPARTURE_CLEAR_US``;
- the landing clearance: in a landing, no touchdown on a UAV: while one stands on the spot or hovers over it
  lower down (taking off, holding), the vehicle waits level beside the pad, outside the occupant's climb-out
  column, and goes back over the spot once it has left; and no descent while a track is predicted through the
  column below. Below ``GROUND_LOCK_AGL_M`` over its spot (within ``LANDING_RADIUS_M``) a landing is committed:
  the layer lets it touch down (a vehicle landing has right of way; holding or moving a metre above the pad only
  delays the touchdown and skids across the pads); pushed farther aside it is held in the air, above the floor;
- the altitude-change corridor: in a mission, hold or return, no climb or descent while a track passing by is
  predicted through the levels the change enters (:func:`autopilot.traffic.columns.corridor_threat`) before it
  would be through: two vehicles changing levels through each other pass
  level, apart by the difference, and change once clear.

Texts: one when avoidance starts (naming the track and the phase), one when the fallback starts, one when it ends.
"""

from __future__ import annotations

import math

from autopilot.navigation.home_frame import HomeFrame
from autopilot.navigation.outputs import ReferenceOverride
from autopilot.parameters.store import ParamStore
from autopilot.traffic.columns import COLUMN_MARGIN_S, CORRIDOR_MIN_M_S, column_conflict, corridor_threat
from autopilot.traffic.param_decls import TrafficAction, TrafficParams
from autopilot.traffic.reactive import (
    GROUND_LOCK_AGL_M,
    FenceZoneLike,
    Phase,
    ReactiveCommand,
    ReactiveLayer,
    ReactiveLimits,
    uncertainty_m,
)
from autopilot.traffic.rules import COLUMN_SPEED_M_S, parked
from autopilot.traffic.tracks import TrackTable, TrafficTrack
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.traffic import TrafficSource
from mavlink_bridge.contract.vehicle_api import FlightMode, Severity, StatusText

#: Solve at most this often (µs of sim time): the navigator's rate; and, while the velocity flown keeps more than
#: CLEAR_SLACK_M_S from every track's plane (no track can close that in the interval: 0.1 s x 3 m/s^2 x 2), at
#: CLEAR_PERIOD_US.
SOLVE_PERIOD_US = 20_000
CLEAR_PERIOD_US = 100_000
CLEAR_SLACK_M_S = 1.0
#: Once engaged, the reactive reference is flown at least this long (µs): no chattering between the two.
MIN_ENGAGED_US = 1_000_000
#: An avoidance shorter than this (µs) ends without a text, and the next one says its start only if it changed.
QUIET_US = 5_000_000
#: A change of the kind of avoidance (reactive, fallback, take-off held) is said at most this often (µs).
SAY_KIND_US = 1_000_000
#: The preferred velocity pulls toward the reference position with this gain (1/s), at most this fast (m/s).
PULL_GAIN_1_S = 1.0
PULL_MAX_M_S = 3.0
#: A landing waits while a track is predicted through the column below within this time (s): one that would cross
#: it later meets a vehicle descending, which the reactive layers of both keep apart.
LANDING_WINDOW_S = 5.0
#: The altitude-change corridor (:func:`corridor_threat`) is checked in these phases.
CORRIDOR_PHASES = (Phase.MISSION, Phase.HOLD, Phase.RETURN)
#: A landing whose spot has a UAV on it or hovering over it (on the ground, taking off, holding: slower than
#: COLUMN_SPEED_M_S within PAD_RADIUS_VOLUMES of the grown volume of the spot, its report's accuracy added: a pad
#: a metre or two off, not a neighbouring pad, which the encounter worlds keep 20 m away and a user's world may
#: put 12 m away) waits beside the pad, PAD_ASIDE_VOLUMES volumes from the occupant:
#: outside the occupant's climb-out column, so its departure is not held for the waiting vehicle (which would
#: never end), and back over the spot once the occupant has left (encounter case 168: a ring-swap vehicle landed
#: 2 m from one whose take-off was held, and they touched on the ground).
PAD_RADIUS_VOLUMES = 0.5
PAD_ASIDE_VOLUMES = 2.0
#: ... at least this high above home (m): pushed lower (by the layer, down to CA_MIN_AGL_M) it climbs back.
PAD_HOLD_AGL_M = 5.0
#: The command's ``escape`` while a landing waits beside an occupied pad.
PAD_HELD = "landing held beside the pad"
#: The climb-out column of a departure reaches this high above the pad (m): above a delivery drone's cruise.
DEPARTURE_COLUMN_M = 30.0
#: The command's ``escape`` while the departure hold is in force.
TAKEOFF_HELD = "take-off held"
#: The departure hold ends once the column has been clear this long (µs): released at the first clear check, a
#: hold that a track's noise brings back a moment later steps the motors between idle and hover a few centimetres
#: over the pad (encounter case 625: held and released every 0.25-0.5 s, the vehicle tipped 19 degrees onto it).
DEPARTURE_CLEAR_US = 2_000_000
#: A held take-off that had left the pad goes back down at this speed (m/s): onto the pad while the commander's
#: take-off has not left it (no land detection then), else to this height (m) over it (a touchdown in the air
#: would be a landing, and disarm).
HELD_AGL_M = 0.5
#: A take-off's climb to ``GROUND_LOCK_AGL_M`` stays within this (m) of where it left the ground: a vehicle low and
#: climbing farther away is not taking off (failure search of the depot with a helicopter, case 3: one pushed down
#: to the floor 260 m from its pad was held as a take-off and sank to 0.7 m, unable to move aside).
DEPARTURE_RADIUS_M = 5.0
#: A landing is over its spot within this (m) of the touchdown point: only there is it committed below
#: ``GROUND_LOCK_AGL_M``, locked to vertical moves and free of the altitude floor. One the layer pushed aside is
#: not landing there (encounter case 84: a landing vehicle pushed 45 m aside by a helicopter's plane sank under the
#: floor, was released as committed at 1.7 m and flew back to its pad at that height through another vehicle's
#: escape: 9.1 m).
LANDING_RADIUS_M = 5.0
HELD_DESCENT_M_S = 0.5
#: A held take-off that has stayed this low over its pad (m, the estimate's height about home) and this slow (m/s,
#: vertical) for PAD_SETTLE_US (µs) sits on it: the caller flies nothing, motors at idle and no integrator winding
#: up against the ground (PX4's ready-for-takeoff) until the hold ends. Not at once: a hold that comes back a moment
#: after its release finds the vehicle a few centimetres up, and idle motors there drop it with no attitude control
#: (encounter case 267: it touched down rolled 21 degrees); the hold's descent puts it down first.
PAD_CONTACT_AGL_M = 0.1
PAD_SETTLE_M_S = 0.2
PAD_SETTLE_US = 1_000_000

_PHASES = {
    FlightMode.AUTO_TAKEOFF: Phase.TAKEOFF,
    FlightMode.AUTO_MISSION: Phase.MISSION,
    FlightMode.AUTO_LOITER: Phase.HOLD,
    FlightMode.AUTO_RTL: Phase.RETURN,
    FlightMode.AUTO_LAND: Phase.LAND,
}


def _pull_m_s(error_m: float) -> float:
    """A preferred velocity component toward a point ``error_m`` away: ``PULL_GAIN_1_S`` x it, at most
    ``PULL_MAX_M_S``."""
    return min(max(PULL_GAIN_1_S * error_m, -PULL_MAX_M_S), PULL_MAX_M_S)


def _within(pos_ned_m: Vec3, spot_ned_m: tuple[float, ...], radius_m: float) -> bool:
    """``pos_ned_m`` is horizontally within ``radius_m`` of ``spot_ned_m`` (same frame)."""
    return math.hypot(pos_ned_m[0] - spot_ned_m[0], pos_ned_m[1] - spot_ned_m[1]) < radius_m


def phase_of(mode: FlightMode, landing: bool, pos_home_ned_m: Vec3, pref_ned_m_s: Vec3, held: bool = False,
             departing: bool = True) -> Phase:  # fmt: skip
    """The reactive layer's phase: from the mode; a LAND target is a landing; a climb from the pad a take-off, and
    so is a take-off ``held`` on the pad (its reference, stopped, no longer climbs). ``departing``: the vehicle is
    where its take-off began (:meth:`TrafficGuard.departing`); a low climb anywhere else is no take-off."""
    phase = _PHASES.get(mode, Phase.MANUAL)
    if phase is Phase.MANUAL:
        return phase
    if landing:
        return Phase.LAND
    if departing and -pos_home_ned_m[2] < GROUND_LOCK_AGL_M and (pref_ned_m_s[2] < 0.0 or held):
        return Phase.TAKEOFF
    return phase


class TrafficGuard:
    """The reactive layer's reference while it is engaged; pure (the caller gives time and state)."""

    def __init__(self, params: ParamStore, system_id: int) -> None:
        self.params = params
        self.layer = ReactiveLayer(system_id)
        self.command: ReactiveCommand | None = None
        self.texts: list[StatusText] = []
        self._engaged_us = -1
        self._solved_us = -CLEAR_PERIOD_US  # the first call solves
        self._vel: list[float] = [0.0, 0.0, 0.0]
        self._limits_version: object = None
        self.fences: tuple[FenceZoneLike, ...] = ()  # the geofence's zones about home (the navigator's link sets them)
        self.taking_off = False  # the commander's take-off, not yet off the pad (the link sets it every step)
        self.land_spot_ned_m: Vec3 | None = None  # a landing's touchdown point about the origin (the link sets it)
        self._limits: ReactiveLimits | None = None
        self._said: tuple[str, bool, bool] | None = None
        self._said_us = 0
        self._settling_us = -1  # since when a held take-off has been low and still on its pad (on_pad)
        self._departure_ne_m: tuple[float, float] | None = None  # where the last take-off left the ground, about home
        self._departure_threat: str | None = None  # the departure hold's track, kept until DEPARTURE_CLEAR_US clear
        self._departure_clear_us = -1  # since when the climb-out column has been clear of it

    @property
    def engaged(self) -> bool:
        return self._engaged_us >= 0

    @property
    def holding_takeoff(self) -> bool:
        """The departure hold is in force (the vehicle waits on its pad)."""
        return self.command is not None and self.command.escape == TAKEOFF_HELD

    def on_pad(self, t_us: int, frame: HomeFrame, pos_ned_m: Vec3, vel_ned_m_s: Vec3) -> bool:
        """The departure hold keeps the commander's take-off on its pad and the vehicle has settled on it
        (``PAD_CONTACT_AGL_M``, ``PAD_SETTLE_M_S`` for ``PAD_SETTLE_US``; ``pos_ned_m`` about the origin): nothing
        is flown until the hold ends."""
        low = -frame.home_from_origin(pos_ned_m)[2] < PAD_CONTACT_AGL_M and abs(vel_ned_m_s[2]) < PAD_SETTLE_M_S
        if not (self.taking_off and self.holding_takeoff and low):
            self._settling_us = -1
            return False
        if self._settling_us < 0:
            self._settling_us = t_us
        return t_us - self._settling_us >= PAD_SETTLE_US

    def departing(self, pos_home_ned_m: Vec3) -> bool:
        """In the commander's take-off, held on the pad, or within ``DEPARTURE_RADIUS_M`` of where the last take-off
        left the ground."""
        if self.taking_off or self.holding_takeoff:
            return True
        return self._departure_ne_m is not None and _within(pos_home_ned_m, self._departure_ne_m, DEPARTURE_RADIUS_M)

    def over_spot(self, frame: HomeFrame, pos_home_ned_m: Vec3) -> bool:
        """Within ``LANDING_RADIUS_M`` of the landing's touchdown point (a landing without one: where it is)."""
        if self.land_spot_ned_m is None:
            return True
        return _within(pos_home_ned_m, frame.home_from_origin(self.land_spot_ned_m), LANDING_RADIUS_M)

    def limits(self) -> ReactiveLimits:
        """What the vehicle may fly: MPC_* speeds and acceleration, CA_MIN_AGL_M, CA_CEILING_M / GF_MAX_VER_DIST,
        the fence's zones (``fences``, about home) with CA_FENCE_MARG_M."""
        key = (self.params.version, self.fences)
        if self._limits is None or self._limits_version != key:
            g = self.params.get
            ceiling = g("CA_CEILING_M")
            if g("GF_MAX_VER_DIST") > 0.0:
                ceiling = min(ceiling, g("GF_MAX_VER_DIST"))
            self._limits = ReactiveLimits(g("MPC_XY_VEL_MAX"), g("MPC_Z_VEL_MAX_UP"), g("MPC_Z_VEL_MAX_DN"),
                                          g("MPC_ACC_HOR"), -g("CA_MIN_AGL_M"), -ceiling, self.fences,
                                          g("CA_FENCE_MARG_M"))  # fmt: skip
            self._limits_version = key
        return self._limits

    def release(self, t_us: int | None = None) -> None:
        """Back to the reference given (texts: the end once, and only after ``QUIET_US`` of avoidance)."""
        if self.engaged and (t_us is None or t_us - self._engaged_us >= QUIET_US):
            self.texts.append(StatusText(Severity.INFO, "Traffic: clear, reactive avoidance ended"))
            self._said = None
        self._engaged_us, self.command = -1, None

    def step(self, t_us: int, dt_s: float, frame: HomeFrame, pos_ned_m: Vec3, vel_ned_m_s: Vec3,
             ref_pos_ned_m: Vec3, ref_vel_ned_m_s: Vec3, mode: FlightMode, landing: bool, table: TrackTable,
             params: TrafficParams) -> ReferenceOverride | None:  # fmt: skip
        """This control step's reference (about the origin), or None to fly the one given; ``table``'s tracks are
        read at the navigator's rate."""
        if self.taking_off:
            spot = frame.home_from_origin(pos_ned_m)
            self._departure_ne_m = (spot[0], spot[1])
        if params.action is not TrafficAction.AVOID or not table.has_tracks:
            self.release()
            return None
        period = SOLVE_PERIOD_US if self.engaged or self.layer.slack_m_s < CLEAR_SLACK_M_S else CLEAR_PERIOD_US
        if t_us - self._solved_us >= period:
            self._solved_us = t_us
            self._solve(t_us, frame, pos_ned_m, vel_ned_m_s, ref_pos_ned_m, ref_vel_ned_m_s, mode, landing,
                        table.tracks, params, table.version)  # fmt: skip
        command = self.command
        if command is None:
            return None
        a = self.limits().acc_m_s2 * dt_s
        vel, acc = self._vel, [0.0, 0.0, 0.0]
        before = (vel[0], vel[1], vel[2])
        for k in range(3):
            dv = min(max(command.vel_ned_m_s[k] - vel[k], -a), a)
            vel[k] += dv
            acc[k] = dv / dt_s if dt_s > 0.0 else 0.0
        if self.layer.keep_inside_fence(vel) and dt_s > 0.0:  # on the way to the command too, never toward the fence
            acc = [(vel[k] - before[k]) / dt_s for k in range(3)]
        return ReferenceOverride(pos_ned_m, (vel[0], vel[1], vel[2]), (acc[0], acc[1], acc[2]))

    def _solve(self, t_us: int, frame: HomeFrame, pos_ned_m: Vec3, vel_ned_m_s: Vec3, ref_pos_ned_m: Vec3,
               ref_vel_ned_m_s: Vec3, mode: FlightMode, landing: bool, tracks: tuple[TrafficTrack, ...],
               params: TrafficParams, version: int) -> None:  # fmt: skip
        pref = [0.0, 0.0, 0.0]
        for k in range(3):
            pref[k] = ref_vel_ned_m_s[k] + _pull_m_s(ref_pos_ned_m[k] - pos_ned_m[k])
        pos = frame.home_from_origin(pos_ned_m)
        departing = self.departing(pos)
        phase = phase_of(mode, landing, pos, (pref[0], pref[1], pref[2]), self.holding_takeoff, departing)
        if phase is Phase.MANUAL:
            self.release()  # manual: warn only
            return
        climbing = pref[2] < 0.0
        held = None
        if phase is Phase.LAND and self.land_spot_ned_m is not None:
            spot = frame.home_from_origin(self.land_spot_ned_m)
            occupant = self._pad_occupant(t_us, pos, spot, tracks, params)
            if occupant is not None:
                self._wait_beside(t_us, pos, occupant, pref, params)
                held = occupant.name
        pad_held = held is not None
        landing_here = phase is Phase.LAND and self.over_spot(frame, pos)
        if landing_here and not pad_held and -pos[2] < GROUND_LOCK_AGL_M:
            self.release()  # a landing this low is committed (the others give way to it)
            return
        limits = self.limits()
        if held is None:
            held = self._column_threat(t_us, pos, pref, phase, tracks, params)
            if phase is Phase.TAKEOFF or self._departure_threat is not None:
                held = self._latched_departure(t_us, held if phase is Phase.TAKEOFF else None)
            if held is not None:
                pref[2] = 0.0  # hold the height: no climb out of the pad, no descent into the column, no level change
        over_pad = departing or pad_held or landing_here  # (a take-off phase is a departing one)
        # waiting beside the pad, or pushed away from the spot, a landing vehicle is held in the air (the floor)
        layer_phase = Phase.HOLD if pad_held or (phase is Phase.LAND and not landing_here) else phase
        command = self.layer.solve(t_us, pos, vel_ned_m_s, (pref[0], pref[1], pref[2]), tracks, params, limits,
                                   layer_phase, version, over_pad)  # fmt: skip
        if held is not None and phase is Phase.TAKEOFF:  # on the pad: stay (no escape climbs out of it), low
            # back onto the pad only while no landing can be detected there, else down to HELD_AGL_M over it
            down = HELD_DESCENT_M_S if self.taking_off else min(max(-pos[2] - HELD_AGL_M, 0.0), HELD_DESCENT_M_S)
            command = ReactiveCommand((0.0, 0.0, down), held, False, TAKEOFF_HELD)
        elif command is None and held is not None:
            what = "landing" if phase is Phase.LAND else "climb" if climbing else "descent"
            command = ReactiveCommand(self.layer.limited_ned_m_s, held, False, PAD_HELD if pad_held else f"{what} held")
        elif command is not None and pad_held and not command.fallback:
            command = ReactiveCommand(command.vel_ned_m_s, held, False, PAD_HELD)
        elif command is not None and held is not None and phase in CORRIDOR_PHASES and not command.fallback:
            # the layer binds too (its preference held level): the hold is what the text says
            command = ReactiveCommand(command.vel_ned_m_s, held, False, "climb held" if climbing else "descent held")
        if command is None:
            if self.engaged and t_us - self._engaged_us >= MIN_ENGAGED_US:
                self.release(t_us)
            elif self.engaged and self.command is not None:  # the preference, within the limits and the fence
                self.command = ReactiveCommand(self.layer.limited_ned_m_s, self.command.threat, False)
            return
        if not self.engaged:
            self._engaged_us = t_us
            self._vel = [float(ref_vel_ned_m_s[0]), float(ref_vel_ned_m_s[1]), float(ref_vel_ned_m_s[2])]
        self.command = command
        on_pad = -pos[2] < GROUND_LOCK_AGL_M and command.vel_ned_m_s[2] >= 0.0 and phase is Phase.TAKEOFF
        said = (command.threat, command.fallback and not on_pad, on_pad)
        # a new text when the kind of avoidance changes, at most once a second; another track binding (in a crowd
        # the binding plane changes at every solve) at most once per QUIET_US
        wait_us = SAY_KIND_US if self._said is None or said[1:] != self._said[1:] else QUIET_US
        if said != self._said and (self._said is None or t_us - self._said_us >= wait_us):
            self._said, self._said_us = said, t_us
            if on_pad:
                self.texts.append(StatusText(Severity.NOTICE, f"Traffic: take-off held for {command.threat}"))
            elif command.fallback:
                text = f"Traffic: no safe velocity from {command.threat} ({phase.value}): braking to a hover, "
                self.texts.append(StatusText(Severity.WARNING, text + command.escape))
            elif command.escape == PAD_HELD:
                text = f"Traffic: {PAD_HELD}, {command.threat} on it or over it"
                self.texts.append(StatusText(Severity.NOTICE, text))
            elif command.escape:
                text = f"Traffic: {command.escape} for {command.threat} (predicted through the column)"
                self.texts.append(StatusText(Severity.NOTICE, text))
            else:
                text = f"Traffic: avoiding {command.threat} ({phase.value}), reactive"
                self.texts.append(StatusText(Severity.NOTICE, text))

    def _column_threat(self, t_us: int, pos: Vec3, pref: list[float], phase: Phase,
                       tracks: tuple[TrafficTrack, ...], params: TrafficParams) -> str | None:  # fmt: skip
        """The departure hold, the landing clearance and the altitude-change corridor: the track predicted through
        the column the vehicle is about to climb out of (from the pad), descend into, or change levels through,
        before it would be through (a manned aircraft: within the look-ahead, from the pad); None when clear."""
        if phase in CORRIDOR_PHASES and abs(pref[2]) >= CORRIDOR_MIN_M_S and -pos[2] >= GROUND_LOCK_AGL_M:
            return corridor_threat(t_us, pos, pref, tracks, params)
        manned_window = 0.0
        if phase is Phase.TAKEOFF and (pref[2] < 0.0 or self.holding_takeoff) and -pos[2] < GROUND_LOCK_AGL_M:
            top = -DEPARTURE_COLUMN_M  # up at the take-off's climb rate (held, the reference stops; it says nothing)
            window = DEPARTURE_COLUMN_M / self.params.get("MPC_TKO_SPEED") + COLUMN_MARGIN_S
            manned_window = max(window, params.horizon_s)
        elif phase is Phase.LAND and pref[2] > 0.0 and -pos[2] >= GROUND_LOCK_AGL_M:
            top, window = pos[2], LANDING_WINDOW_S  # the descent itself is the reactive layer's (others avoid it)
        else:
            return None
        for track in tracks:
            if parked(track, t_us):
                continue
            manned = track.source is TrafficSource.MANNED and manned_window > 0.0
            look_s, levels = (manned_window, (False, True)) if manned else (window, (False,))  # ADS-B climb: noise
            if any(column_conflict(track, t_us, pos, top, look_s, params, level) is not None for level in levels):
                return track.name
        return None

    def _latched_departure(self, t_us: int, threat: str | None) -> str | None:
        """The departure hold's track: ``threat`` (this solve's, None: clear or no take-off), or the last one until
        the column has been clear ``DEPARTURE_CLEAR_US`` (only while the hold is still in force)."""
        if threat is not None or not self.holding_takeoff:
            self._departure_threat, self._departure_clear_us = threat, -1
            return threat
        if self._departure_clear_us < 0:
            self._departure_clear_us = t_us
        if t_us - self._departure_clear_us >= DEPARTURE_CLEAR_US:
            self._departure_threat = None
        return self._departure_threat

    def _pad_occupant(self, t_us: int, pos: Vec3, spot: Vec3, tracks: tuple[TrafficTrack, ...],
                      params: TrafficParams) -> TrafficTrack | None:  # fmt: skip
        """The landing clearance's first half: the UAV on the touchdown ``spot`` (about home) or hovering over it
        lower than the vehicle (slower than ``COLUMN_SPEED_M_S`` within ``PAD_RADIUS_VOLUMES`` of the grown volume,
        its report's accuracy added); None when the pad is free."""
        reach_m = PAD_RADIUS_VOLUMES * params.uav.grown(params.margin).hor_m
        for track in tracks:
            if track.source is not TrafficSource.UAV or math.hypot(*track.steady_vel_ned_m_s[:2]) >= COLUMN_SPEED_M_S:
                continue
            p = track.position_at(t_us)
            on_spot = math.hypot(p[0] - spot[0], p[1] - spot[1]) < reach_m + uncertainty_m(track)[0]
            if on_spot and -p[2] < -pos[2]:  # one over the vehicle is going or gone up: not in the column below it
                return track
        return None

    def _wait_beside(self, t_us: int, pos: Vec3, occupant: TrafficTrack, pref: list[float],
                     params: TrafficParams) -> None:  # fmt: skip
        """Sets ``pref`` to wait level (at least ``PAD_HOLD_AGL_M`` up) ``PAD_ASIDE_VOLUMES`` volumes from the
        pad's ``occupant``, on the vehicle's side of it (right over it: east for the lower system id, else west)."""
        p = occupant.position_at(t_us)
        an, ae = pos[0] - p[0], pos[1] - p[1]
        away = math.hypot(an, ae)
        if away < 1e-3:
            an, ae, away = 0.0, (1.0 if self.layer.system_id < occupant.target_id else -1.0), 1.0
        aside = PAD_ASIDE_VOLUMES * (params.uav.grown(params.margin).hor_m + uncertainty_m(occupant)[0])
        pref[0] = _pull_m_s(p[0] + an / away * aside - pos[0])
        pref[1] = _pull_m_s(p[1] + ae / away * aside - pos[1])
        pref[2] = -max(_pull_m_s(PAD_HOLD_AGL_M + pos[2]), 0.0)  # level, and back up if pushed low
