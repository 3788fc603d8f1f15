"""The simulator's part of a fleet's Rerun recording (issue 23 item 7): traffic and separations, from the truth.

Written with the recording id the autopilots use (``quadsitl up`` passes it), so the simulator's ``.rrd`` and
each autopilot's open in the viewer as one recording. Sampled at ``rate_hz`` of sim time (timeline
``sim_time``, like the autopilots'), written when the flight ends. Everything is about the world's home (NED, m):

- ``traffic/<callsign>``: the scripted aircraft's pose (``Transform3D``, while it flies), with children
  ``aircraft`` (a point, labelled) and ``nmac_volume`` (the NMAC separation volume, 152.4 m x 30.48 m half sizes,
  drawn as an ellipsoid) and ``traffic/<callsign>/path`` (its scripted route, static);
- ``separation/<a>-<b>``: per vehicle pair, the horizontal and vertical distance of their centres (m);

and the fleet's layout (:func:`sim.world_layout.fleet_blueprint`, framed on where the vehicles flew), made active.
The application id is :data:`sim.world_layout.FLEET_APPLICATION_ID`, the autopilots' in a fleet.
"""

from __future__ import annotations

from itertools import combinations
from pathlib import Path

import numpy as np
import rerun as rr

from sim.traffic import NMAC_HOR_M, NMAC_VER_M, ScriptedTraffic
from sim.world_layout import FLEET_APPLICATION_ID, SEPARATION, TRAFFIC, fleet_blueprint

TIMELINE = "sim_time"
_COLOR_TRAFFIC = (230, 40, 160)


def separation_entity(a: str, b: str) -> str:
    """The separation series of vehicles ``a`` and ``b`` (instance order)."""
    return f"{SEPARATION}/{a}-{b}"


class WorldRecorder:
    """Buffer the world's truth at ``rate_hz`` of sim time; :meth:`write` saves it as ``path``."""

    def __init__(
        self, names: list[str], traffic: ScriptedTraffic, path: Path, recording_id: str, rate_hz: float = 5.0
    ) -> None:
        if not rate_hz > 0.0 or path.suffix != ".rrd":
            raise ValueError("world recording: need a .rrd path and rate_hz > 0")
        self.names, self.traffic, self.path, self.recording_id = names, traffic, path, recording_id
        self._period_us = round(1e6 / rate_hz)
        self._next_us = 0
        self._t_us: list[int] = []
        self._pos_ned_m: list[np.ndarray] = []  # (n, 3) per sample, vehicles about the world's home
        self._traffic_ned_m: list[np.ndarray] = []  # (m, 3) per sample, NaN rows when not flying

    def sample(self, t_us: int, pos_ned_m: np.ndarray) -> None:
        """Keep the vehicles' and aircraft's positions when a sample is due."""
        if t_us < self._next_us:
            return
        self._next_us = t_us + self._period_us
        self._t_us.append(int(t_us))
        self._pos_ned_m.append(np.array(pos_ned_m, dtype=np.float64))
        self._traffic_ned_m.append(self.traffic.positions(t_us * 1e-6))

    def write(self) -> Path:
        """Save the recording (parent directories created); returns its path."""
        rec = rr.RecordingStream(FLEET_APPLICATION_ID, recording_id=self.recording_id)
        rec.set_log_time_enabled(False)
        rec.set_log_tick_enabled(False)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        rec.save(self.path)
        rec.log("/", rr.ViewCoordinates.FRD, static=True)  # X north, Y east, Z down: NED
        t_us = np.array(self._t_us, dtype=np.int64)
        times = [rr.TimeColumn(TIMELINE, duration=t_us.astype("timedelta64[us]"))]
        if len(t_us):
            pos = np.stack(self._pos_ned_m)  # (s, n, 3)
            for a, b in combinations(range(len(self.names)), 2):
                d = pos[:, a, :] - pos[:, b, :]
                cols = np.column_stack((np.hypot(d[:, 0], d[:, 1]), np.abs(d[:, 2])))
                path = separation_entity(self.names[a], self.names[b])
                rec.log(path, rr.SeriesLines(names=["horizontal_m", "vertical_m"]), static=True)
                rec.send_columns(path, indexes=times, columns=rr.Scalars.columns(scalars=cols))
        for k, aircraft in enumerate(self.traffic.aircraft):
            base = f"{TRAFFIC}/{aircraft.callsign}"
            route = [(p.north_m, p.east_m, -p.alt_m) for p in aircraft.path]
            rec.log(f"{base}/path", rr.LineStrips3D([route], colors=[_COLOR_TRAFFIC], radii=0.5), static=True)
            rec.log(
                f"{base}/aircraft",
                rr.Points3D([(0.0, 0.0, 0.0)], colors=[_COLOR_TRAFFIC], radii=3.0, labels=[aircraft.callsign]),
                static=True,
            )
            rec.log(
                f"{base}/nmac_volume",
                rr.Ellipsoids3D(half_sizes=[(NMAC_HOR_M, NMAC_HOR_M, NMAC_VER_M)], colors=[(*_COLOR_TRAFFIC, 60)]),
                static=True,
            )
            if not len(t_us):
                continue
            track = np.stack([p[k] for p in self._traffic_ned_m])
            flying = np.isfinite(track).all(axis=1)
            if flying.any():
                rec.send_columns(
                    base,
                    indexes=[rr.TimeColumn(TIMELINE, duration=t_us[flying].astype("timedelta64[us]"))],
                    columns=rr.Transform3D.columns(translation=track[flying]),
                )
        flown = np.concatenate(self._pos_ned_m) if self._pos_ned_m else None
        rec.send_blueprint(fleet_blueprint(self.names, flown), make_active=True, make_default=True)
        rec.flush()
        rec.disconnect()
        return self.path
