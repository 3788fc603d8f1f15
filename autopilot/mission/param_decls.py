"""Mission parameters (PX4-style names, SPEC §8): acceptance radii, upload limits, RTL altitude, cruise speed."""

from __future__ import annotations

from autopilot.parameters.store import ParamSpec


def mission_param_specs() -> list[ParamSpec]:
    """Every parameter the mission executor and mission validation read."""
    return [
        ParamSpec(
            "MIS_ACC_RAD", 1.0, 0.05, 200.0, "m", "Default horizontal acceptance radius of a waypoint (param2 = 0)"
        ),
        ParamSpec("MIS_ALT_ACC_RAD", 0.8, 0.05, 50.0, "m", "Vertical acceptance for waypoints, takeoff and RTL climb"),
        ParamSpec("MIS_CRUISE_SPD", 5.0, 0.1, 30.0, "m/s", "Mission cruise speed until a DO_CHANGE_SPEED item"),
        ParamSpec("MIS_SPEED_MAX", 20.0, 0.1, 50.0, "m/s", "Largest speed a DO_CHANGE_SPEED item may ask for"),
        ParamSpec(
            "MIS_RTL_ALT", 30.0, 0.0, 500.0, "m", "RTL: climb to at least this altitude above home before returning"
        ),
        ParamSpec("MIS_MAX_ITEMS", 1000.0, 1.0, 10000.0, "", "Largest mission upload accepted (items)"),
        ParamSpec("MIS_ALT_MIN", 1.0, 0.0, 1000.0, "m", "Lowest altitude above home of takeoff/waypoint/loiter items"),
        ParamSpec("MIS_ALT_MAX", 120.0, 1.0, 10000.0, "m", "Highest altitude above home of any mission item"),
        ParamSpec("MIS_DIST_MAX", 10000.0, 10.0, 1.0e6, "m", "Largest horizontal distance of a mission item from home"),
    ]


#: The defaults of :func:`mission_param_specs` by name (the executor's and validation's dataclass defaults).
MISSION_PARAM_DEFAULTS: dict[str, float] = {spec.name: spec.default for spec in mission_param_specs()}
