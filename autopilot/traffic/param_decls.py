"""Traffic-avoidance parameters (SPEC §13): PX4's NAV_TRAFF_* names and meanings, plus the separation volumes.

PX4 (``navigator_params.yaml``): NAV_TRAFF_AVOID 0 disabled, 1 warn only, 2 return, 3 land, 4 position hold
(PX4's 5 is flight termination, which quadsitl does not have: here 5 is *avoid*, the default);
NAV_TRAFF_A_HOR / NAV_TRAFF_A_VER the alert volume and NAV_TRAFF_COLL_T the time-to-collision horizon.
The separation volumes per traffic class are quadsitl's (``docs/traffic_avoidance.md``).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

from autopilot.parameters.store import ParamSpec, ParamStore


class TrafficAction(IntEnum):
    """Values of NAV_TRAFF_AVOID (PX4's 0..4; 5 = avoid replaces PX4's terminate)."""

    OFF = 0
    WARN = 1
    RETURN = 2
    LAND = 3
    HOLD = 4
    AVOID = 5


def traffic_param_specs() -> tuple[ParamSpec, ...]:
    """The NAV_TRAFF_* parameters of the traffic avoidance."""
    return (
        ParamSpec(
            "NAV_TRAFF_AVOID",
            5.0,
            0.0,
            5.0,
            "",
            "Traffic conflict action: 0 off, 1 warn, 2 return, 3 land, 4 hold, 5 avoid",
        ),
        ParamSpec("NAV_TRAFF_A_HOR", 500.0, 10.0, 10000.0, "m", "Alert radius: predicted CPA inside it is an advisory"),
        ParamSpec(
            "NAV_TRAFF_A_VER", 500.0, 5.0, 5000.0, "m", "Alert half-height: predicted CPA inside it is an advisory"
        ),
        ParamSpec("NAV_TRAFF_COLL_T", 60.0, 3.0, 300.0, "s", "Look-ahead horizon of the closest-approach prediction"),
        ParamSpec("NAV_TRAFF_U_HOR", 10.0, 1.0, 1000.0, "m", "UAV separation: horizontal radius kept from other UAVs"),
        ParamSpec("NAV_TRAFF_U_VER", 5.0, 0.5, 500.0, "m", "UAV separation: vertical half-height kept from other UAVs"),
        ParamSpec("NAV_TRAFF_M_HOR", 150.0, 10.0, 5000.0, "m", "Manned separation: horizontal radius (NMAC 500 ft)"),
        ParamSpec("NAV_TRAFF_M_VER", 30.0, 5.0, 1000.0, "m", "Manned separation: vertical half-height (NMAC 100 ft)"),
        ParamSpec(
            "NAV_TRAFF_MARGIN", 0.3, 0.0, 2.0, "", "Detours plan for the separation volume grown by this fraction"
        ),
        ParamSpec("NAV_TRAFF_AGE_S", 5.0, 1.0, 60.0, "s", "A track not reported for this long is dropped"),
    )


@dataclass(frozen=True, slots=True)
class SeparationVolume:
    """A vertical cylinder about the vehicle: separation is lost only when BOTH are inside (horizontal < radius and
    |vertical| < half-height); either one outside keeps separation."""

    hor_m: float
    ver_m: float

    def grown(self, fraction: float) -> SeparationVolume:
        return SeparationVolume(self.hor_m * (1.0 + fraction), self.ver_m * (1.0 + fraction))

    def contains(self, dh_m: float, dv_m: float) -> bool:
        return dh_m < self.hor_m and abs(dv_m) < self.ver_m


@dataclass(frozen=True, slots=True)
class TrafficParams:
    """The NAV_TRAFF_* values in force (SI units)."""

    action: TrafficAction = TrafficAction.AVOID
    alert: SeparationVolume = SeparationVolume(500.0, 500.0)
    horizon_s: float = 60.0
    uav: SeparationVolume = SeparationVolume(10.0, 5.0)
    manned: SeparationVolume = SeparationVolume(150.0, 30.0)
    margin: float = 0.2
    max_age_s: float = 5.0

    @classmethod
    def from_store(cls, store: ParamStore) -> TrafficParams:
        """Read the values in force (call again after a PARAM_SET)."""
        g = store.get
        return cls(
            action=TrafficAction(round(g("NAV_TRAFF_AVOID"))),
            alert=SeparationVolume(g("NAV_TRAFF_A_HOR"), g("NAV_TRAFF_A_VER")),
            horizon_s=g("NAV_TRAFF_COLL_T"),
            uav=SeparationVolume(g("NAV_TRAFF_U_HOR"), g("NAV_TRAFF_U_VER")),
            manned=SeparationVolume(g("NAV_TRAFF_M_HOR"), g("NAV_TRAFF_M_VER")),
            margin=g("NAV_TRAFF_MARGIN"),
            max_age_s=g("NAV_TRAFF_AGE_S"),
        )
