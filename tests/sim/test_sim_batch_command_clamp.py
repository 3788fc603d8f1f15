"""``BatchSim.step`` relies on the kernel's clamp: out-of-range and non-finite commands give bit-identical states
to the same commands clipped to [0, 1] (NaN as 0) beforehand."""

from __future__ import annotations

import numpy as np

from sim.batch import BatchSim
from sim.vehicle_config import load_vehicle


def test_out_of_range_commands_equal_clipped_ones_bit_for_bit() -> None:
    vehicle = load_vehicle("x500")
    raw_sim, clipped_sim = BatchSim(vehicle, 3, seed=5), BatchSim(vehicle, 3, seed=5)
    rng = np.random.default_rng(11)
    for k in range(400):
        raw = rng.uniform(-0.5, 1.5, (3, 4))
        raw[0, k % 4] = np.nan if k % 3 == 0 else np.inf
        raw[1, (k + 1) % 4] = -np.inf
        clipped = np.clip(np.nan_to_num(raw, nan=0.0), 0.0, 1.0)
        raw_sim.step(raw)
        clipped_sim.step(clipped)
    assert np.array_equal(raw_sim.state, clipped_sim.state)
    assert raw_sim.state.any()


def test_a_single_command_row_broadcasts_to_every_vehicle() -> None:
    vehicle = load_vehicle("x500")
    one, each = BatchSim(vehicle, 2, seed=1), BatchSim(vehicle, 2, seed=1)
    for _ in range(100):
        one.step(np.array([0.7, 0.7, 0.7, 0.7]))
        each.step(np.full((2, 4), 0.7))
    assert np.array_equal(one.state, each.state)
