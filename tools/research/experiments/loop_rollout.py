"""One seeded flight of the product's own closed loop, in process: the simulator's sensor models -> the
estimator (the EKF by default) -> the autopilot's commander, navigator and NLVG-PID cascade (issue 22 item 1).

The composition is the one of ``tests/autopilot_loop.py`` and ``tools/benchmarks/estimator.py`` (no sockets, no
lockstep): a :class:`~sim.vehicle.VehicleSim` with its :class:`~sim.sensors.SensorModel` and an
:class:`~autopilot.runner.Autopilot` with the gains under test as its ``NV_*`` parameters. The vehicle uploads
the route's mission when the estimate is valid, arms when the estimator allows, starts the mission and flies
until the mission's last item is done (or landed and disarmed). The measured window is the mission while
airborne:

* true tracking error: ``|position setpoint − TRUE position|`` every 5th step (50 Hz); the setpoint is in the
  estimator's frame, moved into the simulator's frame by the estimator origin's offset from home;
* motor chatter: RMS rate of the motor commands (1/s) every step, the yaw mode projected out
  (:class:`tools.research.experiments.rollout.MotorChatter`, the same measure as the batched tuner's).

:func:`fly_route` takes one small frozen :class:`LoopRollout` and is top level, so a campaign engine can ship
it to worker processes as it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from autopilot.control.airframe import load_airframe
from autopilot.control.gains import CascadeGains
from autopilot.control.param_decls import params_from_gains
from autopilot.estimation import make_estimator
from autopilot.mission.files import load_mission_file
from autopilot.mission.plan import MissionPlan
from autopilot.param_schema import make_param_store
from autopilot.runner import Autopilot, AutopilotConfig
from autopilot.vehicle_adapter import VehicleAdapter
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.mav_enums import MavCmd, MissionState
from mavlink_bridge.contract.vehicle_api import CommandRequest, CommandResult, LandedState, MissionType
from mavlink_bridge.lockstep import LockstepFrame
from sim.end_reason import EndReason
from sim.sensors import SensorModel
from sim.vehicle import VehicleSim
from sim.vehicle_config import load_vehicle
from sim.world import World, load_world
from tools.research.experiments.rollout import MotorChatter

ROOT = Path(__file__).resolve().parents[3]
#: the routes: short tuning segments (``loop_routes/*.yaml``) and the user's delivery mission
ROUTES = {
    "leg": Path(__file__).resolve().parent / "loop_routes" / "leg.yaml",
    "steps": Path(__file__).resolve().parent / "loop_routes" / "steps.yaml",
    "delivery": ROOT / "missions" / "delivery.yaml",
}
CONTROL_HZ = 250
SAMPLE_EVERY = 5  # the tracking error at 50 Hz (an error cannot change much in 20 ms)
#: a true tracking error above this ends the rollout as diverged (cost inf)
DIVERGED_M = 10.0


@dataclass(frozen=True, slots=True)
class LoopRollout:
    """One flight: airframe, the gains as ``NV_*`` parameter values, route name, seed (sensor noise, gusts)."""

    vehicle: str
    params: tuple[tuple[str, float], ...]
    route: str
    seed: int
    estimator: str = "ekf"
    timeout_s: float = 200.0

    @staticmethod
    def of(vehicle: str, gains: CascadeGains, route: str, seed: int, estimator: str = "ekf") -> LoopRollout:
        """A rollout flying ``gains`` (a single set)."""
        return LoopRollout(vehicle, tuple(sorted(params_from_gains(gains).items())), route, seed, estimator)


@dataclass(frozen=True, slots=True)
class LoopOutcome:
    """What one flight measured (see the module docstring); ``mean_sq_err_m2`` is inf when it diverged."""

    route: str
    vehicle: str
    seed: int
    completed: bool
    diverged: bool
    end_reason: str
    sim_s: float
    pos_err_rms_m: float
    pos_err_max_m: float
    chatter_rms_per_s: float
    samples: int

    @property
    def mean_sq_err_m2(self) -> float:
        if self.diverged or not self.completed or self.samples == 0:
            return math.inf
        return self.pos_err_rms_m**2


@cache
def _route(name: str) -> tuple[MissionPlan, World]:
    if name not in ROUTES:
        raise ValueError(f"unknown route {name!r} (known: {', '.join(sorted(ROUTES))})")
    return load_mission_file(ROUTES[name]), load_world(ROUTES[name])


def _command(cmd: MavCmd, *params: float) -> CommandRequest:
    full = (*params, *([0.0] * (7 - len(params))))
    return CommandRequest(int(cmd), tuple(full), 255, 190)  # type: ignore[arg-type]


def fly_route(rollout: LoopRollout) -> LoopOutcome:
    """Fly ``rollout`` in process and measure it (module docstring)."""
    plan, world = _route(rollout.route)
    config = load_vehicle(rollout.vehicle)
    payload_kg = min(world.payload_kg, config.payload_max_kg)
    sim = VehicleSim(config, world=world, seed=rollout.seed, payload_kg=payload_kg)
    sensors = SensorModel(config, world.home, rollout.seed)
    est = make_estimator(rollout.estimator)
    ap_config = AutopilotConfig(vehicle=rollout.vehicle, estimator=rollout.estimator, avoidance=False)
    airframe = load_airframe(rollout.vehicle)
    params = make_param_store(payload_nominal_kg=airframe.payload_nominal_kg, airframe=airframe.name)
    for name, value in rollout.params:
        params.set(name, value)
    ap = Autopilot(ap_config, params=params, estimator=est)
    vehicle = VehicleAdapter(ap)
    home_frame = LocalNedFrame(world.home)
    chatter = MotorChatter(rollout.vehicle, 1, 1.0 / CONTROL_HZ)
    offset = np.zeros(3)
    sq_sum, err_max, n = 0.0, 0.0, 0
    phase = 0  # 0 upload, 1 arm, 2 started, 3 done
    diverged = False
    steps = 0
    for steps in range(1, round(rollout.timeout_s * CONTROL_HZ) + 1):
        frame = LockstepFrame(sensors.imu_baro_mag(sim), sensors.gps(sim), sim.ground_truth())
        ap.update_context(estimator_status=est.status)
        cmd = ap.step(frame)
        ap.after_answer()
        if cmd.gripper_release and sim.payload_kg > 0.0:
            sim.release_payload()
        sim.step(cmd.motor_cmd)
        if sim.end_reason is not EndReason.RUNNING:
            break
        commander = ap.commander
        if phase == 0 and ap.state is not None and ap.state.valid:
            vehicle.replace_mission(MissionType.MISSION, list(plan.items))
            vehicle.replace_mission(MissionType.FENCE, list(plan.fence))
            phase = 1
        elif phase == 1 and steps % 25 == 0:
            if vehicle.handle_command(_command(MavCmd.COMPONENT_ARM_DISARM, 1.0)) is CommandResult.ACCEPTED:
                vehicle.handle_command(_command(MavCmd.MISSION_START, 0.0, 0.0))
                origin = est.origin
                assert origin is not None
                offset = np.asarray(home_frame.ned_from_geodetic(origin.lat_deg, origin.lon_deg, origin.alt_amsl_m))
                phase = 2
        elif phase == 2:
            if not (commander.armed and commander.in_air):
                if commander.landed_state is LandedState.ON_GROUND and not commander.armed:
                    phase = 3
                    break
                continue
            chatter.add(np.asarray(cmd.motor_cmd, dtype=np.float64)[None, :])
            if steps % SAMPLE_EVERY == 0:
                ref = ap.control.reference
                e = np.asarray(ref.pos_ned_m) + offset - sim.pos_ned
                err = float(np.sqrt(e @ e))
                sq_sum += err * err
                err_max = max(err_max, err)
                n += 1
                if err > DIVERGED_M:
                    diverged = True
                    break
            executor = ap.navigator.executor
            if executor is not None and executor.state is MissionState.COMPLETE and commander.in_air:
                phase = 3  # a mission that ends in the air (the tuning segments): done when its last item is
                break
    return LoopOutcome(
        route=rollout.route,
        vehicle=rollout.vehicle,
        seed=rollout.seed,
        completed=phase == 3,
        diverged=diverged,
        end_reason=sim.end_reason.name,
        sim_s=steps / CONTROL_HZ,
        pos_err_rms_m=math.sqrt(sq_sum / n) if n else math.nan,
        pos_err_max_m=err_max,
        chatter_rms_per_s=float(chatter.rms()[0]),
        samples=n,
    )
