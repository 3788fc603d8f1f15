"""Turn a flight recording into the paper-style figures and a CSV of its series (issue 7, paper §4).

Usage: ``python -m tools.rrd_figures RECORDING.rrd --out DIR``. Writes into DIR:

- ``attitude_error.png``: roll/pitch/yaw error (deg) vs sim time (the paper's angle-error plots);
- ``position_error.png``: north/east/down error (m) vs sim time;
- ``path_3d.png`` and ``path_xy.png``: flown path vs setpoint (and the route when recorded), 3D and top view;
- ``gains.png``: live k_p(s) of the position and attitude loops;
- ``series.csv``: one row per control step, ``t_s`` then every scalar series (``<entity>/<line>`` columns).

Exit status 0, 2 when the recording cannot be read or lacks the flight series.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from autopilot.telemetry import entities as ent
from autopilot.telemetry.recording_reader import Recording, RecordingReadError, read_recording
from autopilot.telemetry.rerun_logger import SERIES

FIGURES = ("attitude_error.png", "position_error.png", "path_3d.png", "path_xy.png", "gains.png")


def _time_plot(recording: Recording, entity: str, names: tuple[str, ...], ylabel: str, title: str, out: Path) -> None:
    s = recording.scalars(entity)
    t = s.t_us * 1e-6
    fig, ax = plt.subplots(figsize=(8, 4))
    for k, name in enumerate(names):
        ax.plot(t, s.values[:, k], label=name, linewidth=1.0)
    ax.set_xlabel("sim time (s)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)


def _route(recording: Recording, home_ned: np.ndarray) -> np.ndarray | None:
    if ent.ROUTE not in recording.entities:
        return None
    strips = recording.latest_component(ent.ROUTE, "LineStrips3D:strips")
    return np.asarray(strips[0], dtype=float) + home_ned if strips else None


def _home(recording: Recording) -> np.ndarray:
    if ent.HOME not in recording.entities:
        return np.zeros(3)
    return np.asarray(recording.latest_component(ent.HOME, "Transform3D:translation")[0], dtype=float)


def _path_plots(recording: Recording, out_dir: Path) -> None:
    pos = recording.scalars(ent.POS_NED).values
    sp = recording.scalars(ent.POS_SP_NED).values
    route = _route(recording, _home(recording))
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    ax.plot(pos[:, 1], pos[:, 0], -pos[:, 2], label="flown", linewidth=1.2)
    ax.plot(sp[:, 1], sp[:, 0], -sp[:, 2], "--", label="setpoint", linewidth=0.8)
    if route is not None:
        ax.plot(route[:, 1], route[:, 0], -route[:, 2], "o-", label="route", markersize=3, linewidth=0.6)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_zlabel("altitude (m)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out_dir / "path_3d.png", dpi=120)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 6))
    ax.plot(pos[:, 1], pos[:, 0], label="flown", linewidth=1.2)
    ax.plot(sp[:, 1], sp[:, 0], "--", label="setpoint", linewidth=0.8)
    if route is not None:
        ax.plot(route[:, 1], route[:, 0], "o-", label="route", markersize=3, linewidth=0.6)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title("path, top view (X-Y)")
    fig.tight_layout()
    fig.savefig(out_dir / "path_xy.png", dpi=120)
    plt.close(fig)


def _gains_plot(recording: Recording, out: Path) -> None:
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for ax, loop, names in ((axes[0], "position", ("x", "y", "z")), (axes[1], "attitude", ent.RPY)):
        s = recording.scalars(ent.gain_path(loop, "kp"))
        for k, name in enumerate(names):
            ax.plot(s.t_us * 1e-6, s.values[:, k], label=name, linewidth=1.0)
        ax.set_ylabel(f"k_p(s) {loop}")
        ax.grid(True, alpha=0.3)
        ax.legend()
    axes[1].set_xlabel("sim time (s)")
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)


def write_csv(recording: Recording, out: Path) -> int:
    """``series.csv``: one row per step (the rows of every series share the step times). Returns rows."""
    header = ["t_s"]
    columns = []
    t_us = None
    for path, _, width, names in SERIES:
        s = recording.scalars(path)
        if t_us is None:
            t_us = s.t_us
        elif not np.array_equal(s.t_us, t_us):
            raise RecordingReadError(f"{recording.path}: {path} is not on the same steps as {SERIES[0][0]}")
        header += [f"{path}/{n}" for n in names[:width]]
        columns.append(s.values)
    assert t_us is not None
    table = np.column_stack([t_us * 1e-6, *columns])
    with out.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(table.tolist())
    return len(table)


def make_figures(recording_path: str | Path, out_dir: str | Path) -> list[Path]:
    """Write the figures and ``series.csv`` for one recording; returns the files written."""
    recording = read_recording(recording_path)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _time_plot(recording, ent.ATT_ERR, ent.RPY, "error (deg)", "attitude error", out / "attitude_error.png")
    _time_plot(recording, ent.POS_ERR_NED, ent.XYZ, "error (m)", "position error", out / "position_error.png")
    _path_plots(recording, out)
    _gains_plot(recording, out / "gains.png")
    write_csv(recording, out / "series.csv")
    return [out / name for name in (*FIGURES, "series.csv")]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.rrd_figures", description=__doc__.split("\n")[0])
    parser.add_argument("recording", help="a .rrd written by the autopilot (--rerun save:PATH)")
    parser.add_argument("--out", default=None, help="output directory (default: beside the recording, <name>_figures)")
    args = parser.parse_args(argv)
    out = Path(args.out) if args.out else Path(args.recording).with_name(Path(args.recording).stem + "_figures")
    try:
        files = make_figures(args.recording, out)
    except RecordingReadError as exc:
        print(f"rrd_figures: {exc}", file=sys.stderr)
        return 2
    for f in files:
        print(f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
