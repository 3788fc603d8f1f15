"""Turn a flight recording into the paper-style figures and a CSV of its series (paper §4).

Usage: ``python -m tools.rrd_figures RECORDING.rrd --out DIR``. Writes into DIR:

- ``attitude_error.png``: roll/pitch/yaw error (deg) vs sim time (the paper's angle-error plots);
- ``position_error.png``: north/east/down error (m) vs sim time;
- ``path_3d.png`` and ``path_xy.png``: flown path vs setpoint and the route (when recorded, at the heights
  it is flown: an RTL climbs to its return altitude), with the world's obstacles and the fence, 3D and top
  view (framed on the flight, so a wide inclusion fence does not shrink it to a dot);
- ``altitude.png``: flown and setpoint altitude above the origin vs sim time;
- ``gains.png``: live k_p(s) of the position and attitude loops;
- ``series.csv``: one row per control step, ``t_s`` then every scalar series (``<entity>/<line>`` columns;
  a series recorded at a lower rate holds its latest sample).

Exit status 0, 2 when the recording cannot be read or lacks the flight series.
"""

from __future__ import annotations

import argparse
import csv
import sys
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from autopilot.telemetry import entities as ent
from autopilot.telemetry.recording_reader import Recording, RecordingReadError, read_recording
from autopilot.telemetry.rerun_logger import SERIES

FIGURES = ("attitude_error.png", "position_error.png", "path_3d.png", "path_xy.png", "altitude.png", "gains.png")
_OBSTACLE_COLOR = "0.55"
_FENCE_EXCL, _FENCE_INCL = "tab:red", "tab:cyan"


@dataclass(frozen=True)
class Solid:
    """An obstacle as a horizontal outline (m, 2) north-east about the origin and its bottom/top altitude (m)."""

    outline_ne: np.ndarray
    bottom_m: float
    top_m: float


def _circle(center_ne: np.ndarray, radius_m: float, n: int = 40) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * np.pi, n)
    return np.column_stack([center_ne[0] + radius_m * np.cos(a), center_ne[1] + radius_m * np.sin(a)])


def _static(recording: Recording, entity: str, component: str) -> list[object]:
    if entity not in recording.entities:
        return []
    try:
        return recording.static_component(entity, component)
    except RecordingReadError:
        return []


def obstacles(recording: Recording, home_ned: np.ndarray) -> list[Solid]:
    """The world's true obstacles recorded with ``--rerun-world`` (cylinders, boxes, spheres)."""
    base = ent.OBSTACLES_TRUE
    solids: list[Solid] = []
    cyl = f"{base}/cylinders"
    for c, r, h in zip(
        _static(recording, cyl, "Cylinders3D:centers"),
        _static(recording, cyl, "Cylinders3D:radii"),
        _static(recording, cyl, "Cylinders3D:lengths"),
        strict=False,
    ):
        center = np.asarray(c, dtype=float) + home_ned
        solids.append(Solid(_circle(center[:2], float(r)), -center[2] - float(h) / 2, -center[2] + float(h) / 2))
    box = f"{base}/boxes"
    rotations = _static(recording, box, "Boxes3D:rotation_axis_angles")
    for k, (c, half) in enumerate(
        zip(_static(recording, box, "Boxes3D:centers"), _static(recording, box, "Boxes3D:half_sizes"), strict=False)
    ):
        center, (hn, he, hd) = np.asarray(c, dtype=float) + home_ned, (float(v) for v in half)
        yaw = _yaw(rotations[k]) if k < len(rotations) else 0.0
        corners = np.array([(hn, he), (hn, -he), (-hn, -he), (-hn, he), (hn, he)])
        rot = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
        solids.append(Solid(corners @ rot.T + center[:2], -center[2] - hd, -center[2] + hd))
    sph = f"{base}/spheres"
    for c, half in zip(
        _static(recording, sph, "Ellipsoids3D:centers"),
        _static(recording, sph, "Ellipsoids3D:half_sizes"),
        strict=False,
    ):
        center, r = np.asarray(c, dtype=float) + home_ned, float(half[0])
        solids.append(Solid(_circle(center[:2], r), -center[2] - r, -center[2] + r))
    return solids


def _yaw(rotation: object) -> float:
    """The angle of a ``RotationAxisAngle`` about down (the recorded form: {"axis": [...], "angle": rad})."""
    if isinstance(rotation, dict):
        axis, angle = rotation.get("axis") or (0.0, 0.0, 1.0), rotation.get("angle") or 0.0
        return float(angle) * (1.0 if float(axis[2]) >= 0.0 else -1.0)
    return 0.0


def fences(recording: Recording, home_ned: np.ndarray) -> list[tuple[np.ndarray, str]]:
    """The recorded fence outlines (m, 2) north-east about the origin, each with its colour."""
    strips = _static(recording, ent.FENCE, "LineStrips3D:strips")
    colors = _static(recording, ent.FENCE, "LineStrips3D:colors")
    out = []
    for k, strip in enumerate(strips):
        ne = np.asarray(strip, dtype=float)[:, :2] + home_ned[:2]
        rgba = int(colors[k]) if k < len(colors) and colors[k] is not None else 0
        inclusion = ((rgba >> 24) & 0xFF) < ((rgba >> 8) & 0xFF)  # blue-ish (inclusion) rather than red
        out.append((ne, _FENCE_INCL if inclusion else _FENCE_EXCL))
    return out


