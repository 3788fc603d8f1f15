"""Avoidance-planner parameters (SPEC §7, §8): declared once, read into a frozen PlannerParams."""

from __future__ import annotations

from dataclasses import dataclass

from autopilot.parameters.store import ParamSpec, ParamStore


def planner_param_specs() -> tuple[ParamSpec, ...]:
    """The CA_* parameters of the obstacle-avoidance planner."""
    return (
        ParamSpec("CA_ENABLE", 1.0, 0.0, 1.0, "", "Obstacle avoidance: 1 plans detours, 0 only maps obstacles"),
        ParamSpec("CA_RSAFE_M", 2.0, 0.3, 20.0, "m", "Safety-sphere radius R_safe kept from every obstacle surface"),
        ParamSpec("CA_MARGIN_M", 0.5, 0.0, 5.0, "m", "Extra radius on detour via points beyond R_safe"),
        ParamSpec("CA_TRACK_TOL_M", 0.5, 0.0, 5.0, "m", "Documented tracking tolerance: clearance >= R_safe - this"),
        ParamSpec("CA_LOOKAHEAD_M", 30.0, 5.0, 200.0, "m", "Route length checked ahead for conflicts"),
        ParamSpec("CA_VMAX_M_S", 6.0, 0.5, 20.0, "m/s", "Speed limit on the detour curve (hodograph bound)"),
        ParamSpec("CA_CRUISE_M_S", 5.0, 0.5, 20.0, "m/s", "Detour speed when the vehicle flies slower than this"),
        ParamSpec("CA_AMAX_M_S2", 3.0, 0.5, 15.0, "m/s^2", "Acceleration limit on the detour curve (hodograph bound)"),
        ParamSpec("CA_REJOIN_M", 4.0, 0.5, 50.0, "m", "Route distance past the safety sphere where a detour rejoins"),
        ParamSpec("CA_FORGET_S", 20.0, 0.5, 600.0, "s", "An obstacle not detected for this long is forgotten"),
        ParamSpec("CA_MERGE_M", 1.0, 0.0, 10.0, "m", "Detections whose volumes overlap by this are one obstacle"),
        ParamSpec("CA_MIN_AGL_M", 2.0, 0.0, 50.0, "m", "Lowest altitude above home a detour may use (ground)"),
        ParamSpec("CA_CEILING_M", 120.0, 5.0, 1000.0, "m", "Highest altitude above home a detour may use"),
        ParamSpec("CA_SENS_RANGE_M", 25.0, 1.0, 200.0, "m", "Obstacle sensor range (stereo camera max range)"),
        ParamSpec("CA_REPLAN_S", 0.2, 0.0, 5.0, "s", "Shortest interval between two replans"),
        ParamSpec("CA_FENCE_MARG_M", 3.0, 0.0, 50.0, "m", "Routes keep this far from fence boundaries"),
        ParamSpec("CA_NOROUTE_T", 30.0, 0.0, 3600.0, "s", "With no route, hold this long, then CA_NOROUTE_ACT"),
        ParamSpec("CA_NOROUTE_ACT", 3.0, 2.0, 4.0, "", "Action when no route exists: 2 hold, 3 return, 4 land"),
    )


@dataclass(frozen=True, slots=True)
class PlannerParams:
    """The planner's parameter values (SI units; altitudes above home)."""

    enable: bool = True
    r_safe_m: float = 2.0
    margin_m: float = 0.5
    track_tol_m: float = 0.5
    lookahead_m: float = 30.0
    v_max_m_s: float = 6.0
    cruise_m_s: float = 5.0
    a_max_m_s2: float = 3.0
    rejoin_m: float = 4.0
    forget_s: float = 20.0
    merge_m: float = 1.0
    min_agl_m: float = 2.0
    ceiling_m: float = 120.0
    sensor_range_m: float = 25.0
    replan_s: float = 0.2
    fence_margin_m: float = 3.0
    noroute_t_s: float = 30.0
    noroute_action: int = 3

    @classmethod
    def from_store(cls, store: ParamStore) -> PlannerParams:
        """Read the CA_* values in force (call again after a PARAM_SET: changes apply in flight)."""
        g = store.get
        return cls(
            enable=g("CA_ENABLE") >= 0.5,
            r_safe_m=g("CA_RSAFE_M"),
            margin_m=g("CA_MARGIN_M"),
            track_tol_m=g("CA_TRACK_TOL_M"),
            lookahead_m=g("CA_LOOKAHEAD_M"),
            v_max_m_s=g("CA_VMAX_M_S"),
            cruise_m_s=g("CA_CRUISE_M_S"),
            a_max_m_s2=g("CA_AMAX_M_S2"),
            rejoin_m=g("CA_REJOIN_M"),
            forget_s=g("CA_FORGET_S"),
            merge_m=g("CA_MERGE_M"),
            min_agl_m=g("CA_MIN_AGL_M"),
            ceiling_m=g("CA_CEILING_M"),
            sensor_range_m=g("CA_SENS_RANGE_M"),
            replan_s=g("CA_REPLAN_S"),
            fence_margin_m=g("CA_FENCE_MARG_M"),
            noroute_t_s=g("CA_NOROUTE_T"),
            noroute_action=int(g("CA_NOROUTE_ACT")),
        )
