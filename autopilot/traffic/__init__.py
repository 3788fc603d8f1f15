"""Traffic avoidance (SPEC §13): track table, closest-approach prediction, right-of-way rules and Bézier detours
around moving traffic. The entry point is :class:`TrafficAvoidance`; ``docs/traffic_avoidance.md`` is the design."""

from autopilot.traffic.avoidance import Conflict, TrafficAvoidance, TrafficDecision
from autopilot.traffic.param_decls import TrafficAction, TrafficParams, traffic_param_specs
from autopilot.traffic.resolution import AvoidLimits, Maneuver, OwnShip, Resolution

__all__ = [
    "AvoidLimits",
    "Conflict",
    "Maneuver",
    "OwnShip",
    "Resolution",
    "TrafficAction",
    "TrafficAvoidance",
    "TrafficDecision",
    "TrafficParams",
    "traffic_param_specs",
]
