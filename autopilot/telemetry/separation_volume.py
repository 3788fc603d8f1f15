"""The vehicle's own UAV separation volume in a fleet recording: a vertical cylinder that follows the vehicle.

Its size is the autopilot's own NAV_TRAFF_U_HOR (radius) and NAV_TRAFF_U_VER (half height), read from each step
record (``StepRecord.uav_separation``), so a PARAM_SET shows. Another vehicle whose centre enters it has lost
separation from this one (``docs/traffic_avoidance.md``). Drawn at ``world/separation_volume`` (in a fleet:
``vehicles/<name>/separation_volume``), not under the vehicle's pose, which tilts with the attitude: the entity's
transform is the vehicle's position only, sent with the pose's columns (the 3D rate). The shape is logged again
only when its size or colour changes: blue, red while traffic avoidance has a conflict (a track predicted inside
its separation volume within NAV_TRAFF_COLL_T, ``StepRecord.traffic_decision.conflicts``).
"""

from __future__ import annotations

import numpy as np
import rerun as rr

from autopilot.telemetry import entities as ent

COLOR_CLEAR = (60, 140, 255, 110)
COLOR_CONFLICT = (255, 50, 50, 200)


class SeparationVolumeLog:
    """Draws one vehicle's separation volume into ``rec`` (at sim time, on the ``sim_time`` timeline)."""

    def __init__(self, rec: rr.RecordingStream) -> None:
        self.rec = rec
        self._key: tuple[float, float, bool] | None = None

    def on_sample(self, t_us: int, uav_separation: object | None, traffic_decision: object | None) -> None:
        """At a 3D sample: (re)draw the cylinder when its size or conflict state changed (None: not known)."""
        if uav_separation is None:
            return
        hor_m = float(getattr(uav_separation, "hor_m"))  # noqa: B009  (a SeparationVolume, duck-typed)
        ver_m = float(getattr(uav_separation, "ver_m"))  # noqa: B009
        conflict = bool(getattr(traffic_decision, "conflicts", ()))
        key = (hor_m, ver_m, conflict)
        if key == self._key:
            return
        self._key = key
        self.rec.set_time(ent.TIMELINE, duration=np.timedelta64(int(t_us), "us"))
        self.rec.log(
            ent.SEPARATION_VOLUME,
            rr.Cylinders3D(
                lengths=[2.0 * ver_m],
                radii=[hor_m],
                colors=[COLOR_CONFLICT if conflict else COLOR_CLEAR],
                fill_mode=rr.components.FillMode.MajorWireframe,
                line_radii=[0.04],
            ),
        )

    def send_positions(self, times: list[rr.TimeColumn], pos_ned_m: np.ndarray) -> None:
        """The volume's centre (n, 3) NED about the origin at the 3D samples ``times`` (one chunk)."""
        if self._key is not None:
            self.rec.send_columns(
                ent.SEPARATION_VOLUME, indexes=times, columns=rr.Transform3D.columns(translation=pos_ned_m)
            )