def _limits(points_ne: list[np.ndarray], margin_m: float = 10.0) -> tuple[float, float, float, float]:
    """(north lo, north hi, east lo, east hi) around the flight, square, with a margin."""
    allp = np.vstack([p for p in points_ne if len(p)])
    lo, hi = allp.min(axis=0) - margin_m, allp.max(axis=0) + margin_m
    half = max(hi - lo) / 2.0
    mid = (lo + hi) / 2.0
    return mid[0] - half, mid[0] + half, mid[1] - half, mid[1] + half


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
    home = _home(recording)
    route = _route(recording, home)
    solids, fence = obstacles(recording, home), fences(recording, home)
    flight_ne = [pos[:, :2], sp[np.isfinite(sp).all(axis=1), :2], *([route[:, :2]] if route is not None else [])]
    n_lo, n_hi, e_lo, e_hi = _limits(flight_ne + [s.outline_ne for s in solids])
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    if route is not None:  # under the flight: the flown line stays visible where it follows the route
        ax.plot(
            route[:, 1], route[:, 0], -route[:, 2], "o-", label="route", markersize=3, linewidth=0.6, color="tab:green"
        )
    ax.plot(sp[:, 1], sp[:, 0], -sp[:, 2], "--", label="setpoint", linewidth=0.8, color="tab:orange")
    ax.plot(pos[:, 1], pos[:, 0], -pos[:, 2], label="flown", linewidth=1.2, color="tab:blue")
    for k, s in enumerate(solids):
        label = "obstacles" if k == 0 else None
        for alt in (s.bottom_m, s.top_m):
            ax.plot(s.outline_ne[:, 1], s.outline_ne[:, 0], alt, color=_OBSTACLE_COLOR, linewidth=0.8, label=label)
            label = None
        for n, e in s.outline_ne[:: max(1, len(s.outline_ne) // 4)]:
            ax.plot([e, e], [n, n], [s.bottom_m, s.top_m], color=_OBSTACLE_COLOR, linewidth=0.6)
    for k, (ne, color) in enumerate(fence):
        inside = (ne[:, 0] >= n_lo) & (ne[:, 0] <= n_hi) & (ne[:, 1] >= e_lo) & (ne[:, 1] <= e_hi)
        shown = np.where(inside[:, None], ne, np.nan)  # the parts of the fence within the flight's frame
        ax.plot(shown[:, 1], shown[:, 0], 0.0, color=color, linewidth=1.0, label="fence" if k == 0 else None)
    ax.set_xlim(e_lo, e_hi)
    ax.set_ylim(n_lo, n_hi)
    ax.set_zlim(bottom=0.0)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_zlabel("altitude (m)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out_dir / "path_3d.png", dpi=120)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 6))
    for k, s in enumerate(solids):
        ax.fill(s.outline_ne[:, 1], s.outline_ne[:, 0], color=_OBSTACLE_COLOR, alpha=0.6,
                label="obstacles" if k == 0 else None)  # fmt: skip
    for k, (ne, color) in enumerate(fence):
        ax.plot(ne[:, 1], ne[:, 0], color=color, linewidth=1.5, label="fence" if k == 0 else None)
    if route is not None:
        ax.plot(route[:, 1], route[:, 0], "o-", label="route", markersize=3, linewidth=0.6, color="tab:green")
    ax.plot(sp[:, 1], sp[:, 0], "--", label="setpoint", linewidth=0.8, color="tab:orange")
    ax.plot(pos[:, 1], pos[:, 0], label="flown", linewidth=1.2, color="tab:blue")
    ax.set_xlim(e_lo, e_hi)
    ax.set_ylim(n_lo, n_hi)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title("path, top view (north-east)")
    fig.tight_layout()
    fig.savefig(out_dir / "path_xy.png", dpi=120)
    plt.close(fig)


def _altitude_plot(recording: Recording, out: Path) -> None:
    pos, sp = recording.scalars(ent.POS_NED), recording.scalars(ent.POS_SP_NED)
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.plot(pos.t_us * 1e-6, -pos.values[:, 2], label="flown", linewidth=1.2)
    ax.plot(sp.t_us * 1e-6, -sp.values[:, 2], "--", label="setpoint", linewidth=0.8)
    ax.set_xlabel("sim time (s)")
    ax.set_ylabel("altitude above origin (m)")
    ax.set_title("altitude")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out, dpi=120)
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
    """``series.csv``: one row per control step (the steps of the position series); a series recorded at a
    lower rate holds its latest sample (NaN before its first). Returns the number of rows."""
    t_us = recording.scalars(ent.POS_NED).t_us
    header = ["t_s"]
    columns = []
    for path, _, width, names in SERIES:
        s = recording.scalars(path)
        idx = np.searchsorted(s.t_us, t_us, side="right") - 1
        held = np.where((idx >= 0)[:, None], s.values[np.clip(idx, 0, None)], np.nan)
        header += [f"{path}/{n}" for n in names[:width]]
        columns.append(held)
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
    _altitude_plot(recording, out / "altitude.png")
    _gains_plot(recording, out / "gains.png")
    write_csv(recording, out / "series.csv")
    return [out / name for name in (*FIGURES, "series.csv")]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m tools.rrd_figures",
        description="Turn a flight recording into paper-style PNG figures and a CSV of its series.",
    )
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
