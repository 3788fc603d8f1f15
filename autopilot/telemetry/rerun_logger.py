"""The Rerun telemetry: a passive listener of the autopilot loop.

``RerunTelemetry.on_step(record)`` is called by ``autopilot.runner.run_loop`` after each
control step has been answered; it never changes what it is given. Cost and size are kept low:

- every step writes one preallocated row of scalar series (positions, errors, live gains
  k(s), motors, thrust, battery, clearance); rows are flushed with ``send_columns`` every
  ``batch_rows`` steps (one chunk per entity per batch: a saved recording uses 120 s batches, a live
  viewer 4 s ones). What is flushed keeps every step of the series a controller is judged by
  (position, attitude, their errors, motors) and every :data:`DECIMATION`-th step of the rest
  (setpoints, gains, thrust: 50 Hz; clearance 25 Hz; battery and mission item 5 Hz), which halves
  the file;
- the 3D pose, setpoint and trail are sampled at ``rate_3d_hz`` (default 25 Hz) into another
  preallocated buffer flushed with the same batch;
- rare things (events, home, route, detours, obstacles, fence) are logged when they change.

Timeline ``sim_time`` only (a duration from the simulator's ``time_us``); wall-clock timelines
are disabled by :func:`autopilot.telemetry.sinks.open_recording`. Angles are logged in degrees.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import rerun as rr

from autopilot.estimation.state import EstimatorStatus, VehicleState
from autopilot.flight_tasks.setpoints import TargetKind
from autopilot.telemetry import entities as ent
from autopilot.telemetry.blueprint import Framing, flight_blueprint
from autopilot.telemetry.estimator_errors import EstimatorErrorLog
from autopilot.telemetry.scene_log import SceneLog
from autopilot.telemetry.separation_volume import SeparationVolumeLog
from autopilot.telemetry.step_columns import (
    ANGLE_COLS,
    C_ATT_ERR,
    DECIMATION,
    LIVE_BATCH_ROWS,
    LIVE_TRAIL_POINTS,
    N_3D,
    N_COLS,
    N_CTRL,
    SAVE_BATCH_ROWS,
    SAVE_TRAIL_POINTS,
    SERIES,
)
from mavlink_bridge.contract.vehicle_api import FlightMode, Severity
from mavlink_bridge.contract.wire import GroundTruth

if TYPE_CHECKING:
    from autopilot.reporting.report import StepRecord

__all__ = [
    "DECIMATION",
    "LIVE_BATCH_ROWS",
    "LIVE_TRAIL_POINTS",
    "SAVE_BATCH_ROWS",
    "SAVE_TRAIL_POINTS",
    "SERIES",
    "RerunTelemetry",
]

_COLOR_TRAIL = (60, 140, 255)
_COLOR_TARGETS = (255, 150, 0)
_MAX_TARGETS = 2000


def _time_column(t_us: np.ndarray) -> rr.TimeColumn:
    return rr.TimeColumn(ent.TIMELINE, duration=t_us.astype("timedelta64[us]"))


class RerunTelemetry(SceneLog):
    """Passive per-step listener that writes one flight into a Rerun recording stream.

    Methods (all take sim time, never wall time):
    ``on_step(record)`` each control step; ``on_event(text, severity, time_us)``;
    ``on_route(points_ned_home)`` / ``on_mission(items, home)``; ``on_fence(zones)``;
    ``on_true_obstacles(obstacles)`` / ``on_world(world_mapping)``; ``on_obstacles(tracked, time_us)``;
    ``on_detour(points_ned_home, time_us)``; ``flush()``; ``close()``.
    Things "about home" are drawn under ``world/home`` whose transform follows the home position.
    """

    def __init__(
        self,
        rec: rr.RecordingStream,
        *,
        rate_3d_hz: float = 25.0,
        batch_rows: int = 1000,
        trail_segment_points: int = 125,
        safety_radius_m: float = 2.0,
        rotor_pos_frd_m: Sequence[Sequence[float]] | None = None,
        obstacle_period_s: float = 0.5,
        blueprint_sent: bool = False,
        rtl_alt_m: float | None = None,
        obstacles_known: bool | None = None,
        separation_volume: bool = False,
    ) -> None:
        """``blueprint_sent``: the recording already holds its (framed) blueprint; otherwise one is sent with
        the first route (framed on it) or at :meth:`close`. ``rtl_alt_m``: the RTL altitude above home
        (``MIS_RTL_ALT``) an RTL item climbs to when lower. ``obstacles_known``: whether the world is
        known to have obstacles (None: not known), for the clearance panel's title. ``separation_volume``: draw the
        vehicle's own UAV separation volume (:mod:`autopilot.telemetry.separation_volume`; a fleet's recording)."""
        self._estimator_errors: EstimatorErrorLog | None = None
        self._volume = SeparationVolumeLog(rec) if separation_volume else None
        if not (rate_3d_hz > 0.0 and batch_rows >= 1 and trail_segment_points >= 2):
            raise ValueError("need rate_3d_hz > 0, batch_rows >= 1 and trail_segment_points >= 2")
        super().__init__(
            rec,
            safety_radius_m=safety_radius_m,
            blueprint_sent=blueprint_sent,
            rtl_alt_m=rtl_alt_m,
            obstacles_known=obstacles_known,
        )
        self._period_3d_us = round(1e6 / rate_3d_hz)
        self._obstacle_period_us = round(obstacle_period_s * 1e6)
        self._batch_rows = int(batch_rows)
        self._vals: list[float] = []
        self._times: list[int] = []
        self._ctrl = np.full((self._batch_rows, N_CTRL), math.nan)
        self._has_battery: bool | None = None
        self._vals3: list[float] = []
        self._times3: list[int] = []
        self._trail = np.zeros((trail_segment_points, 3))
        self._trail_n = 0
        self._trail_segment = 0
        self._trail_dirty = False
        self._trail_t_us = 0
        self._next_3d_us = -1
        self._next_obstacles_us = -1
        self._last_mode: FlightMode | None = None
        self._last_armed: bool | None = None
        self._last_seq: int | None = None
        self._last_target_key: Sequence[float] | None = None  # the latest target drawn (LAND: its xy only)
        self._targets: list[tuple[float, float, float]] = []
        self._last_detour: object | None = None
        self._last_planned_route: object | None = None
        self._last_obstacle_key: tuple[Any, ...] | None = None
        self._steps: list[int] = []  # the step number of each buffered row (decimation keeps its phase)
        self.steps_logged = 0
        self.closed = False
        self._log_static(rotor_pos_frd_m)

    # ------------------------------------------------------------------ static content
    def _log_static(self, rotor_pos_frd_m: Sequence[Sequence[float]] | None) -> None:
        rec = self.rec
        rec.log(ent.WORLD, rr.ViewCoordinates.FRD, static=True)  # X north, Y east, Z down: NED
        rotors = np.asarray(rotor_pos_frd_m if rotor_pos_frd_m is not None else _DEFAULT_ROTORS_FRD, dtype=float)
        arm = float(np.max(np.linalg.norm(rotors[:, :2], axis=1)))
        rec.log(ent.VEHICLE, rr.TransformAxes3D(axis_length=max(0.5, 2.0 * arm)), static=True)
        colors = [(230, 60, 60) if p[0] > 0.0 else (200, 200, 200) for p in rotors]
        rec.log(
            ent.VEHICLE_BODY,
            rr.LineStrips3D([[(0.0, 0.0, 0.0), tuple(p)] for p in rotors], colors=colors, radii=0.01 * (1 + arm)),
            rr.Ellipsoids3D(
                centers=rotors,
                half_sizes=[(0.5 * arm, 0.5 * arm, 0.01)] * len(rotors),
                colors=colors,
                fill_mode=rr.components.FillMode.Solid,
            ),
            static=True,
        )
        for path, _, _, names in SERIES:
            rec.log(path, rr.SeriesLines(names=list(names)), static=True)

    # ------------------------------------------------------------------ per step
    def on_step(self, record: StepRecord) -> None:
        """Buffer one control step (every step goes to the series; 3D at ``rate_3d_hz``)."""
        t_us = int(record.time_us)
        if t_us <= self._last_t_us:  # a repeated frame: keep sim time strictly increasing
            return
        self._last_t_us = t_us
        state = record.state
        pos = state.pos_ned_m
        sp = record.pos_sp_ned_m
        v = self._vals  # one flat list per batch: the cheapest per-step append in CPython
        v += pos
        v += sp
        v += (sp[0] - pos[0], sp[1] - pos[1], sp[2] - pos[2], state.roll_rad, state.pitch_rad, state.yaw_rad)
        v += record.motor_cmd
        planner = record.planner_output
        clearance = getattr(planner, "clearance_m", math.nan) if planner is not None else math.nan
        battery = self._battery_fields(record)
        v += (
            getattr(record, "battery_remaining_pct") if battery else math.nan,  # noqa: B009
            getattr(record, "battery_voltage_v") if battery else math.nan,  # noqa: B009
            clearance if math.isfinite(clearance) else math.nan,
            record.mission_seq,
        )
        i = len(self._times)
        control = record.control
        if control is not None:
            self._ctrl[i] = control.values
        else:
            self._ctrl[i] = math.nan
        self._times.append(t_us)
        self._steps.append(self.steps_logged)
        self.steps_logged += 1
        if record.truth is not None:  # the estimate against the sim's truth (decimated inside)
            self.on_truth(state, record.truth, record.estimator_status)

        if t_us >= self._next_3d_us:
            self._next_3d_us = t_us + self._period_3d_us
            self._sample_3d(t_us, pos, state.q_ned_frd, sp)
            if self._volume is not None:
                self._volume.on_sample(
                    t_us, getattr(record, "uav_separation", None), getattr(record, "traffic_decision", None)
                )
            target = record.target
            kind = target.kind
            if kind is TargetKind.POSITION or kind is TargetKind.LAND:  # IDLE and VELOCITY have no position
                pos = target.pos_ned_m
                # LAND holds the xy of its target while its down follows the vehicle: one point per landing
                key = (pos[0], pos[1]) if kind is TargetKind.LAND else pos
                if key != self._last_target_key:
                    self._last_target_key = key
                    self._add_target(t_us, pos)
            if planner is not None:
                self._planner_3d(t_us, planner)
            planned = getattr(record, "planned_route_home_ned_m", None)
            if planned is not self._last_planned_route:  # a replanned leg around the zones (issue 13)
                self._last_planned_route = planned
                self.on_planned_route(planned, t_us)
        if record.texts or record.mode is not self._last_mode or record.armed is not self._last_armed:
            self._events(record)
        if record.mission_seq != self._last_seq:
            if self._last_seq is not None:
                self.on_event(f"mission: current item {record.mission_seq}", Severity.INFO, t_us)
            self._last_seq = record.mission_seq
        home = record.home_ned_m
        if home is not None and home != self._last_home:
            self._last_home = (float(home[0]), float(home[1]), float(home[2]))
            self._set_time(t_us)
            self.rec.log(ent.HOME, rr.Transform3D(translation=self._last_home))
        if len(self._times) >= self._batch_rows:
            self.flush()

    def _add_target(self, t_us: int, pos_ned: Sequence[float]) -> None:
        """The navigation targets flown so far (about the origin): the reference route as commanded."""
        if len(self._targets) >= _MAX_TARGETS:
            del self._targets[: _MAX_TARGETS // 2]
        self._targets.append((float(pos_ned[0]), float(pos_ned[1]), float(pos_ned[2])))
        self._set_time(t_us)
        self.rec.log(
            ent.TARGETS,
            rr.LineStrips3D([self._targets], colors=[_COLOR_TARGETS], radii=0.05),
            rr.Points3D(self._targets, colors=[_COLOR_TARGETS], radii=0.25),
        )

    def _battery_fields(self, record: StepRecord) -> bool:
        """Whether records carry ``battery_remaining_pct``/``battery_voltage_v`` (checked once)."""
        has = self._has_battery
        if has is None:
            has = self._has_battery = hasattr(record, "battery_remaining_pct") and hasattr(record, "battery_voltage_v")
        return has

    def _sample_3d(self, t_us: int, pos: Sequence[float], q_ned_frd: Sequence[float], sp: Sequence[float]) -> None:
        self._times3.append(t_us)
        v = self._vals3
        v += pos
        v += (q_ned_frd[1], q_ned_frd[2], q_ned_frd[3], q_ned_frd[0])  # Rerun quaternions are x, y, z, w
        v += sp
        k = self._trail_n
        if k == len(self._trail):  # segment full: log it for good and start the next at its last point
            self._log_trail(self._trail_t_us)
            self._trail[0] = self._trail[k - 1]
            self._trail_segment += 1
            k = 1
        self._trail[k] = pos
        self._trail_n = k + 1
        self._trail_t_us = t_us
        self._trail_dirty = True

    def _log_trail(self, t_us: int) -> None:
        self._set_time(t_us)
        self.rec.log(
            f"{ent.TRAIL}/seg{self._trail_segment:05d}",
            rr.LineStrips3D([self._trail[: self._trail_n]], colors=[_COLOR_TRAIL], radii=0.05),
        )
        self._trail_dirty = False

    def _events(self, record: StepRecord) -> None:
        """Arming and mode changes (unless the step's own texts already say so), then the texts."""
        t_us = record.time_us
        said = " ".join(t.text for t in record.texts).lower()
        if record.armed is not self._last_armed:
            word = "armed" if record.armed else "disarmed"
            if (self._last_armed is not None or record.armed) and word not in said:
                self.on_event(word, Severity.INFO, t_us)
            self._last_armed = record.armed
        if record.mode is not self._last_mode:
            if record.mode.name.lower() not in said:
                self.on_event(f"mode {record.mode.name}", Severity.INFO, t_us)
            self._last_mode = record.mode
        for text in record.texts:
            self.on_event(text.text, text.severity, t_us)

    def _planner_3d(self, t_us: int, planner: Any) -> None:
        """Draw the planner's tracked obstacles (rate-limited, on change) and its detour (on change)."""
        detour = getattr(planner, "detour", None) or getattr(planner, "hold_path", None)
        if detour is not self._last_detour:
            self._last_detour = detour
            path = getattr(planner, "planned_path_ned", None)
            self.on_detour(None if path is None else np.asarray(path), t_us)
        obstacles = getattr(planner, "obstacles", ())
        if t_us >= self._next_obstacles_us:
            key = tuple((o.obstacle_id, round(o.radius_m, 1), *(round(c, 1) for c in o.center_ned)) for o in obstacles)
            if key != self._last_obstacle_key:
                self._last_obstacle_key = key
                self._next_obstacles_us = t_us + self._obstacle_period_us
                self.on_obstacles(obstacles, t_us)

    # ------------------------------------------------------------------ estimate against truth
    def on_truth(self, state: VehicleState, truth: GroundTruth, status: EstimatorStatus | None = None) -> None:
        """The estimate against the sim's truth (``estimator/`` error series, 25 Hz of sim time)."""
        if self._estimator_errors is None:
            self._estimator_errors = EstimatorErrorLog(self.rec, ent.TIMELINE)
        self._estimator_errors.log(state, truth, status)

    # ------------------------------------------------------------------ flushing
    def flush(self) -> None:
        """Send the buffered rows (one ``send_columns`` per entity) and the open trail segment."""
        rec = self.rec
        if self._estimator_errors is not None:
            self._estimator_errors.flush()
        if self._times:
            n = len(self._times)
            rows = np.empty((n, N_COLS))
            rows[:, :C_ATT_ERR] = np.array(self._vals, dtype=np.float64).reshape(n, C_ATT_ERR)
            rows[:, C_ATT_ERR:] = self._ctrl[:n]
            for cols in ANGLE_COLS:
                rows[:, cols] *= 180.0 / math.pi
            t_us = np.array(self._times, dtype=np.int64)
            steps = np.array(self._steps, dtype=np.int64)
            for path, c0, width, _ in SERIES:
                keep = steps % DECIMATION.get(path, 1) == 0
                if not keep.any():
                    continue
                rec.send_columns(
                    path,
                    indexes=[_time_column(t_us[keep])],
                    columns=rr.Scalars.columns(scalars=rows[keep, c0 : c0 + width]),
                )
            self._vals.clear()
            self._times.clear()
            self._steps.clear()
        if self._times3:
            r3 = np.array(self._vals3, dtype=np.float64).reshape(len(self._times3), N_3D)
            times3 = [_time_column(np.array(self._times3, dtype=np.int64))]
            rec.send_columns(
                ent.VEHICLE,
                indexes=times3,
                columns=rr.Transform3D.columns(translation=r3[:, 0:3], quaternion=r3[:, 3:7]),
            )
            rec.send_columns(ent.SETPOINT, indexes=times3, columns=rr.Points3D.columns(positions=r3[:, 7:10]))
            if self._volume is not None:
                self._volume.send_positions(times3, r3[:, 0:3])
            self._vals3.clear()
            self._times3.clear()
        if self._trail_dirty:
            self._log_trail(self._trail_t_us)

    def close(self) -> None:
        """Flush everything and finalize the sink (the ``.rrd`` footer is written). Idempotent."""
        if self.closed:
            return
        self.flush()
        if not self._blueprint_sent:  # no route came: the unframed layout
            self._blueprint_sent = True
            self.rec.send_blueprint(flight_blueprint(Framing(obstacles=self._obstacles_known)), make_default=True)
        self.closed = True
        self.rec.flush()
        self.rec.disconnect()


#: x500-like rotor layout (PX4 quad-x order) used when no airframe is given.
_DEFAULT_ROTORS_FRD = ((0.174, 0.174, 0.0), (-0.174, -0.174, 0.0), (0.174, -0.174, 0.0), (-0.174, 0.174, 0.0))
