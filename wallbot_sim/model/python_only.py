"""What only the Python model computes (docs/model.md 13): the compiled engine and the batch refuse it by name."""

from __future__ import annotations

from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.robot import Robot
from wallbot_sim.model.world import World


def python_only_features(robot: Robot) -> list[str]:
    """What ``robot`` has that only the Python model computes: a world file, a motor block, a vacuum block."""
    return [name for name, present in (('a world file', robot.world != World()),
                                       ('a motor block', robot.params.motor is not None),
                                       ('a vacuum block', robot.params.adhesion is not None)) if present]


def python_only_reason(robot: Robot) -> str | None:
    """Why ``robot`` needs the python engine, e.g. 'a world file runs on the python engine only'; None if it does
    not."""
    features = python_only_features(robot)
    if not features:
        return None
    verb = 'runs' if len(features) == 1 else 'run'
    return f'{" and ".join(features)} {verb} on the python engine only'


def refuse_compiled(robot: Robot) -> None:
    """ParameterError naming the python engine if ``robot`` has what the compiled kernel does not compute."""
    reason = python_only_reason(robot)
    if reason is not None:
        raise ParameterError(f'{reason}: use --engine python (engine parameter python)')
