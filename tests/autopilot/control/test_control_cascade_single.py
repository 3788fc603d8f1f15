"""The single-vehicle tuple path of the cascade is the batch path, bit for bit (the autopilot's per-step call)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autopilot.control import CascadeController, CascadeGains, load_airframe


def _pair() -> tuple[CascadeController, CascadeController]:
    airframe, gains = load_airframe("x500"), CascadeGains.paper_default()
    return CascadeController(airframe, gains), CascadeController(airframe, gains)


def test_single_tuple_path_equals_update_position_bit_for_bit_over_a_random_sequence() -> None:
    rng = np.random.default_rng(7)
    batch, single = _pair()
    for k in range(300):
        pos, vel, rate = rng.normal(0, 3, 3), rng.normal(0, 2, 3), rng.normal(0, 1, 3)
        q = rng.normal(0, 1, 4)
        q /= np.linalg.norm(q)
        pos_sp, vel_sp, acc_ff = rng.normal(0, 3, 3), rng.normal(0, 2, 3), rng.normal(0, 1, 3)
        yaw = float(rng.uniform(-4, 4))
        if k == 100:  # the NaN guard holds the last command on both paths
            pos[0] = math.nan
        u = batch.update_position(
            pos[None], vel[None], q[None], rate[None], pos_sp[None], vel_sp[None], acc_ff[None], yaw
        )
        out = single.update_position_single(
            *(tuple(float(x) for x in a) for a in (pos, vel, q, rate, pos_sp, vel_sp, acc_ff)),  # type: ignore[arg-type]
            yaw,
        )
        assert out[:4] == tuple(u[0].tolist())
        d = batch.diagnostics
        assert out[4] == d.thrust_n[0]
        assert out[5:8] == tuple(d.pos_err_ned[0].tolist())
        assert out[8:10] == tuple(d.att_err_rad[0, :2].tolist())
        assert np.array_equal(batch._work, single._work, equal_nan=True)


def test_single_tuple_path_refuses_a_batch() -> None:
    controller = CascadeController(load_airframe("x500"), CascadeGains.paper_default(), n=2)
    zero = (0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="n = 1"):
        controller.update_position_single(zero, zero, (1.0, 0.0, 0.0, 0.0), zero, zero, zero, zero, 0.0)
