"""``fast_frozen_init`` keeps the frozen-dataclass contract of the wire messages (signature, defaults, semantics)."""

from __future__ import annotations

import dataclasses
import inspect
import pickle

import pytest

from mavlink_bridge.contract.wire import (
    ActuatorCommand,
    GroundTruth,
    ObstacleDetection,
    ObstacleShape,
    fast_frozen_init,
)


def test_fast_init_keeps_signature_defaults_equality_hash_replace_and_pickle() -> None:
    cmd = ActuatorCommand(5, (0.1, 0.2, 0.3, 0.4), True)
    assert (cmd.gripper_release, cmd.lockstep) == (False, True)
    assert cmd == ActuatorCommand(time_us=5, motor_cmd=(0.1, 0.2, 0.3, 0.4), armed=True, gripper_release=False)
    assert hash(cmd) == hash(ActuatorCommand(5, (0.1, 0.2, 0.3, 0.4), True, False, True))
    assert dataclasses.replace(cmd, armed=False).armed is False
    assert pickle.loads(pickle.dumps(cmd)) == cmd
    assert list(inspect.signature(ActuatorCommand).parameters) == [f.name for f in dataclasses.fields(ActuatorCommand)]
    assert ObstacleDetection(1, 2, (1.0, 0.0, 0.0), 0.5).shape is ObstacleShape.UNKNOWN
    assert "time_us=1" in repr(ObstacleDetection(1, 2, (1.0, 0.0, 0.0), 0.5))


def test_fast_init_keeps_instances_frozen_and_rejects_missing_or_unknown_fields() -> None:
    truth = GroundTruth(1, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 47.0, 8.0, 500.0, (0.0, 0.0, 0.0), (0.0, 0.0, -9.8))
    with pytest.raises(dataclasses.FrozenInstanceError):
        truth.lat_deg = 0.0  # type: ignore[misc]
    with pytest.raises(TypeError):
        ActuatorCommand(1, (0.0, 0.0, 0.0, 0.0))  # type: ignore[call-arg]
    with pytest.raises(TypeError):
        ActuatorCommand(1, (0.0, 0.0, 0.0, 0.0), True, colour="red")  # type: ignore[call-arg]


def test_fast_init_refuses_classes_it_cannot_reproduce() -> None:
    @dataclasses.dataclass(frozen=True, slots=True)
    class WithPostInit:
        x: float

        def __post_init__(self) -> None:
            pass

    @dataclasses.dataclass(slots=True)
    class NotFrozen:
        x: float

    for cls in (WithPostInit, NotFrozen):
        with pytest.raises(TypeError):
            fast_frozen_init(cls)
