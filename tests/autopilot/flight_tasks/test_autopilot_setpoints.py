"""Setpoint generator: speed, acceleration, jerk and yaw-rate limits hold; it stops at the target; LAND descends;
VELOCITY flies the commanded velocity within the limits."""

from __future__ import annotations

import math

import pytest

from autopilot.flight_tasks.setpoints import (
    LAND_ALIGN_M,
    LAND_MAX_LEAD_M,
    VELOCITY_MAX_LEAD_M,
    NavTarget,
    SetpointGenerator,
    SetpointLimits,
    TargetKind,
)

DT = 0.004
LIMITS = SetpointLimits(acc_xy_m_s2=3.0, acc_up_m_s2=2.5, acc_down_m_s2=1.5, jerk_m_s3=8.0, yaw_rate_rad_s=0.5)


def _fly(target: NavTarget, seconds: float, gen: SetpointGenerator | None = None) -> tuple[SetpointGenerator, dict]:
    gen = gen or SetpointGenerator(LIMITS)
    worst = {"v_xy": 0.0, "v_up": 0.0, "v_dn": 0.0, "a_xy": 0.0, "a_up": 0.0, "a_dn": 0.0, "jerk": 0.0, "yaw_rate": 0.0}
    prev_acc = list(gen.acc_ned)
    prev_yaw = gen.yaw_rad
    for _ in range(round(seconds / DT)):
        gen.update(target, DT, (0.0, 0.0, 0.0))
        v, a = gen.vel_ned, gen.acc_ned
        worst["v_xy"] = max(worst["v_xy"], math.hypot(v[0], v[1]))
        worst["v_up"] = max(worst["v_up"], -v[2])
        worst["v_dn"] = max(worst["v_dn"], v[2])
        worst["a_xy"] = max(worst["a_xy"], math.hypot(a[0], a[1]))
        worst["a_up"] = max(worst["a_up"], -a[2])
        worst["a_dn"] = max(worst["a_dn"], a[2])
        worst["jerk"] = max(worst["jerk"], max(abs(x - y) for x, y in zip(a, prev_acc, strict=True)) / DT)
        dyaw = (gen.yaw_rad - prev_yaw + math.pi) % (2 * math.pi) - math.pi
        worst["yaw_rate"] = max(worst["yaw_rate"], abs(dyaw) / DT)
        prev_acc, prev_yaw = list(a), gen.yaw_rad
    return gen, worst


@pytest.mark.parametrize(
    ("goal", "speed_xy"),
    [((60.0, -25.0, -20.0), 5.0), ((3.0, 1.0, -1.0), 12.0), ((-200.0, 0.0, 10.0), 12.0), ((0.0, 0.0, -0.3), 5.0)],
)
def test_limits_hold_and_the_reference_stops_at_the_target(goal: tuple[float, float, float], speed_xy: float) -> None:
    target = NavTarget(TargetKind.POSITION, goal, 1.0, speed_xy, 3.0, 1.5)
    gen = SetpointGenerator(LIMITS)
    gen.reset((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), -2.0)
    gen, worst = _fly(target, 120.0, gen)
    eps = 1e-9
    assert worst["v_xy"] <= speed_xy + eps and worst["v_up"] <= 3.0 + eps and worst["v_dn"] <= 1.5 + eps
    assert worst["a_xy"] <= LIMITS.acc_xy_m_s2 + eps
    assert worst["a_up"] <= LIMITS.acc_up_m_s2 + eps and worst["a_dn"] <= LIMITS.acc_down_m_s2 + eps
    assert worst["jerk"] <= LIMITS.jerk_m_s3 * 1.0001
    assert worst["yaw_rate"] <= LIMITS.yaw_rate_rad_s * 1.0001
    assert gen.pos_ned == pytest.approx(goal, abs=1e-3)
    assert gen.vel_ned == pytest.approx((0.0, 0.0, 0.0), abs=1e-3)
    assert gen.yaw_rad == pytest.approx(1.0)


def test_no_overshoot_and_cruise_speed_reached_on_a_long_leg() -> None:
    gen = SetpointGenerator(LIMITS)
    target = NavTarget(TargetKind.POSITION, (100.0, 0.0, 0.0), math.nan, 8.0)
    furthest, top_speed = 0.0, 0.0
    for _ in range(round(40.0 / DT)):
        gen.update(target, DT, (0.0, 0.0, 0.0))
        furthest = max(furthest, gen.pos_ned[0])
        top_speed = max(top_speed, gen.vel_ned[0])
    assert furthest - 100.0 < 0.02
    assert top_speed == pytest.approx(8.0, abs=1e-6)


