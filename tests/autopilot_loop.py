"""In-process closed loop for the autopilot wiring tests: sim vehicle + sensors + Autopilot at 250 Hz, no sockets."""

from __future__ import annotations

from collections.abc import Callable

from autopilot_fakes import command

from autopilot.runner import Autopilot, AutopilotConfig
from autopilot.vehicle_adapter import VehicleAdapter
from mavlink_bridge.contract.vehicle_api import CommandResult, FlightMode
from mavlink_bridge.contract.wire import ActuatorCommand
from mavlink_bridge.lockstep import LockstepFrame
from sim.obstacle_sensor import ObstacleSensor, ObstacleSensorConfig
from sim.sensors import SensorModel
from sim.vehicle import VehicleSim
from sim.vehicle_config import load_vehicle
from sim.world import World, empty_world

CONTROL_HZ = 250


class SimLoop:
    """One simulated vehicle flown by an in-process :class:`Autopilot`; payload released when commanded."""

    def __init__(  # type: ignore[no-untyped-def]
        self,
        vehicle: str = "x500",
        *,
        payload_kg: float | None = None,
        seed: int = 3,
        world: World | None = None,
        **ap_kw,
    ) -> None:
        config = load_vehicle(vehicle)
        world = world or empty_world()
        self.sim = VehicleSim(config, world=world, seed=seed, payload_kg=payload_kg)
        self.sensors = SensorModel(config, world.home, seed)
        self.obstacle_sensor = ObstacleSensor(world, seed) if world.obstacles else None
        self._detect_every = round(CONTROL_HZ / ObstacleSensorConfig().rate_hz)
        self._k = 0
        # The offboard/joystick/GCS link ages run on a clock that follows sim time (a client streaming every
        # step at speed 1): on the real wall clock, a loaded machine's stall would age the stream out mid-test.
        ap_kw.setdefault("wall_clock", lambda: self.sim.t_us * 1e-6)
        self.ap = Autopilot(AutopilotConfig(vehicle=vehicle), **ap_kw)
        self.vehicle = VehicleAdapter(self.ap)
        self.texts: list[str] = []
        self.last: ActuatorCommand | None = None

    def frame(self) -> LockstepFrame:
        """The lockstep frame of the current sim state (detections at the sensor's rate)."""
        sim = self.sim
        detections = ()
        if self.obstacle_sensor is not None and self._k % self._detect_every == 0:
            detections = self.obstacle_sensor.detect(sim.pos_ned, sim.q_ned_frd, sim.t_us)
        self._k += 1
        truth = sim.ground_truth()
        return LockstepFrame(self.sensors.imu_baro_mag(sim), self.sensors.gps(sim), truth, tuple(detections))

    def apply(self, cmd: ActuatorCommand) -> None:
        """Integrate one control step with the autopilot's answer (payload released when commanded)."""
        if cmd.gripper_release and self.sim.payload_kg > 0.0:
            self.sim.release_payload()
        self.sim.step(cmd.motor_cmd)
        self.last = cmd

    def step(self) -> ActuatorCommand:
        cmd = self.ap.step(self.frame())
        self.apply(cmd)
        texts = self.ap.drain_texts()
        listener = self.ap.listener
        if listener is not None:  # as run_loop does after the answer
            record = self.ap.record(texts)
            assert record is not None
            listener.on_step(record)
        self.texts += [t.text for t in texts]
        return cmd

    def run_s(self, seconds: float, each: Callable[[], None] | None = None) -> None:
        for _ in range(round(seconds * CONTROL_HZ)):
            self.step()
            if each is not None:
                each()

    def run_until(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        for _ in range(round(timeout_s * CONTROL_HZ)):
            self.step()
            if predicate():
                return True
        return False

    def take_off(self, alt_m: float = 10.0, settle_s: float = 4.0) -> None:
        """Arm, take off to ``alt_m`` above home and hover ``settle_s``."""
        self.run_s(0.5)
        assert self.vehicle.handle_command(command(400, 1.0)) is CommandResult.ACCEPTED
        takeoff = command(22, *[0] * 6, alt_m, is_int=True, frame=6)
        assert self.vehicle.handle_command(takeoff) is CommandResult.ACCEPTED
        assert self.run_until(lambda: self.ap.commander.mode is FlightMode.AUTO_LOITER, 30.0), self.texts
        self.run_s(settle_s)

    @property
    def alt_m(self) -> float:
        return -float(self.sim.pos_ned[2])


class InProcessLockstep:
    """The ``LockstepClient`` surface ``run_loop`` needs, over a :class:`SimLoop`'s simulator (no sockets)."""

    connected = True
    sim_lost = False

    def __init__(self, loop: SimLoop) -> None:
        self.loop = loop

    def next_frame(self, timeout_s: float) -> LockstepFrame:
        del timeout_s
        return self.loop.frame()

    def answer(self, cmd: ActuatorCommand, own_report: object | None = None) -> None:
        del own_report  # no traffic receiver here
        self.loop.apply(cmd)
