"""``make run``: fly the default delivery mission end to end through sim + autopilot + ground station.

Starts ``quadsitl up`` (simulator and autopilot as two processes, ``--speed max``) on a free
``--instance``, then runs the ground-station script's ``fly`` on the mission, stops both
processes, and prints one summary. Everything lands in ``runs/<timestamp>/``:
``flight.rrd`` (Rerun recording), ``sim_summary.json``, ``autopilot_summary.json``,
``gcs_summary.json``, ``summary.json`` and the processes' logs.

Usage: ``python -m tools.run_delivery [--mission missions/delivery.yaml] [--speed max|N]
[--vehicle NAME] [--seed N] [--out-dir DIR] [--timeout-s S]``.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import time
from datetime import datetime
from pathlib import Path

# Default ports of SPEC §3; --instance N offsets every one of them by N.
_BASE_PORTS = (14560, 18570, 14550, 14580, 14540)


def _ports_free(instance: int) -> bool:
    for port in _BASE_PORTS:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            try:
                s.bind(("127.0.0.1", port + instance))
            except OSError:
                return False
    return True


def free_instance(start: int = 0, limit: int = 200) -> int:
    """The smallest instance number >= start whose ports are all free on 127.0.0.1."""
    for instance in range(start, start + limit):
        if _ports_free(instance):
            return instance
    raise RuntimeError(f"no free quadsitl instance in {start}..{start + limit - 1}")


def _stop(proc: subprocess.Popen[bytes], timeout_s: float = 15.0) -> int:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return int(proc.returncode)


def _read_json(path: Path) -> dict[str, object]:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.run_delivery", description=__doc__.split("\n")[0])
    parser.add_argument("--mission", default="missions/delivery.yaml", help="mission file (YAML, .waypoints, .plan)")
    parser.add_argument("--speed", default="max", help="'max' or a real-time factor such as 1 or 10")
    parser.add_argument("--vehicle", default=None, help="vehicle config name (default: the mission's)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out-dir", default=None, help="default runs/<timestamp>")
    parser.add_argument("--timeout-s", type=float, default=600.0, help="wall-clock limit for the flight")
    parser.add_argument("--rerun", default=None, help="override --rerun (default save:<out-dir>/flight.rrd)")
    args = parser.parse_args(argv)

    mission = Path(args.mission)
    if not mission.is_file():
        print(f"run_delivery: mission file {mission} not found", file=sys.stderr)
        return 2
    out_dir = Path(args.out_dir or Path("runs") / datetime.now().strftime("%Y%m%d-%H%M%S"))
    out_dir.mkdir(parents=True, exist_ok=True)
    recording = out_dir / "flight.rrd"
    instance = free_instance()

    up_cmd = [
        sys.executable, "-m", "quadsitl_cli", "up",
        "--world", str(mission), "--seed", str(args.seed), "--speed", args.speed,
        "--instance", str(instance), "--log-dir", str(out_dir),
        "--rerun", args.rerun or f"save:{recording}",
    ]  # fmt: skip
    if args.vehicle:
        up_cmd += ["--vehicle", args.vehicle]
    gcs_cmd = [
        sys.executable, "-m", "tools.gcs", "--instance", str(instance),
        "fly", str(mission), "--summary", str(out_dir / "gcs_summary.json"), "--timeout-s", str(args.timeout_s),
    ]  # fmt: skip

    print(f"[run] mission {mission} -> {out_dir} (instance {instance}, speed {args.speed})", flush=True)
    t0 = time.monotonic()
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    with open(out_dir / "up.log", "wb") as up_log:
        up = subprocess.Popen(up_cmd, stdout=up_log, stderr=subprocess.STDOUT, env=env)
        try:
            gcs_rc = subprocess.call(gcs_cmd, env=env)
        finally:
            up_rc = _stop(up)
    wall_s = time.monotonic() - t0

    sim = _read_json(out_dir / "sim_summary.json")
    ap = _read_json(out_dir / "autopilot_summary.json")
    gcs = _read_json(out_dir / "gcs_summary.json")
    ok = gcs_rc == 0 and bool(gcs.get("ok")) and sim.get("collisions", 1) == 0
    summary = {
        "ok": ok,
        "mission": str(mission),
        "out_dir": str(out_dir),
        "wall_time_s": round(wall_s, 2),
        "gcs": gcs,
        "sim": sim,
        "autopilot": ap,
        "recording": str(recording) if recording.exists() else None,
        "exit_codes": {"gcs": gcs_rc, "up": up_rc},
    }
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")

    print()
    print(f"{'result':<26} {'OK' if ok else 'FAILED'}")
    print(f"{'items reached':<26} {gcs.get('items_reached', '?')}/{gcs.get('items_total', '?')}")
    print(f"{'landed / disarmed':<26} {gcs.get('landed', '?')} / {gcs.get('disarmed', '?')}")
    print(f"{'sim time / wall time':<26} {sim.get('sim_time_s', '?')} s / {sim.get('wall_time_s', '?')} s")
    print(f"{'real-time factor':<26} {sim.get('real_time_factor', '?')}")
    print(f"{'payload released at':<26} {sim.get('payload_released_at_s', '?')} s (sim time)")
    print(f"{'collisions':<26} {sim.get('collisions', '?')}")
    print(f"{'min clearance':<26} {sim.get('min_clearance_m', '?')} m")
    print(f"{'max tilt':<26} {sim.get('max_tilt_deg', '?')} deg")
    print(f"{'sim end reason':<26} {sim.get('end_reason', '?')}")
    print(f"\nsummary:   {out_dir / 'summary.json'}")
    if recording.exists():
        print(f"recording: {recording}  (open it with: .venv/bin/rerun {recording})")
    else:
        print("recording: none written (see up.log)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