def test_target_change_in_flight_keeps_velocity_continuous() -> None:
    gen = SetpointGenerator(LIMITS)
    _fly(NavTarget(TargetKind.POSITION, (100.0, 0.0, 0.0), math.nan, 6.0), 10.0, gen)
    v_before = list(gen.vel_ned)
    gen, worst = _fly(NavTarget(TargetKind.POSITION, (0.0, 100.0, 0.0), math.nan, 6.0), 0.2, gen)
    dv = math.dist(v_before, gen.vel_ned)
    assert dv <= LIMITS.acc_xy_m_s2 * 0.2 + 1e-9
    assert worst["jerk"] <= LIMITS.jerk_m_s3 * 1.0001


def test_land_descends_at_speed_and_stays_near_a_vehicle_on_the_ground() -> None:
    gen = SetpointGenerator(LIMITS)
    gen.reset((0.0, 0.0, -5.0), (0.0, 0.0, 0.0), 0.0)
    land = NavTarget(TargetKind.LAND, (0.0, 0.0, -5.0), math.nan, 5.0, 3.0, 0.7)
    for _ in range(round(5.0 / DT)):
        gen.update(land, DT, (0.0, 0.0, -5.0 + 0.0))
    assert gen.vel_ned[2] == pytest.approx(0.7, abs=1e-6)
    assert gen.pos_ned[2] == pytest.approx(-5.0 + LAND_MAX_LEAD_M)  # vehicle held at -5: lead clamped


def test_land_pushed_aside_goes_back_over_the_spot_before_it_descends() -> None:
    """A landing resumed 40 m from its spot (traffic pushed it aside): the reference keeps its height until it is
    back within LAND_ALIGN_M, then descends there; it never flies sideways low over the ground."""
    gen = SetpointGenerator(LIMITS)
    gen.reset((40.0, 0.0, -12.0), (0.0, 0.0, 0.0), 0.0)
    land = NavTarget(TargetKind.LAND, (0.0, 0.0, -12.0), math.nan, 5.0, 3.0, 1.5)
    lowest_away = -math.inf
    for _ in range(round(30.0 / DT)):
        gen.update(land, DT, (gen.pos_ned[0], gen.pos_ned[1], gen.pos_ned[2]))
        if math.hypot(gen.pos_ned[0], gen.pos_ned[1]) > LAND_ALIGN_M:
            lowest_away = max(lowest_away, gen.pos_ned[2])
    assert lowest_away == pytest.approx(-12.0, abs=0.05)  # held its height while away
    assert math.hypot(gen.pos_ned[0], gen.pos_ned[1]) < 0.1 and gen.pos_ned[2] > -2.0  # then came down on it


def test_idle_follows_the_vehicle() -> None:
    gen = SetpointGenerator(LIMITS)
    gen.update(NavTarget(TargetKind.IDLE), DT, (1.0, 2.0, 3.0))
    assert gen.pos_ned == [1.0, 2.0, 3.0] and gen.vel_ned == [0.0, 0.0, 0.0]


def test_prepared_reference_is_bit_identical_and_never_stale() -> None:
    """``prepare`` (run after the answer) gives the same floats as ``update`` alone, and is dropped when the
    target, dt, limits or the reference changed in between (reset, set_reference, another update)."""
    plain, ahead = SetpointGenerator(), SetpointGenerator()
    hold = NavTarget(TargetKind.POSITION, (20.0, -5.0, -10.0), 1.0, 5.0, 3.0, 1.5)
    other = NavTarget(TargetKind.POSITION, (20.0, -5.0, -10.0), -1.0, 4.0, 3.0, 1.5)
    land = NavTarget(TargetKind.LAND, (20.0, -5.0, 0.0), math.nan, 5.0, 3.0, 0.7)
    vehicle = (0.0, 0.0, -2.0)
    plan: list[tuple[NavTarget, float]] = [(hold, DT)] * 300 + [(other, DT)] * 50 + [(other, 2 * DT)] * 20
    plan += [(land, DT)] * 50 + [(hold, DT)] * 30
    for k, (target, dt) in enumerate(plan):
        if k == 100:
            for gen in (plain, ahead):
                gen.limits = SetpointLimits(acc_xy_m_s2=2.0)
        if k == 200:
            for gen in (plain, ahead):
                gen.set_reference((1.0, 2.0, -3.0), (0.5, 0.0, 0.0), (0.0, 0.0, 0.0))
        if k == 250:
            for gen in (plain, ahead):
                gen.reset((0.0, 1.0, -4.0), (0.0, 0.0, 0.0), 0.3)
        plain.update(target, dt, vehicle)
        ahead.update(target, dt, vehicle)
        assert (ahead.pos_ned, ahead.vel_ned, ahead.acc_ned, ahead.yaw_rad) == (
            plain.pos_ned,
            plain.vel_ned,
            plain.acc_ned,
            plain.yaw_rad,
        ), k
        ahead.prepare(hold, DT)  # always guesses "hold at DT": wrong for most of the plan after step 300


