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


def refuse_compiled(robot: Robot) -> None:
    """ParameterError naming the python engine if ``robot`` has what the compiled kernel does not compute."""
    features = python_only_features(robot)
    if features:
        verb = 'runs' if len(features) == 1 else 'run'
        raise ParameterError(f'{" and ".join(features)} {verb} on the python engine only: use --engine python '
                             '(engine parameter python)')
