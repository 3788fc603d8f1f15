"""A world flown in one process (``mode: inproc``): the simulator's and the autopilot's own modules, the lockstep's
own wire format, no sockets and no ground station (SPEC §2: tools may compose sim and autopilot).

The simulator's socket-free run (``sim.fleet_run.FleetRun``: the same datagrams, traffic reports and physics as
``sim.server``; a world without ``vehicles:`` is a fleet of one) and one ``Autopilot`` per vehicle (MAV_SYS_ID
i+1, its mission and fence handed over before the first step as MISSION_ITEM_INT would carry them), stepped
together: each control step every live vehicle's datagram is decoded into its frame (``FrameAssembler``), its
autopilot steps and its answer goes through the lockstep answer's own writer and reader (motor commands as
float32, as on the wire), its own UTM_GLOBAL_POSITION (1 Hz, once the receiver was heard) through the bridge's
encoder and decoder to the simulator's relay, as ``LockstepClient`` sends it with the answer, then the physics of
all vehicles. The truth hashes are the simulator's (sha256 of each
vehicle's state after every control step), so a case flies to the same hashes in-process and over the lockstep.

Instead of the ground station a script drives each autopilot on sim time (the world's ``failures:`` and the
vehicle's own merged in, as ``autopilot --world-failures [--fleet-vehicle]`` does):

- a single-vehicle campaign case (:func:`fly`): the case's ``script.yaml``; the flight runs until it is over,
  like ``sim --end-when-landed --duration-s sim_time_s`` (landed and disarmed, or the vehicle ended, or
  ``sim_time_s``), its record has the single-vehicle ``sim_summary``;
- a fleet world (an encounter case, ``python -m tools.campaign.inproc_flight``): vehicle i is armed at
  ``arm_at_s + i * stagger_s`` and starts its mission 0.5 s later, and each vehicle is judged as the fleet ground
  station judges it (``tools.gcs.fly``): done when landed and disarmed after flying, or when it crashed; stuck
  (``stuck: ...``) by the ground station's rule (``tools.gcs.summary.ProgressWatch``): once armed, after
  ``stuck_s`` of sim time with no mission progress (item reached, landed state, arming) and no motion (it stayed
  within ``STILL_MOVE_M``: time enough to hold and resume), or after ``stall_s`` without progress though moving;
  ok when its mission was completed, it landed and disarmed, and no failsafe fired. The run ends when every
  vehicle is done, when one is stuck (the others are then "still flying": a verdict is never taken back by a
  later recovery), or at ``sim_time_s``; the record has the shape ``fleet_record.record`` reads (``sim``: the
  fleet ``sim_summary``; ``vehicles``: one row per vehicle, ``stuck`` among its keys).

A case is a function of its world, parameters and seed: re-flying it gives the same truth hashes
(``quadsitl campaign replay``). The wall-clock deadline is checked every simulated second.

``python -m tools.campaign.inproc_flight WORLD.yaml [--stagger-s S] [--params P] [--seed N]`` flies a fleet
world and prints the record's traffic columns and one line per vehicle (``--json``: the whole record).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from autopilot.commander.script import CommandScript, ScriptStep, failure_steps, load_script, merged, parse_script
from autopilot.launch_recording import fleet_recording_id, vehicle_rerun_spec, world_rerun_path
from autopilot.mission.files import load_fleet_missions, load_mission_file
from autopilot.mission.plan import MissionPlan
from autopilot.runner import Autopilot, AutopilotConfig
from autopilot.vehicle_adapter import VehicleAdapter
from mavlink_bridge.contract.status_texts import is_bypassed
from mavlink_bridge.contract.vehicle_api import LandedState, MissionResult, MissionType
from mavlink_bridge.lockstep import FrameAssembler
from mavlink_bridge.lockstep.answer_kernel import (
    ANSWER_OK,
    AnswerWriter,
    read_answer,
)
from mavlink_bridge.wire.codec import Decoder, Encoder
from mavlink_bridge.wire.mission_items import as_on_the_wire
from sim.end_reason import EndReason
from sim.fleet_run import FleetRun, fleet_airframes
from sim.fleet_world import load_fleet
from sim.server import DEFAULT_VEHICLE, mission_vehicle
from sim.summary_file import LinkCounts, solo_summary
from sim.world import load_world
from tools.campaign.cases import MISSION_START_DELAY_S
from tools.campaign.fleet_record import record
from tools.gcs import failsafe_reason
from tools.gcs.summary import FLEET_STALL_S, FLEET_STILL_S, ProgressWatch

CONTROL_HZ = 250
DEFAULT_ARM_AT_S = 3.0
DEFAULT_STALL_S = FLEET_STALL_S  # as the fleet ground station's --stall-s
DEFAULT_STUCK_S = FLEET_STILL_S  # no progress and no motion for this long: stuck
DEFAULT_SIM_TIME_S = 900.0
#: The world :func:`warm` flies (the shipped delivery mission).
WARM_WORLD = Path(__file__).resolve().parent.parent.parent / "missions" / "delivery.yaml"
_RUNNING = int(EndReason.RUNNING)
_MISSION_COMPLETE = "COMPLETE"


@dataclass(slots=True)
class _Vehicle:
    """One autopilot of the flight and what the judge knows of its flight."""

    name: str
    plan: MissionPlan
    autopilot: Autopilot
    answers: AnswerWriter
    encoder: Encoder  # its own UTM reports, as ``LockstepClient.answer`` writes them
    assembler: FrameAssembler = field(default_factory=lambda: FrameAssembler())
    texts: list[Any] = field(default_factory=list)
    seen_armed: bool = False
    watch: ProgressWatch = field(default_factory=ProgressWatch)  # the ground station's stuck rule
    done: bool = False
    stuck: bool = False
    reason: str = ""
    upload_error: str = ""
    home_ned: tuple[float, float, float] = (0.0, 0.0, 0.0)  # its pad in the world's NED (its fence is about it)
    outside: bool = False  # armed and out of its fence at the last judged second (simulator truth)
    fence_exits: int = 0  # times it went out, armed, in flight or on the ground


def vehicle_script(index: int, arm_at_s: float, stagger_s: float) -> list[ScriptStep]:
    """Vehicle ``index``'s arm and mission start (the fleet ground station's staggered start, on sim time)."""
    at_s = arm_at_s + index * stagger_s
    return parse_script(
        [{"at_s": at_s, "cmd": "arm"}, {"at_s": at_s + MISSION_START_DELAY_S, "cmd": "mission_start"}],
        f"<vehicle {index} start>",
    )


def fly_world(
    world_path: Path,
    *,
    seed: int = 0,
    vehicle: str | None = None,
    params_file: str | None = None,
    estimator: str = "ekf",
    script: list[ScriptStep] | None = None,
    stagger_s: float = 0.0,
    arm_at_s: float = DEFAULT_ARM_AT_S,
    sim_time_s: float = DEFAULT_SIM_TIME_S,
    stall_s: float | None = DEFAULT_STALL_S,
    stuck_s: float = DEFAULT_STUCK_S,
    deadline_s: float | None = None,
    rerun: str | None = None,
    end_when_landed: bool = False,
) -> dict[str, Any]:
    """Fly the world at ``world_path``; its record (see the module docstring: the single-vehicle shape for a world
    without ``vehicles:``, else the fleet's). ``vehicle``: the airframe of vehicles without their own (default:
    the world's ``vehicle:``); ``script``: what every autopilot runs instead of the staggered arm and mission
    start; ``stall_s`` None: no judging, the flight runs to ``sim_time_s`` or until every vehicle ended;
    (with ``end_when_landed``: or every flight is over, ``FleetRun.flights_over``, as ``sim --end-when-landed``);
    ``stuck_s``: sim seconds without progress or motion that make a vehicle stuck.
    ``deadline_s``: wall-clock limit (``timed_out`` in the record). ``rerun``: ``save:PATH.rrd`` records the
    flight as ``autopilot --rerun`` (one vehicle) or ``quadsitl up --rerun`` (a fleet: ``PATH_<name>.rrd`` per
    vehicle, ``PATH_world.rrd``, one id) does."""
    t0, cpu0 = time.monotonic(), time.process_time()
    world = load_world(world_path)
    fleet = load_fleet(world_path)
    plans = load_fleet_missions(world_path) or [load_mission_file(world_path)]
    airframes = fleet_airframes(fleet, vehicle or mission_vehicle(world_path) or DEFAULT_VEHICLE)
    recording_id = fleet_recording_id(world_path, seed) if rerun and fleet.is_fleet else ""
    world_rrd = world_rerun_path(rerun) if rerun and fleet.is_fleet else None
    run = FleetRun(
        world,
        fleet,
        airframes,
        seed=seed,
        control_hz=CONTROL_HZ,
        recording=Path(world_rrd) if world_rrd else None,
        recording_id=recording_id,
    )
    vehicles = []
    for i, (spec, plan, airframe) in enumerate(zip(run.vehicles, plans, airframes, strict=True)):
        config = AutopilotConfig(
            vehicle=airframe.name, estimator=estimator, params_file=params_file, system_id=spec.sys_id
        )
        failures = failure_steps(fleet.failures_of(i) if fleet.is_fleet else world.failures)
        steps = script if script is not None else vehicle_script(i, arm_at_s, stagger_s)
        ap = Autopilot(config, script=CommandScript(merged(steps, failures)))
        if failures:  # as ``autopilot --world-failures``: a schedule enables the injection
            ap.params.set("SYS_FAILURE_EN", 1.0)
        if rerun:
            from autopilot.telemetry import make_listener  # imports rerun: only when a recording is asked for

            where: dict[str, Any] = {"mission_file": str(world_path)}
            if fleet.is_fleet:
                home = (spec.home_north_m, spec.home_east_m, 0.0)
                where = {"recording_id": recording_id, "fleet_name": spec.name, "home_offset_ned_m": home}
            ap.listener = make_listener(
                vehicle_rerun_spec(rerun, spec.name) if fleet.is_fleet else rerun,
                vehicle=airframe.name,
                safety_radius_m=ap.params.get("CA_RSAFE_M"),
                rtl_alt_m=ap.params.get("MIS_RTL_ALT"),
                **where,
            )
        v = _Vehicle(spec.name, plan, ap, AnswerWriter(spec.sys_id, 1), Encoder(spec.sys_id, 1))
        v.home_ned = (spec.home_north_m, spec.home_east_m, 0.0)
        v.watch = ProgressWatch(stall_s, stuck_s)
        api = VehicleAdapter(ap)
        for mission_type, items in ((MissionType.FENCE, plan.fence), (MissionType.MISSION, plan.items)):
            result, why = api.replace_mission(mission_type, [as_on_the_wire(item) for item in items])
            if result is not MissionResult.ACCEPTED:
                v.upload_error = f"{mission_type.name} upload refused: {result.name} {why}"
        vehicles.append(v)

    n, sim = run.n, run.sim
    alive = np.ones(n, dtype=bool)
    live = n  # autopilots alive (a count: no array reduction per step)
    answer, payload = np.zeros(16), np.zeros(96, dtype=np.uint8)
    uplink_decoder = Decoder()  # the simulator's reading of the own reports
    timed_out = False
    upload_error = "; ".join(v.upload_error for v in vehicles if v.upload_error)
    error = ""
    end = EndReason.STOPPED
    wait_s = physics_s = 0.0
    while not upload_error:  # a refused upload: nothing flies
        if stall_s is None and not sim.any_running():
            end = EndReason(int(sim.end_reason.max()))
            break
        if sim.t_s >= sim_time_s - 1e-9:
            end = EndReason.COMPLETED
            break
        if end_when_landed and run.flights_over():
            end = EndReason.COMPLETED
            break
        if sim.steps % CONTROL_HZ == 0:
            if stall_s is not None:
                pos = sim.pos_ned.tolist()
                verdicts = [_judge(v, sim.t_s, int(sim.end_reason[i]), pos[i]) for i, v in enumerate(vehicles)]
                if all(verdicts):  # every vehicle judged every second (no short-circuit)
                    end = EndReason.COMPLETED
                    break
                if any(v.stuck for v in vehicles):  # the case ends with its verdict (fleet_record: STUCK)
                    end = EndReason.STOPPED
                    break
            if deadline_s is not None and time.monotonic() - t0 > deadline_s:
                timed_out = True
                break
        wait0 = time.perf_counter()
        for i, datagram in run.frames(alive):
            v = vehicles[i]
            ap = v.autopilot
            cmd = ap.step(v.assembler.frame(datagram))
            step_texts = ap.drain_texts()
            v.texts += step_texts
            if ap.listener is not None:
                step_record = ap.record(step_texts)
                if step_record is not None:
                    ap.listener.on_step(step_record)
            length = v.answers.write(cmd.time_us, cmd.motor_cmd, cmd.armed, cmd.gripper_release, cmd.lockstep)
            if read_answer(v.answers.buffer, length, sim.t_us, answer, payload) != ANSWER_OK:
                error = f"{v.name}: the autopilot's answer at t={sim.t_us} us was refused by the simulator's reader"
                alive[i] = False
                live -= 1
                run.stop_motors(i)
                continue
            ap.after_answer()
            run.apply(i, answer)
            own = ap.own_reporter.report_for(cmd.time_us)
            if own is not None and v.assembler.traffic_receiver_t_us >= 0:
                run.uplink(i, uplink_decoder.decode(v.encoder.own_position(own)))
        wait_s += time.perf_counter() - wait0
        if not live:
            end = EndReason.AUTOPILOT_LOST
            break
        physics0 = time.perf_counter()
        run.advance()
        sim.record()
        physics_s += time.perf_counter() - physics0
    run.close()
    wall_s = time.monotonic() - t0
    for v in vehicles:
        v.texts += v.autopilot.drain_texts()
        close = getattr(v.autopilot.listener, "close", None)
        if close is not None:
            close()
    links = [LinkCounts(frames=v.autopilot.frames) for v in vehicles]
    ends = run.summaries(end, np.ones(n, dtype=bool), [None] * n, links, [0] * n)
    timing_s = (wait_s, 0.0, physics_s, time.process_time() - cpu0)
    summary = run.summary(end, ends, seed=seed, speed=None, wall_s=wall_s, timing_s=timing_s)
    if not fleet.is_fleet:
        (v,) = vehicles
        return {
            "error": upload_error or error,
            "timed_out": timed_out,
            "sim": asdict(solo_summary(summary, links[0], sim.max_tilt_deg(0))),
            "autopilot": v.autopilot.summary(wall_s),
            "texts": [t.text for t in v.texts],
            "wall_s": wall_s,
        }
    rows = [_row(v, wall_s, sim.t_s) for v in vehicles]
    out = record({"sim": asdict(summary), "vehicles": rows})
    out["error"] = out.get("error") or upload_error or error
    out["timed_out"] = timed_out
    out["wall_s"] = wall_s
    out["vehicle_rows"] = rows
    return out


def fly(
    case_dir: Path, deadline_s: float | None = None, rerun: str | None = None, *, stagger_s: float = 0.0
) -> dict[str, Any]:
    """Fly the campaign case in ``case_dir`` (``case.json``, ``world.yaml``, ``params.yaml``; a single-vehicle
    case also ``script.yaml``); ``stagger_s``: an encounter case's sim seconds between take-offs. ``error`` in
    the record says what went wrong, ``timed_out`` whether the deadline stopped it; ``rerun``: record the
    flight (``save:PATH``)."""
    case = json.loads((case_dir / "case.json").read_text())
    world_path = case_dir / "world.yaml"
    common: dict[str, Any] = {
        "seed": int(case["sim_seed"]),
        "params_file": str(case_dir / "params.yaml"),
        "estimator": str(case["estimator"]),
        "sim_time_s": float(case["sim_time_s"]),
        "deadline_s": deadline_s,
        "rerun": rerun,
    }
    if load_fleet(world_path).is_fleet:
        return fly_world(world_path, stagger_s=stagger_s, **common)
    script = load_script(case_dir / "script.yaml")
    return fly_world(
        world_path, vehicle=str(case["vehicle"]), script=script, stall_s=None, end_when_landed=True, **common
    )


def warm() -> None:
    """A Dask worker's set-up, once before its first case: the first 8 s of the delivery mission in process (arm,
    take-off), which imports the modules, loads the compiled kernels from numba's cache and parses the shipped
    airframes (~0.8 s of CPU that the first case would otherwise pay)."""
    fly_world(WARM_WORLD, script=vehicle_script(0, 1.0, 0.0), sim_time_s=8.0, stall_s=None)


def _judge(v: _Vehicle, t_s: float, end_code: int, pos_ned: list[float]) -> bool:
    """Update vehicle ``v``'s verdict at sim time ``t_s`` (its simulator end code, its true position); True once it
    is done (``v.stuck`` when given up as stuck, by its :class:`ProgressWatch`)."""
    if v.done:
        return True
    commander = v.autopilot.commander
    armed = commander.armed
    on_ground = commander.landed_state is LandedState.ON_GROUND
    progress = (len(v.autopilot.progress.reached_seqs), on_ground, armed)
    v.seen_armed = v.seen_armed or armed
    home = v.home_ned  # the fence by the truth, on the ground too (the autopilot reports breaches in the air only)
    rel = (pos_ned[0] - home[0], pos_ned[1] - home[1], pos_ned[2] - home[2])
    outside = armed and v.autopilot.navigator.geofence.violates(rel)
    v.fence_exits += outside and not v.outside
    v.outside = outside
    stuck = v.watch.stuck(t_s, progress, pos_ned if v.seen_armed else None)
    if end_code != _RUNNING:
        v.reason, v.done = f"the vehicle ended {EndReason(end_code).name} in the simulator", True
    elif v.seen_armed and not armed and on_ground:
        v.done = True
    elif stuck:
        v.reason, v.done, v.stuck = stuck, True, True
    return v.done


def _row(v: _Vehicle, wall_s: float, end_s: float) -> dict[str, Any]:
    """Vehicle ``v``'s row, as the fleet ground station's summary has it (and ``stuck``); ``end_s``: the sim time
    the case ended at."""
    s = v.autopilot.summary(wall_s)
    total = int(s["items_total"])  # type: ignore[call-overload]
    reached = set(s["reached_seqs"])  # type: ignore[call-overload]
    mission_done = s["mission_state"] == _MISSION_COMPLETE or (total > 0 and total - 1 in reached)
    reason = v.reason or v.upload_error or failsafe_reason(v.texts)
    if not reason and v.done and not mission_done:
        reason = "the vehicle landed and disarmed before the mission was complete"
    landed, disarmed = bool(s["landed"]), bool(s["disarmed"])
    if not reason and not v.done and not (landed and disarmed):  # (landed and disarmed after the judge's last look)
        reason = f"still flying when the case ended at {end_s:.1f} s of sim time"
    return {
        "name": v.name,
        "ok": not reason and landed and disarmed and mission_done,
        "items_total": total,
        "items_reached": len(reached),
        "items_bypassed": sum(is_bypassed(t.text) for t in v.texts),
        "sim_time_s": s["sim_time_s"],
        "landed": landed,
        "disarmed": disarmed,
        "reason": reason,
        "stuck": v.stuck,
        "fence_exits": v.fence_exits,
        "traffic_texts": [t.text for t in v.texts if t.text.startswith("Traffic")],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.campaign.inproc_flight", description=__doc__.split("\n")[0])
    parser.add_argument("world", type=Path, help="a fleet world YAML (vehicles:, traffic:)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--params", default=None, help="a parameter file every vehicle loads")
    parser.add_argument("--estimator", default="ekf", choices=("ekf", "truth"))
    parser.add_argument("--stagger-s", type=float, default=0.0, help="sim seconds between take-offs")
    parser.add_argument("--sim-time-s", type=float, default=DEFAULT_SIM_TIME_S, help="sim time limit")
    parser.add_argument("--json", action="store_true", help="print the whole record as JSON")
    args = parser.parse_args(argv)
    try:
        if not load_fleet(args.world).is_fleet:
            raise ValueError(f"{args.world}: no vehicles: list (a single-vehicle world: fly it with quadsitl up)")
        out = fly_world(
            args.world,
            seed=args.seed,
            params_file=args.params,
            estimator=args.estimator,
            stagger_s=args.stagger_s,
            sim_time_s=args.sim_time_s,
        )
    except (OSError, ValueError) as exc:  # MissionFileError, FleetWorldError, ScriptError are ValueErrors
        print(f"inproc_flight: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(out, indent=1, default=str))
        return 0
    traffic = out["traffic"]
    print(" ".join(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}" for k, v in traffic.items()))
    sim_rows = {r["name"]: r for r in out["sim"]["vehicles"]}
    for r in out["vehicle_rows"]:
        sep = sim_rows[r["name"]]["min_separation_m"]
        sep_text = "-" if sep is None or not math.isfinite(sep) else f"{sep:.2f} m"
        print(f"{r['name']:>10} ok={r['ok']!s:5} items {r['items_reached']}/{r['items_total']} min_sep {sep_text} "
              f"{r['reason']}")  # fmt: skip
    print(f"sim {out['sim']['sim_time_s']:.1f} s in {out['wall_s']:.1f} s wall")
    return 0 if not out["error"] else 1


if __name__ == "__main__":
    sys.exit(main())