def _velocity(vel: tuple[float, float, float], yaw: float = math.nan, yaw_rate: float = math.nan) -> NavTarget:
    nan3 = (math.nan, math.nan, math.nan)
    return NavTarget(TargetKind.VELOCITY, nan3, yaw, 5.0, 2.0, 1.0, vel, yaw_rate)


def test_velocity_target_is_flown_within_the_speed_and_jerk_limits() -> None:
    """A velocity command is reached with limited acceleration and jerk; a too-fast one is scaled to the limits
    (horizontal magnitude to speed_xy, climb and descent to their own speeds), keeping its direction."""
    gen = SetpointGenerator(LIMITS)
    gen, worst = _fly(_velocity((3.0, -1.0, -0.5)), 5.0, gen)
    assert gen.vel_ned == pytest.approx((3.0, -1.0, -0.5), abs=1e-6)
    assert gen.acc_ned == pytest.approx((0.0, 0.0, 0.0), abs=1e-4)
    assert worst["a_xy"] <= LIMITS.acc_xy_m_s2 + 1e-9 and worst["jerk"] <= LIMITS.jerk_m_s3 * 1.0001
    gen, worst = _fly(_velocity((30.0, 40.0, -9.0)), 10.0, gen)
    assert gen.vel_ned == pytest.approx((3.0, 4.0, -2.0), abs=1e-6)  # |v_xy| 50 -> 5, climb 9 -> 2
    gen, worst = _fly(_velocity((0.0, 0.0, 9.0)), 10.0, gen)
    assert gen.vel_ned == pytest.approx((0.0, 0.0, 1.0), abs=1e-6) and worst["v_dn"] <= 1.0 + 1e-9


def test_velocity_reference_integrates_and_keeps_on_a_leash() -> None:
    """The position reference moves with the velocity while the vehicle follows, and stays within
    VELOCITY_MAX_LEAD_M of a vehicle that does not (horizontally and vertically)."""
    gen = SetpointGenerator(LIMITS)
    target = _velocity((2.0, 0.0, 0.0))
    vehicle = [0.0, 0.0, -5.0]
    gen.reset(tuple(vehicle), (0.0, 0.0, 0.0), 0.0)
    for k in range(round(10.0 / DT)):  # the vehicle follows the reference exactly
        gen.update(target, DT, tuple(vehicle))
        vehicle[:] = gen.pos_ned
        if k == round(9.0 / DT) - 1:
            at_9s = gen.pos_ned[0]
    assert gen.pos_ned[0] - at_9s == pytest.approx(2.0, abs=1e-6)  # 2 m/s, well after the ramp
    assert gen.pos_ned[1:] == pytest.approx([0.0, -5.0], abs=1e-12)
    stuck = tuple(vehicle)
    for _ in range(round(10.0 / DT)):  # a wall: the vehicle stops
        gen.update(_velocity((2.0, 0.0, 3.0)), DT, stuck)
        assert math.hypot(gen.pos_ned[0] - stuck[0], gen.pos_ned[1] - stuck[1]) <= VELOCITY_MAX_LEAD_M + 1e-9
        assert abs(gen.pos_ned[2] - stuck[2]) <= VELOCITY_MAX_LEAD_M + 1e-9
    assert gen.pos_ned[2] == pytest.approx(stuck[2] + VELOCITY_MAX_LEAD_M)


def test_velocity_yaw_rate_turns_the_heading_within_the_limit() -> None:
    gen = SetpointGenerator(LIMITS)
    gen.reset((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0)
    gen, _ = _fly(_velocity((0.0, 0.0, 0.0), yaw_rate=0.25), 2.0, gen)
    assert gen.yaw_rad == pytest.approx(0.5)
    gen, worst = _fly(_velocity((0.0, 0.0, 0.0), yaw_rate=-10.0), 1.0, gen)  # clamped to the 0.5 rad/s limit
    assert gen.yaw_rad == pytest.approx(0.0, abs=1e-9) and worst["yaw_rate"] <= LIMITS.yaw_rate_rad_s * 1.0001
    gen, _ = _fly(_velocity((0.0, 0.0, 0.0), yaw=1.0, yaw_rate=0.25), 4.0, gen)  # a yaw wins over a yaw rate
    assert gen.yaw_rad == pytest.approx(1.0)
